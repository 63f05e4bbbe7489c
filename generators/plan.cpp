#include "generators/plan.hpp"

#include <cmath>
#include <numbers>

namespace chromasim::generators {

Plan make_plan(const Spec& spec) {
    Plan plan;
    const double P = spec.press.normal_force_N;
    for (int k = 0; k < spec.press.frames; ++k) {
        const double s = double(k + 1) / spec.press.frames;
        plan.frames.push_back({int(plan.frames.size()), "press", s * P, {0, 0}, spec.object.mu});
    }
    const double a = spec.pull.direction_deg * std::numbers::pi / 180.0;
    const Eigen::Vector2d dir(std::cos(a), std::sin(a));
    const bool displacement = spec.pull.control == "displacement";
    for (int k = 0; k < spec.pull.frames; ++k) {
        const double s = double(k + 1) / spec.pull.frames;
        FramePlan f{int(plan.frames.size()), "pull", P, {0, 0}, spec.object.mu};
        f.displacement_control = displacement;
        if (displacement)
            f.travel_mm = s * spec.pull.displacement_mm * dir;
        else
            f.tangential_force_N = s * spec.pull.tangential_force_N * dir;
        plan.frames.push_back(f);
    }
    return plan;
}

} // namespace chromasim::generators
