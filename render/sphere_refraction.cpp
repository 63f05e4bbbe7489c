#include "render/sphere_refraction.hpp"

#include <algorithm>
#include <cmath>

namespace chromasim::render::detail {

SphereRefraction::SphereRefraction(const Vec3& p, const Vec3& l, double R, double eta)
    : m_p(p), m_l(l), m_R(R), m_R2(R * R), m_eta(eta) {
    // Coordinates (along e1, along e2): p = (a, 0), l = (lx, ly), x = R (c, s) and
    // tau = (-s, c), so that (x - p) . tau = a s and (l - x) . tau = ly c - lx s; each
    // evaluation is then a few flops and two square roots.
    m_a = p.norm();
    if (!(m_a > 0.0)) {
        m_degenerate = true;
        return;
    }
    m_e1 = p / m_a;
    m_lx = l.dot(m_e1);
    m_e2 = l - m_lx * m_e1;
    m_ly = m_e2.norm();
    if (!(m_ly > 1e-9)) { // l on p's axis: straight down
        m_degenerate = true;
        return;
    }
    m_e2 /= m_ly;
    m_l2 = m_lx * m_lx + m_ly * m_ly;
}

double SphereRefraction::t_of(double c, double s) {
    return s / (std::sqrt(c * c + s * s) + c);
}

SphereRefraction::Vec3 SphereRefraction::at(double t) const {
    // cos psi = (1 - t^2) / (1 + t^2), sin psi = 2 t / (1 + t^2).
    const double d = 1.0 / (1.0 + t * t);
    return m_R * ((1.0 - t * t) * d * m_e1 + 2.0 * t * d * m_e2);
}

double SphereRefraction::mismatch(double t, double* slope, double* to_exit) {
    ++m_evaluations;
    const double d = 1.0 / (1.0 + t * t);
    const double c = (1.0 - t * t) * d, s = 2.0 * t * d;
    const double to_x = std::sqrt(std::max(0.0, m_R2 + m_a * m_a - 2.0 * m_a * m_R * c)); // |x-p|
    const double to_l = std::sqrt(std::max(0.0, m_l2 + m_R2 - 2.0 * m_R * (m_lx * c + m_ly * s)));
    if (to_exit) *to_exit = to_x;
    // A unit direction of zero length (x on p or on l) counts as zero, as Eigen's
    // normalized() leaves it (and has no slope).
    const double towards_l = m_ly * c - m_lx * s; // (l - x) . tau
    // The reciprocals once: two divisions, not one per term.
    const double inv_x = to_x > 0.0 ? 1.0 / to_x : 0.0, inv_l = to_l > 0.0 ? 1.0 / to_l : 0.0;
    if (slope) {
        // d psi / dt = 2 d, dc = -s d psi, ds = c d psi; d|x - p| = a R s d psi / |x - p|,
        // d|l - x| = -R (l - x) . tau d psi / |l - x|.
        const double g = 2.0 * d;
        const double inside = m_eta * m_a * g * (c - m_a * m_R * s * s * inv_x * inv_x) * inv_x;
        const double outside =
            g * ((-m_ly * s - m_lx * c) + m_R * towards_l * towards_l * inv_l * inv_l) * inv_l;
        *slope = inside - outside;
    }
    return m_eta * m_a * s * inv_x - towards_l * inv_l;
}

double SphereRefraction::regula_falsi(double tolerance) {
    return illinois([this](double t) { return mismatch(t); }, m_lo, m_hi, m_f_lo, m_f_hi, tolerance)
        .first;
}

SphereRefraction::Vec3 SphereRefraction::solve(double tolerance) {
    if (m_degenerate) return (m_l - m_p).normalized();
    // The bracket: from p's foot (t = 0) to where the straight segment p -> l crosses the
    // sphere, else to l's own direction.
    const double t_l = t_of(m_lx, m_ly);
    m_lo = 0.0, m_hi = t_l;
    m_f_lo = mismatch(m_lo), m_f_hi = 0.0;
    bool bracketed = false;
    {
        const double dx = m_lx - m_a, dy = m_ly;
        const double qa = dx * dx + dy * dy, qb = m_a * dx, qc = m_a * m_a - m_R2;
        const double disc = qb * qb - qa * qc;
        const double u = disc >= 0.0 ? (-qb - std::sqrt(disc)) / qa : -1.0;
        if (u > 0.0 && u < 1.0) {
            const double t_s = t_of(m_a + u * dx, u * dy);
            const double f_s = mismatch(t_s);
            if (m_f_lo * f_s <= 0.0 && std::abs(t_s) < std::abs(t_l))
                m_hi = t_s, m_f_hi = f_s, bracketed = true;
        }
        if (!bracketed) m_f_hi = mismatch(m_hi);
    }
    if (m_f_lo * m_f_hi > 0.0) return (m_l - m_p).normalized();
    return direction_at(regula_falsi(tolerance));
}

std::optional<SphereRefraction::Vec3> SphereRefraction::newton(const Vec3& guess, double tolerance,
                                                               double step_tolerance) {
    if (m_degenerate) return std::nullopt;
    // Where the guessed ray leaves the sphere (from outside it: p is in the shell).
    const double b = m_p.dot(guess), c = m_a * m_a - m_R2;
    const double disc = b * b - c;
    if (!(disc >= 0.0)) return std::nullopt;
    const double s = -b - std::sqrt(disc);
    if (!(s > 0.0)) return std::nullopt;
    const Vec3 x = m_p + s * guess;
    double t = t_of(x.dot(m_e1), x.dot(m_e2));
    // The root lies before l's own direction (solve()'s whole bracket) and on the cap of
    // the sphere p sees (psi up to acos(R / a)): beyond it the mismatch has other roots, of
    // paths that would cross the cavity to reach the sphere from inside. t_of(R, h) with
    // h = sqrt(a^2 - R^2) is h / (a + R), and t_of(lx, ly) takes |l| = sqrt(l2).
    const double t_hi = std::min(m_ly / (std::sqrt(m_l2) + m_lx),
                                 std::sqrt(std::max(0.0, c)) / (m_a + m_R));
    for (int i = 0; i < kNewtonSteps; ++i) {
        double slope = 0.0, to_exit = 0.0;
        const double f = mismatch(t, &slope, &to_exit);
        if (std::abs(f) < tolerance) return direction_at(t);
        if (!(slope != 0.0)) return std::nullopt;
        const double step = f / slope;
        // The step's turn of the direction from p, at most: the exit point moves by
        // R d psi = 2 R dt / (1 + t^2), seen from p at |x - p|.
        const double turn = 2.0 * m_R * std::abs(step) / ((1.0 + t * t) * to_exit);
        t -= step;
        if (!(t >= 0.0 && t <= t_hi)) return std::nullopt;
        // Converging quadratically: the error after a step is about its turn squared.
        if (turn < step_tolerance) return direction_at(t);
    }
    return std::nullopt;
}

} // namespace chromasim::render::detail
