#include "generators/output/label_cells.hpp"

#include <cmath>

namespace chromasim::generators {

namespace {

using Cells = std::vector<std::pair<std::string, LabelCell>>;

void finger_cells(const std::string& finger, const LabelRow& r, Cells& out) {
    const double ft = std::hypot(r.tangential_x_N, r.tangential_y_N);
    const double stick_ratio = r.contact_area_mm2 > 0 ? r.stick_area_mm2 / r.contact_area_mm2 : 0.0;
    const Cells cells{{"image", r.image},
                      {"exr", r.exr},
                      {"mu", r.mu},
                      {"normal_force_N", r.normal_force_N},
                      {"requested_tangential_force_N", r.requested_tangential_N},
                      {"tangential_force_N", ft},
                      {"tangential_force_x_N", r.tangential_x_N},
                      {"tangential_force_y_N", r.tangential_y_N},
                      {"frictional_strength_N", r.mu * r.normal_force_N},
                      {"gamma", r.gamma},
                      {"stick_ratio", stick_ratio},
                      {"sliding", long(r.sliding)},
                      {"indentation_mm", r.indentation_mm},
                      {"object_travel_x_mm", r.object_travel_x_mm},
                      {"object_travel_y_mm", r.object_travel_y_mm},
                      {"contact_area_mm2", r.contact_area_mm2},
                      {"stick_area_mm2", r.stick_area_mm2},
                      {"contact_nodes", long(r.contact_nodes)},
                      {"solver_iterations", long(r.solver_iterations)},
                      {"solver_residual_mm", r.solver_residual_mm},
                      {"solver_residual_N", r.solver_residual_N},
                      {"converged", long(r.converged)},
                      {"status", r.status},
                      {"reused", long(r.reused)}};
    for (const auto& [name, cell] : cells)
        out.emplace_back(finger + "_" + name, cell);
}

} // namespace

Cells label_cells(const FrameLabels& f) {
    Cells cells{{"split", f.split},       {"trial", long(f.trial)}, {"frame", long(f.frame)},
                {"time_s", f.time_s},     {"phase", f.phase},       {"object", f.object},
                {"friction", f.friction}, {"grip_N", f.grip_N},     {"load_N", f.load_N},
                {"travel_mm", f.travel_mm}};
    for (std::size_t i = 0; i < f.fingers.size(); ++i)
        finger_cells(finger_name(int(i)), f.fingers[i], cells);
    return cells;
}

std::string labels_header(int fingers) {
    FrameLabels frame;
    frame.fingers.resize(std::size_t(fingers));
    std::string header;
    for (const auto& [name, cell] : label_cells(frame))
        header += (header.empty() ? "" : ",") + name;
    return header;
}

} // namespace chromasim::generators
