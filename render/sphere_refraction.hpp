#pragma once
/// The sphere model's refraction: the direction from a point p in the clear layers (outside
/// the sphere of radius R about the origin) that leaves the layers through the sphere and,
/// refracted into the air (index ratio eta), heads for a point l in the cavity. Shadow rays of
/// the fast integrator and the starts of the path integrator's Newton solves use it.
///
/// Everything lies in the plane of O, p and l. The exit point x = R (cos psi e1 + sin psi e2),
/// psi from p's foot, is parametrised without trigonometry by t = tan(psi / 2); the root of
/// Snell's mismatch n (w_in . tau) - w_out . tau lies between p's foot (t = 0) and where the
/// straight segment p -> l crosses the sphere (the refracted path in the denser layer is
/// steeper).
///
/// Two ways in:
///   - solve(): regula falsi with the Illinois modification over that whole bracket (about 9
///     evaluations of the mismatch to 1e-9);
///   - newton(): Newton's method from a guessed direction (the fast integrator's shadow rays
///     from its per-vertex table, a few hundredths of a radian off; the path integrator's
///     starts from the straight line to l): a few evaluations of the mismatch and its slope,
///     fewer still when it also stops after a step that turns the direction by less than
///     `step_tolerance` (the fast integrator's shadow rays: 1e-2 rad, about 1.3 evaluations);
///     nothing where it would leave the bracket or does not get there, and the caller solves.
#include <Eigen/Core>

#include <cmath>
#include <optional>
#include <utility>

namespace chromasim::render::detail {

class SphereRefraction {
public:
    using Vec3 = Eigen::Vector3d;

    SphereRefraction(const Vec3& p, const Vec3& l, double R, double eta);

    /// The direction by regula falsi over the whole bracket, stopping at a mismatch below
    /// `tolerance` (a difference of sines). Straight p -> l where the plane is degenerate or
    /// the bracket has no sign change.
    Vec3 solve(double tolerance);

    /// The direction by Newton's method on the mismatch, from where the ray from p along the
    /// unit `guess` leaves the sphere, stopping at a mismatch below `tolerance` (as solve()),
    /// or after a step that turns the direction by less than `step_tolerance` (rad; Newton
    /// converges quadratically, so what is left after the step is about its turn squared:
    /// 1e-4 leaves about 1e-8 without the evaluation that would confirm it).
    /// Nothing (use solve()) where the plane is degenerate, the ray does not leave the sphere,
    /// a step leaves the bracket that holds the one root (up to l's direction and on the cap
    /// of the sphere seen from p), the slope vanishes or kNewtonSteps evaluations do not get
    /// there.
    std::optional<Vec3> newton(const Vec3& guess, double tolerance, double step_tolerance = 0.0);
    static constexpr int kNewtonSteps = 8;

    /// Evaluations of the mismatch so far (for tests and benchmarks).
    int evaluations() const { return m_evaluations; }

    /// Snell's mismatch at t (tan of half the exit point's angle from p's foot); `slope`: if
    /// given, gets its derivative in t (newton(); public for the tests' finite differences);
    /// `to_exit`: if given, gets |x - p|.
    double mismatch(double t, double* slope = nullptr, double* to_exit = nullptr);

private:
    Vec3 at(double t) const;
    /// t of the direction of a point (c, s) of the plane: tan(psi / 2) = sin / (1 + cos).
    static double t_of(double c, double s);
    /// illinois() on [m_lo, m_hi]: the last point evaluated.
    double regula_falsi(double tolerance);
    Vec3 direction_at(double t) const { return (at(t) - m_p).normalized(); }

    Vec3 m_p, m_l, m_e1 = Vec3::Zero(), m_e2 = Vec3::Zero();
    double m_a = 0.0, m_lx = 0.0, m_ly = 0.0, m_R = 0.0, m_R2 = 0.0, m_l2 = 0.0, m_eta = 1.0;
    bool m_degenerate = false; ///< p at the origin or l on p's axis: the straight direction
    double m_lo = 0.0, m_hi = 0.0, m_f_lo = 0.0, m_f_hi = 0.0;
    int m_evaluations = 0;
};

/// A root of f in [lo, hi] (f_lo = f(lo) and f_hi = f(hi) of opposite signs) by regula falsi
/// with the Illinois modification: it keeps a bracket like bisection and converges
/// superlinearly (a few evaluations where bisection takes 30). Stops at |f| < tolerance, a
/// bracket below 1e-10 or after 30 steps. Returns the last point and its f.
template <class F>
std::pair<double, double> illinois(F&& f, double lo, double hi, double f_lo, double f_hi,
                                   double tolerance) {
    double x = 0.5 * (lo + hi), fx = f_lo;
    int side = 0;
    for (int i = 0; i < 30 && f_hi != f_lo; ++i) {
        x = (lo * f_hi - hi * f_lo) / (f_hi - f_lo);
        fx = f(x);
        if (std::abs(fx) < tolerance || std::abs(hi - lo) < 1e-10) break;
        if ((fx > 0.0) == (f_hi > 0.0)) {
            hi = x, f_hi = fx;
            if (side == -1) f_lo *= 0.5;
            side = -1;
        } else {
            lo = x, f_lo = fx;
            if (side == 1) f_hi *= 0.5;
            side = 1;
        }
    }
    return {x, fx};
}

/// SphereRefraction(p, l, R, eta).solve(tolerance).
inline Eigen::Vector3d sphere_refraction(const Eigen::Vector3d& p, const Eigen::Vector3d& l,
                                         double R, double eta, double tolerance = 1e-13) {
    return SphereRefraction(p, l, R, eta).solve(tolerance);
}

} // namespace chromasim::render::detail
