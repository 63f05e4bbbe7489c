#include "generators/validation/verify.hpp"

#include "mechanics/block_model.hpp"
#include "mechanics/dome_model.hpp"
#include "mechanics/hertz.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <numbers>
#include <ostream>

namespace chromasim::generators {

namespace {

using Clock = std::chrono::steady_clock;

/// Mindlin's assumption: the normal load goes on without friction, then the tangential load
/// in one monotonic step.
constexpr mechanics::LoadPath kMindlinPath{1, 1, true, 1};

VerifyCase make_case(std::string key, const std::string& level, const std::string& volumetric,
                     double P, double nu, double measured, double reference, double target) {
    VerifyCase c{std::move(key), level, volumetric, P, nu, measured,
                 reference,      0,     target,     0, 0,  ""};
    c.rel_error = measured / reference - 1.0;
    return c;
}

/// Area-equivalent stick radius and stick-zone centroid (area-weighted) of a solution.
std::pair<double, Eigen::Vector2d> stick_zone(const mechanics::BlockModel& block,
                                              const mechanics::ContactSolution& s) {
    double area = 0;
    Eigen::Vector2d centre(0, 0);
    for (int j : s.active)
        if (s.state[std::size_t(j)] == mechanics::NodeContact::stick) {
            const double a = block.candidate_areas()[std::size_t(j)];
            area += a;
            centre += a * block.candidate_positions().row(j).head<2>().transpose();
        }
    return {std::sqrt(area / std::numbers::pi), area > 0 ? Eigen::Vector2d(centre / area) : centre};
}

/// Friction during indentation (report only): P = 1 N pressed in 8 steps with friction on,
/// then Q = 0.5 mu P in 4 steps, against the same load with the normal load applied without
/// friction (Mindlin). Measured: area-equivalent stick radius and the stick zone's centroid
/// shift along the pull; reference: the same from the frictionless indentation.
void friction_indentation_cases(const mechanics::BlockModel& block,
                                const mechanics::ObjectShape& sphere, const std::string& level,
                                const std::string& volumetric, double nu,
                                std::vector<VerifyCase>& out) {
    const double P = 1.0;
    for (double mu : {0.5, 1.0}) {
        const mechanics::ContactLoad load{P, {0.5 * mu * P, 0}, mu};
        const auto t0 = Clock::now();
        const mechanics::ContactSolution with =
            block.solve(load, sphere, mechanics::LoadPath{8, 4, false, 1});
        const double ms = 1e3 * std::chrono::duration<double>(Clock::now() - t0).count();
        const mechanics::ContactSolution without = block.solve(load, sphere, kMindlinPath);
        const auto [c_with, centre_with] = stick_zone(block, with);
        const auto [c_without, centre_without] = stick_zone(block, without);
        const std::string note = "mu " + std::to_string(mu).substr(0, 3) +
                                 ", report only (reference: frictionless indentation)" +
                                 (with.converged ? "" : ", contact solve: " + with.status);
        VerifyCase radius = make_case("friction_indentation_c_050", level, volumetric, P, nu,
                                      c_with, c_without, 0.0);
        VerifyCase shift = make_case("friction_indentation_shift_mm", level, volumetric, P, nu,
                                     centre_with.x(), centre_without.x(), 0.0);
        shift.rel_error = 0; // the reference is ~0 mm: read measured - reference, in mm
        for (VerifyCase* c : {&radius, &shift}) {
            c->frame_ms = ms;
            c->precompute_s = block.stats().mesh_s + block.stats().precompute_s;
            c->note = note;
            out.push_back(*c);
        }
    }
}

/// Cattaneo-Mindlin at P = 1 N: normal load frictionless, then Q / (mu P) = 0.25, 0.5, 0.75
/// for mu = 0.5 and 1.0; stick radius fitted to the nodal tangential tractions.
void mindlin_cases(const mechanics::BlockModel& block, const mechanics::ObjectShape& sphere,
                   const mechanics::ContactFit& fit, const std::string& level,
                   const std::string& volumetric, double nu, std::vector<VerifyCase>& out) {
    const double P = 1.0;
    const double a = mechanics::hertz(P, sphere.radius_mm, 1.0, nu).a_mm;
    for (double mu : {0.5, 1.0})
        for (double ratio : {0.25, 0.5, 0.75}) {
            const auto t0 = Clock::now();
            const mechanics::ContactSolution s =
                block.solve({P, {ratio * mu * P, 0}, mu}, sphere, kMindlinPath);
            const double ms = 1e3 * std::chrono::duration<double>(Clock::now() - t0).count();
            const double c = mechanics::fit_mindlin_stick_radius(
                block.candidate_positions(), block.candidate_areas(), s, fit.a_mm, fit.p0_MPa, mu);
            char key[32];
            std::snprintf(key, sizeof key, "mindlin_c_%03d", int(std::lround(100 * ratio)));
            VerifyCase vc =
                make_case(key, level, volumetric, P, nu, c,
                          mechanics::mindlin_stick_radius(a, ratio * mu * P, mu, P), 0.05);
            vc.frame_ms = ms;
            vc.precompute_s = block.stats().mesh_s + block.stats().precompute_s;
            vc.note = "mu " + std::to_string(mu).substr(0, 3) +
                      (s.converged ? "" : ", contact solve: " + s.status);
            out.push_back(vc);
        }
    friction_indentation_cases(block, sphere, level, volumetric, nu, out);
}

void hertz_cases(const std::string& level, const std::string& volumetric, double nu,
                 std::vector<VerifyCase>& out) {
    constexpr double kRadius_mm = 10.0;
    mechanics::BlockParams params = mechanics::block_level(level);
    params.material.nu = nu;
    params.volumetric = volumetric == "element" ? mechanics::Volumetric::element
                                                : mechanics::Volumetric::nodal_average;
    const mechanics::BlockModel block(params);
    const mechanics::ObjectShape sphere = mechanics::sphere_object(kRadius_mm);
    const double E = params.material.E_MPa;
    for (double P : {1.0, 2.5}) {
        const auto t0 = Clock::now();
        const mechanics::ContactSolution s = block.solve({P, {0, 0}, 0.5}, sphere, kMindlinPath);
        const double frame_ms = 1e3 * std::chrono::duration<double>(Clock::now() - t0).count();
        const mechanics::HertzSolution h = mechanics::hertz(P, kRadius_mm, E, nu);
        const mechanics::ContactFit fit =
            mechanics::fit_hertz_profile(block.candidate_positions(), block.candidate_areas(), s);
        // With the half-space far field on its boundary the block shows Hertz's approach;
        // clamped at its base, Hertz's approach less the settlement below that depth.
        const double delta_ref =
            params.far_field
                ? h.delta_mm
                : h.delta_mm - mechanics::boussinesq_axis_displacement(P, E, nu, params.depth_mm);
        const std::size_t first = out.size();
        out.push_back(make_case("hertz_a", level, volumetric, P, nu, fit.a_mm, h.a_mm, 0.03));
        out.push_back(
            make_case("hertz_delta", level, volumetric, P, nu, s.indentation_mm, delta_ref, 0.03));
        out.push_back(make_case("hertz_p0", level, volumetric, P, nu, fit.p0_MPa, h.p0_MPa, 0.05));
        for (std::size_t i = first; i < out.size(); ++i) {
            out[i].precompute_s = block.stats().mesh_s + block.stats().precompute_s;
            out[i].frame_ms = frame_ms;
            out[i].note = s.converged ? "" : "contact solve: " + s.status;
        }
        if (P == 1.0) mindlin_cases(block, sphere, fit, level, volumetric, nu, out);
    }
}

} // namespace

std::vector<VerifyCase> verify_mechanics(const VerifyOptions& options) {
    std::vector<VerifyCase> cases;
    for (const auto& volumetric : options.volumetrics)
        for (double nu : options.nus)
            for (const auto& level : options.levels)
                hertz_cases(level, volumetric, nu, cases);
    return cases;
}

void print_dome_curve(std::ostream& out) {
    const mechanics::DomeModelOptions options;
    const mechanics::DomeModel model(options);
    mechanics::DomeModelOptions nh_options = options;
    nh_options.material = mechanics::MaterialModel::neo_hookean;
    const mechanics::DomeModel nh_model(nh_options);
    const auto& r = options.dome.radii_mm;
    double E = 0, nu = 0;
    for (int l = 0; l < mechanics::kLayerCount; ++l) {
        const double w = (r[std::size_t(l) + 1] - r[std::size_t(l)]) / (r.back() - r.front());
        E += w * options.materials[std::size_t(l)].E_MPa;
        nu += w * options.materials[std::size_t(l)].nu;
    }
    out << std::defaultfloat << std::setprecision(4) << "dome (coarse, "
        << (options.volumetric == mechanics::Volumetric::nodal_average ? "nodal_average"
                                                                       : "element")
        << ") beside Hertz for a solid sphere R = " << r.back() << " mm, E = " << E
        << " MPa, nu = " << nu << " (thickness-weighted)\n\n"
        << "Each load from rest: grip force in 4 steps with friction on (mu = 0.8). Neo-Hookean: "
           "the "
           "same dome with the compressible neo-Hookean model.\n\n"
        << "| object | P N | indentation mm | neo-Hookean mm | Hertz delta mm | contact radius mm "
           "| "
           "neo-Hookean mm | Hertz a mm | contact nodes |\n|---|---|---|---|---|---|---|---|---|\n"
        << std::setprecision(4);
    for (const double R_obj : {0.0, 45.0}) {
        const mechanics::ObjectShape object =
            R_obj > 0 ? mechanics::sphere_object(R_obj) : mechanics::ObjectShape{};
        // Two curved bodies: 1/R = 1/R1 + 1/R2 (a flat adds nothing).
        const double R = R_obj > 0 ? 1.0 / (1.0 / r.back() + 1.0 / R_obj) : r.back();
        for (double P : {0.25, 0.5, 1.0, 1.5, 2.0, 2.5, 3.2}) {
            const mechanics::FrameResult f = model.solve({P, {0, 0}, 0.8}, {}, object);
            const mechanics::FrameResult g = nh_model.solve({P, {0, 0}, 0.8}, {}, object);
            const mechanics::HertzSolution h = mechanics::hertz(P, R, E, nu);
            out << "| " << (R_obj > 0 ? "sphere 45 mm" : "flat") << " | " << P << " | "
                << f.contact.indentation_mm << " | "
                << (g.contact.converged ? std::to_string(g.contact.indentation_mm).substr(0, 6)
                                        : g.contact.status)
                << " | " << h.delta_mm << " | " << std::sqrt(f.contact_area_mm2 / std::numbers::pi)
                << " | " << std::sqrt(g.contact_area_mm2 / std::numbers::pi) << " | " << h.a_mm
                << " | " << f.contact.active.size() << " |\n";
        }
    }
}

void print_verify_table(const std::vector<VerifyCase>& cases, std::ostream& out) {
    out << "| case | volumetric | level | P N | nu | measured | reference | error | target | "
           "within | "
           "precompute s | frame ms | note "
           "|\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const VerifyCase& c : cases)
        out << "| " << c.key << " | " << c.volumetric << " | " << c.level << " | " << c.load_N
            << " | " << c.nu << " | " << std::setprecision(5) << c.measured << " | " << c.reference
            << " | " << std::fixed << std::setprecision(1) << 100 * c.rel_error << " % | "
            << 100 * c.target << " % | "
            << (c.target <= 0                       ? "report"
                : std::abs(c.rel_error) <= c.target ? "yes"
                                                    : "no")
            << " | " << std::setprecision(2) << c.precompute_s << " | " << c.frame_ms << " |"
            << std::defaultfloat << " " << c.note << " |\n";
}

void write_verify_json(const std::vector<VerifyCase>& cases, std::ostream& out) {
    out << "{\n  \"cases\": [\n" << std::setprecision(10);
    for (std::size_t i = 0; i < cases.size(); ++i) {
        const VerifyCase& c = cases[i];
        out << "    {\"key\": \"" << c.key << "\", \"volumetric\": \"" << c.volumetric
            << "\", \"level\": \"" << c.level << "\", \"load_N\": " << c.load_N
            << ", \"nu\": " << c.nu << ", \"measured\": " << c.measured
            << ", \"reference\": " << c.reference << ", \"rel_error\": " << c.rel_error
            << ", \"target\": " << c.target << ", \"within_target\": "
            << (c.target <= 0                       ? "null"
                : std::abs(c.rel_error) <= c.target ? "true"
                                                    : "false")
            << ", \"precompute_s\": " << c.precompute_s << ", \"frame_ms\": " << c.frame_ms
            << ", \"note\": \"" << c.note << "\"}" << (i + 1 < cases.size() ? "," : "") << "\n";
    }
    out << "  ]\n}\n";
}

} // namespace chromasim::generators
