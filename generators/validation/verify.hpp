#pragma once
/// `chromasim verify mechanics`: validation cases against analytic references, printed as a
/// table and optionally written as JSON (measured, reference, relative error, mesh level,
/// run time, target).
#include <iosfwd>
#include <string>
#include <vector>

namespace chromasim::generators {

struct VerifyCase {
    std::string key;        ///< e.g. hertz_a
    std::string level;      ///< mesh level
    std::string volumetric; ///< nodal_average | element
    double load_N = 0, nu = 0;
    double measured = 0, reference = 0, rel_error = 0, target = 0;
    double precompute_s = 0, frame_ms = 0;
    std::string note;
};

struct VerifyOptions {
    std::vector<std::string> levels{"coarse", "medium"};
    std::vector<double> nus{0.49};
    std::vector<std::string> volumetrics{"nodal_average", "element"};
};

/// Hertz on an elastic block (R = 10 mm, E = 1 MPa, P = 1 and 2.5 N): contact radius, approach
/// and peak pressure; Cattaneo-Mindlin stick radius at P = 1 N, Q / (mu P) = 0.25, 0.5, 0.75,
/// mu = 0.5 and 1; per volumetric formulation, Poisson ratio and mesh level.
std::vector<VerifyCase> verify_mechanics(const VerifyOptions& options);

/// The dome itself (coarse mesh, default materials) under a flat and a 45 mm sphere: force,
/// indentation and area-equivalent contact radius beside Hertz for a solid sphere of the
/// dome's radius with the thickness-weighted Young's modulus of its layers. No pass/fail: the
/// shell is not a half-space.
void print_dome_curve(std::ostream& out);

void print_verify_table(const std::vector<VerifyCase>& cases, std::ostream& out);
void write_verify_json(const std::vector<VerifyCase>& cases, std::ostream& out);

} // namespace chromasim::generators
