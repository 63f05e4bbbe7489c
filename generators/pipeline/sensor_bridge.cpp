#include "generators/pipeline/sensor_bridge.hpp"

#include <algorithm>
#include <vector>

namespace chromasim::generators {

namespace {

constexpr int kPrismTriangles = 4; // per rim point

/// The closed marker volumes of one layer (MarkerDiscs layout: per marker the mid ring, then
/// the inner-face and outer-face rings) as a SurfaceMesh of 4 rim triangles per marker.
void fill_prisms(const mechanics::Points& points, const mechanics::MarkerDiscs& discs, int layer,
                 render::SurfaceMesh& out) {
    const int markers = discs.markers_per_layer, rim = discs.rim_points, ring = 1 + rim;
    const int first = layer * markers * discs.points_per_marker;
    out.V = points.middleRows(first, Eigen::Index(markers) * discs.points_per_marker).cast<float>();
    const Eigen::Index triangles = Eigen::Index(markers) * kPrismTriangles * rim;
    if (out.F.rows() == triangles) return; // topology unchanged
    out.F.resize(triangles, 3);
    Eigen::Index f = 0;
    for (int m = 0; m < markers; ++m) {
        const auto in = std::uint32_t(m * discs.points_per_marker + ring); // inner-face centre
        const auto outer = in + std::uint32_t(ring);                       // outer-face centre
        for (int k = 0; k < rim; ++k) {
            const std::uint32_t a = 1 + std::uint32_t(k), b = 1 + std::uint32_t((k + 1) % rim);
            out.F.row(f++) << in, in + b, in + a;          // faces -n
            out.F.row(f++) << outer, outer + a, outer + b; // faces +n
            out.F.row(f++) << in + a, in + b, outer + b;   // side, faces outwards
            out.F.row(f++) << in + a, outer + b, outer + a;
        }
    }
}
} // namespace

mechanics::ContactLoad contact_load(const FingerLoad& f) {
    mechanics::ContactLoad load{f.normal_force_N, f.tangential_force_N, f.mu};
    if (f.displacement_control) {
        load.tangential = mechanics::TangentialControl::displacement;
        load.tangential_displacement_mm = f.travel_mm;
    }
    return load;
}

double median_marker_thickness_mm(const mechanics::DomeModel& model) {
    std::vector<double> thickness = model.markers().thickness_mm;
    const auto middle = thickness.begin() + std::ptrdiff_t(thickness.size() / 2);
    std::nth_element(thickness.begin(), middle, thickness.end());
    return *middle;
}

render::SensorFrame undeformed_sensor_frame(const mechanics::DomeModel& model) {
    mechanics::FrameResult rest;
    rest.coating_displacement_mm =
        mechanics::Points::Zero(Eigen::Index(model.coating_surface().nodes.size()), 3);
    rest.inner_surface_displacement_mm =
        mechanics::Points::Zero(Eigen::Index(model.inner_surface().nodes.size()), 3);
    rest.marker_points_mm = model.markers().points;
    render::SensorFrame frame;
    fill_sensor_frame(model, rest, frame);
    return frame;
}

void fill_sensor_frame(const mechanics::DomeModel& model, const mechanics::FrameResult& frame,
                       render::SensorFrame& out) {
    if (frame.coating_displacement_mm.rows() == 0 || frame.marker_points_mm.rows() == 0)
        throw std::logic_error("fill_sensor_frame: frame solved without displacement fields");
    const mechanics::SurfacePatch& coating = model.coating_surface();
    const mechanics::TetMesh& mesh = model.mesh();
    out.coating.V.resize(Eigen::Index(coating.nodes.size()), 3);
    for (std::size_t i = 0; i < coating.nodes.size(); ++i) {
        const int n = coating.nodes[i];
        out.coating.V.row(Eigen::Index(i)) =
            (mesh.V.row(n) + frame.coating_displacement_mm.row(Eigen::Index(i))).cast<float>();
    }
    if (out.coating.F.rows() != coating.F.rows()) out.coating.F = coating.F.cast<std::uint32_t>();
    const mechanics::SurfacePatch& inner = model.inner_surface();
    if (frame.inner_surface_displacement_mm.rows() == Eigen::Index(inner.nodes.size())) {
        out.inner_surface.V.resize(Eigen::Index(inner.nodes.size()), 3);
        for (std::size_t i = 0; i < inner.nodes.size(); ++i) {
            const int n = inner.nodes[i];
            out.inner_surface.V.row(Eigen::Index(i)) =
                (mesh.V.row(n) + frame.inner_surface_displacement_mm.row(Eigen::Index(i)))
                    .cast<float>();
        }
        if (out.inner_surface.F.rows() != inner.F.rows())
            out.inner_surface.F = inner.F.cast<std::uint32_t>();
    } else {
        out.inner_surface = {};
    }
    const mechanics::MarkerDiscs& discs = model.markers();
    fill_prisms(frame.marker_points_mm, discs, 0, out.inner_markers);
    fill_prisms(frame.marker_points_mm, discs, 1, out.outer_markers);
    out.triangles_per_marker = kPrismTriangles * discs.rim_points;
}

} // namespace chromasim::generators
