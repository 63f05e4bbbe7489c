#pragma once
/// Hertz contact of a rigid sphere on an elastic half-space (SENSOR.md section 2), and the
/// estimate of the same quantities from a nodal contact solution, for validation.
#include "mechanics/contact.hpp"
#include "mechanics/tet_mesh.hpp"

#include <vector>

namespace chromasim::mechanics {

struct HertzSolution {
    double a_mm = 0;     ///< contact radius (3 P R / (4 E*))^(1/3), E* = E / (1 - nu^2)
    double delta_mm = 0; ///< indentation a^2 / R
    double p0_MPa = 0;   ///< peak pressure 3 P / (2 pi a^2)
};
HertzSolution hertz(double P_N, double R_mm, double E_MPa, double nu);

/// Cattaneo-Mindlin stick radius c = a (1 - Q / (mu P))^(1/3).
double mindlin_stick_radius(double a_mm, double Q_N, double mu, double P_N);

/// Boussinesq: vertical displacement (mm) on the axis at depth z under a point load P on a
/// half-space, P (1 + nu)(3 - 2 nu) / (2 pi E z). The part of Hertz's approach that a block
/// clamped at depth z cannot show.
double boussinesq_axis_displacement(double P_N, double E_MPa, double nu, double depth_mm);

/// Contact radius and peak pressure estimated from nodal forces: nodal pressures
/// p_i = lambda_i / area_i of the contact nodes inside 0.85 of the area-equivalent radius are
/// fitted to the Hertz profile p^2 = p0^2 (1 - r^2 / a^2) by least squares (sub-element
/// accuracy, unlike counting nodes). X: candidate positions (the axis is r = 0).
struct ContactFit {
    double a_mm = 0, p0_MPa = 0, area_radius_mm = 0;
    int nodes_used = 0;
};
ContactFit fit_hertz_profile(const Points& X, const std::vector<double>& area_mm2,
                             const ContactSolution& contact);

/// Stick radius estimated from nodal tangential tractions q_i = |t_i| / area_i (nodes inside
/// 0.85 a): the c in [0, a] whose Mindlin traction profile, mu p0 / a (sqrt(a^2 - r^2) -
/// sqrt(c^2 - r^2)) inside c and mu p0 sqrt(1 - r^2 / a^2) outside, fits best (least squares,
/// scanned in steps of a / 1000). `a_mm` and `p0_MPa` from fit_hertz_profile.
double fit_mindlin_stick_radius(const Points& X, const std::vector<double>& area_mm2,
                                const ContactSolution& contact, double a_mm, double p0_MPa,
                                double mu);

/// Radius of the circle with the tributary area of the sticking contact nodes (mm).
double stick_area_radius(const std::vector<double>& area_mm2, const ContactSolution& contact);

} // namespace chromasim::mechanics
