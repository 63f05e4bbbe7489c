#pragma once
/// A spec turned into the list of frames to simulate: plain data, no work done yet.
#include "generators/spec.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace chromasim::generators {

struct FramePlan {
    int index = 0;
    std::string phase;                        ///< "press" or "pull"
    double normal_force_N = 0.0;              ///< grip force of this frame
    Eigen::Vector2d tangential_force_N{0, 0}; ///< requested pull (x, y), force control
    double mu = 0.0;
    bool displacement_control = false; ///< the object's travel is prescribed
    Eigen::Vector2d travel_mm{0, 0};   ///< requested travel (x, y), displacement control
};

struct Plan {
    std::vector<FramePlan> frames;
};

/// Press: the normal force ramps linearly to its target over `press.frames` frames (the last
/// at full force). Pull: at full normal force, the tangential force ramps linearly to its
/// target (a force, or the object's travel under displacement control) over `pull.frames`
/// frames along `pull.direction_deg`.
Plan make_plan(const Spec& spec);

} // namespace chromasim::generators
