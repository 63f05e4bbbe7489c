#include "render/sphere_refraction.hpp"

#include <algorithm>
#include <cmath>

namespace chromasim::render::detail {

namespace {
/// Narrowing rounds of bracket_near (each a regula falsi step and a probe).
constexpr int kNarrowRounds = 3;
} // namespace

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

double SphereRefraction::mismatch(double t) {
    ++m_evaluations;
    const double d = 1.0 / (1.0 + t * t);
    const double c = (1.0 - t * t) * d, s = 2.0 * t * d;
    const double to_x = std::sqrt(std::max(0.0, m_R2 + m_a * m_a - 2.0 * m_a * m_R * c)); // |x-p|
    const double to_l = std::sqrt(std::max(0.0, m_l2 + m_R2 - 2.0 * m_R * (m_lx * c + m_ly * s)));
    // A unit direction of zero length (x on p or on l) counts as zero, as Eigen's
    // normalized() leaves it.
    return (to_x > 0.0 ? m_eta * m_a * s / to_x : 0.0) -
           (to_l > 0.0 ? (m_ly * c - m_lx * s) / to_l : 0.0);
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

bool SphereRefraction::bracket_near(const Vec3& guess, double half_width_t, double width_mm,
                                    double tolerance) {
    if (m_degenerate) return false;
    // Where the guessed ray leaves the sphere (from outside it: p is in the shell).
    const double b = m_p.dot(guess), c = m_a * m_a - m_R2;
    const double disc = b * b - c;
    if (!(disc >= 0.0)) return false;
    const double s = -b - std::sqrt(disc);
    if (!(s > 0.0)) return false;
    const Vec3 x = m_p + s * guess;
    const double t_guess = t_of(x.dot(m_e1), x.dot(m_e2));
    // Within the whole bracket [0, t_l] (solve's), where the mismatch has its one root.
    const double t_l = t_of(m_lx, m_ly);
    m_lo = std::max(0.0, t_guess - half_width_t), m_hi = std::min(t_l, t_guess + half_width_t);
    if (!(m_lo < m_hi)) return false;
    m_f_lo = mismatch(m_lo), m_f_hi = mismatch(m_hi);
    if (m_f_lo * m_f_hi > 0.0) return false;
    // Narrow: a regula falsi step, then a probe a little past it towards the root, so that
    // both ends close in (plain regula falsi keeps one end fixed).
    const double t_per_mm = 1.0 / m_R; // dt / d(arc) = (1 + t^2) / (2 R), t below 1
    for (int round = 0; round < kNarrowRounds; ++round) {
        if ((at(m_hi) - at(m_lo)).norm() <= width_mm) return true;
        if (m_f_hi == m_f_lo) return false;
        const double t = (m_lo * m_f_hi - m_hi * m_f_lo) / (m_f_hi - m_f_lo);
        const double f = mismatch(t);
        if (std::abs(f) < tolerance) {
            m_lo = m_hi = t, m_f_lo = m_f_hi = f;
            return true;
        }
        // f has m_hi's sign: the root lies in [m_lo, t], else in [t, m_hi].
        if ((f > 0.0) == (m_f_hi > 0.0)) {
            m_hi = t, m_f_hi = f;
            const double probe = std::max(m_lo, t - 0.5 * width_mm * t_per_mm);
            if (probe > m_lo) {
                const double fp = mismatch(probe);
                if ((fp > 0.0) == (f > 0.0))
                    m_hi = probe, m_f_hi = fp;
                else
                    m_lo = probe, m_f_lo = fp;
            }
        } else {
            m_lo = t, m_f_lo = f;
            const double probe = std::min(m_hi, t + 0.5 * width_mm * t_per_mm);
            if (probe < m_hi) {
                const double fp = mismatch(probe);
                if ((fp > 0.0) == (f > 0.0))
                    m_lo = probe, m_f_lo = fp;
                else
                    m_hi = probe, m_f_hi = fp;
            }
        }
    }
    return (at(m_hi) - at(m_lo)).norm() <= width_mm;
}

SphereRefraction::Vec3 SphereRefraction::finish(double tolerance) {
    if (m_lo == m_hi) return direction_at(m_lo);
    return direction_at(regula_falsi(tolerance));
}

} // namespace chromasim::render::detail
