#include "mechanics/dome_model.hpp"

#include "mechanics/stopwatch.hpp"
#include "mechanics/tetgen_adapter.hpp"

#include <Eigen/Geometry>

#include <chrono>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace chromasim::mechanics {

namespace {

SurfacePatch make_patch(const Triangles& F_global) {
    SurfacePatch patch;
    std::vector<int> local_of;
    patch.F.resize(F_global.rows(), 3);
    for (int f = 0; f < F_global.rows(); ++f)
        for (int k = 0; k < 3; ++k) {
            const int g = F_global(f, k);
            if (g >= int(local_of.size())) local_of.resize(std::size_t(g) + 1, -1);
            if (local_of[g] < 0) {
                local_of[g] = int(patch.nodes.size());
                patch.nodes.push_back(g);
            }
            patch.F(f, k) = local_of[g];
        }
    return patch;
}

} // namespace

struct DomeModel::Impl {
    DomeModelOptions options;
    TetMesh mesh;
    MarkerDiscs markers;
    SurfacePatch coating;
    std::vector<int> candidates; ///< mesh nodes that may touch
    Points candidate_X;          ///< their undeformed positions (mm)
    std::vector<double> candidate_area_mm2;
    std::vector<bool> candidate_edge; ///< in the outermost band of the candidate cap
    std::unique_ptr<ElasticBody> body;
    PrecomputeStats stats;

    void build_mesh();
    void find_candidates();
    void build_body();
};

void DomeModel::Impl::build_mesh() {
    const auto t0 = std::chrono::steady_clock::now();
    const MeshLevel level = mesh_level(options.mesh_level);
    TetgenOptions tg;
    tg.max_volume_mm3 = level.max_volume_mm3;
    mesh = tetrahedralize(dome_plc(options.dome, level.edge_mm), tg);
    markers = marker_discs(options.dome);
    coating = make_patch(interface_faces(mesh, kCoating, kOuterMarkerLayer));
    stats.mesh_s = seconds_since(t0);
    stats.nodes = int(mesh.V.rows());
    stats.tets = int(mesh.T.rows());
}

void DomeModel::Impl::find_candidates() {
    const double R = options.dome.radii_mm.back();
    const double cos_max = std::cos(options.contact_candidate_angle_deg * std::numbers::pi / 180);
    const double edge_band = 1.5 * mesh_level(options.mesh_level).edge_mm / R; // radians
    const double cos_edge =
        std::cos(options.contact_candidate_angle_deg * std::numbers::pi / 180 - edge_band);
    // Outer surface: boundary faces of the coating off the rim plane; tributary nodal areas.
    const Triangles outer = interface_faces(mesh, kCoating, -1);
    std::vector<double> area(std::size_t(mesh.V.rows()), 0.0);
    for (int f = 0; f < outer.rows(); ++f) {
        const Eigen::Vector3d a = mesh.V.row(outer(f, 0)), b = mesh.V.row(outer(f, 1)),
                              c = mesh.V.row(outer(f, 2));
        if (std::abs(a.norm() - R) > 1e-6 || std::abs(b.norm() - R) > 1e-6 ||
            std::abs(c.norm() - R) > 1e-6)
            continue;
        const double third = (b - a).cross(c - a).norm() / 6.0;
        for (int k = 0; k < 3; ++k)
            area[outer(f, k)] += third;
    }
    for (int v = 0; v < mesh.V.rows(); ++v) {
        const double cz = mesh.V(v, 2) / R;
        if (area[v] > 0 && cz >= cos_max) {
            candidates.push_back(v);
            candidate_area_mm2.push_back(area[v]);
            candidate_edge.push_back(cz < cos_edge);
        }
    }
    if (candidates.empty()) throw std::runtime_error("no contact candidate nodes on the dome");
    candidate_X.resize(Eigen::Index(candidates.size()), 3);
    for (std::size_t i = 0; i < candidates.size(); ++i)
        candidate_X.row(Eigen::Index(i)) = mesh.V.row(candidates[i]);
    stats.candidates = int(candidates.size());
}

void DomeModel::Impl::build_body() {
    // Clamp the rim: every node in the plane z = 0.
    std::vector<bool> clamped(std::size_t(mesh.V.rows()));
    for (int v = 0; v < mesh.V.rows(); ++v)
        clamped[std::size_t(v)] = mesh.V(v, 2) <= 1e-9;
    body = std::make_unique<ElasticBody>(
        mesh, std::vector<Material>(options.materials.begin(), options.materials.end()), clamped,
        candidates, coating.nodes, embed(mesh, markers.points, "marker point"), options.volumetric);
    const ElasticBodyStats& b = body->stats();
    stats.assemble_s = b.assemble_s;
    stats.factorize_s = b.factorize_s;
    stats.compliance_s = b.compliance_s;
    stats.free_dofs = b.free_dofs;
}

DomeModel::DomeModel(const DomeModelOptions& options) : m_impl(std::make_unique<Impl>()) {
    m_impl->options = options;
    m_impl->build_mesh();
    m_impl->find_candidates();
    m_impl->build_body();
}

DomeModel::~DomeModel() = default;

FrameResult DomeModel::solve(const ContactLoad& load, const FrameRequest& request,
                             const ObjectShape& object) const {
    const Impl& m = *m_impl;
    FrameResult r;
    r.contact = solve_contact(m.body->compliance(), object_gap(object, m.candidate_X), load);
    for (int j : r.contact.active) {
        r.contact_area_mm2 += m.candidate_area_mm2[j];
        r.at_candidate_edge = r.at_candidate_edge || m.candidate_edge[j];
    }
    r.stick_area_mm2 = r.contact_area_mm2;
    for (int j : r.contact.slipping)
        r.stick_area_mm2 -= m.candidate_area_mm2[j];
    if (request.full_field)
        r.node_displacement_mm = m.body->full_displacement(r.contact.forces_N, r.contact.active);
    if (!request.coating && !request.markers) return r;
    const Points u = m.body->observed_displacement(r.contact.forces_N, r.contact.active);
    const Eigen::Index n_coating = Eigen::Index(m.coating.nodes.size());
    if (request.coating) r.coating_displacement_mm = u.topRows(n_coating);
    if (request.markers) r.marker_points_mm = m.markers.points + u.bottomRows(u.rows() - n_coating);
    return r;
}

const TetMesh& DomeModel::mesh() const {
    return m_impl->mesh;
}
const MarkerDiscs& DomeModel::markers() const {
    return m_impl->markers;
}
const SurfacePatch& DomeModel::coating_surface() const {
    return m_impl->coating;
}
const PrecomputeStats& DomeModel::stats() const {
    return m_impl->stats;
}

} // namespace chromasim::mechanics
