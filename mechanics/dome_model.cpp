#include "mechanics/dome_model.hpp"

#include "mechanics/tetgen_adapter.hpp"

#include <Eigen/CholmodSupport>
#include <Eigen/Geometry>

#include <chrono>
#include <cmath>
#include <mutex>
#include <numbers>
#include <stdexcept>

namespace chromasim::mechanics {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

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

/// Barycentric embedding of points in the mesh: tet and weights per point.
struct Embedding {
    std::vector<int> tet;
    std::vector<Eigen::Vector4d> weights;
};

Embedding embed(const TetMesh& mesh, const Points& P) {
    const TetLocator locator(mesh);
    Embedding e;
    for (int i = 0; i < P.rows(); ++i) {
        const int t = locator.locate(P.row(i).transpose());
        if (t < 0)
            throw std::runtime_error("marker point " + std::to_string(i) +
                                     " lies outside the dome mesh");
        e.tet.push_back(t);
        e.weights.push_back(barycentric(mesh, t, P.row(i).transpose()));
    }
    return e;
}

} // namespace

struct DomeModel::Impl {
    DomeModelOptions options;
    TetMesh mesh;
    MarkerDiscs markers;
    Embedding marker_embedding;
    SurfacePatch coating;
    std::vector<int> free_of_dof; ///< free-dof index per mesh dof, -1 where clamped
    Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> solver;
    std::vector<int> candidates; ///< mesh nodes that may touch
    std::vector<double> candidate_area_mm2;
    std::vector<bool> candidate_edge; ///< in the outermost band of the candidate cap
    Eigen::MatrixXd compliance;       ///< 3n x 3n (mm/N)
    /// Response (mm/N) of the observed points to unit forces on the candidates: rows 3i..3i+2
    /// for coating vertex i, then for marker point p (rows 3 (#coating + p) ..). 3n columns.
    Eigen::MatrixXd observed_response;
    mutable std::mutex solver_mutex; ///< CHOLMOD's solve shares one workspace
    Eigen::VectorXd gap_mm;
    PrecomputeStats stats;

    void build_mesh();
    void factorize();
    void find_candidates();
    void compute_compliance();
    Eigen::VectorXd solve_field(const ContactSolution& contact) const;
    void fill_observed(int c0, const Eigen::MatrixXd& u);
    Eigen::VectorXd observed_field(const ContactSolution& contact) const;
};

void DomeModel::Impl::build_mesh() {
    const auto t0 = std::chrono::steady_clock::now();
    const MeshLevel level = mesh_level(options.mesh_level);
    TetgenOptions tg;
    tg.max_volume_mm3 = level.max_volume_mm3;
    mesh = tetrahedralize(dome_plc(options.dome, level.edge_mm), tg);
    markers = marker_discs(options.dome);
    marker_embedding = embed(mesh, markers.points);
    coating = make_patch(interface_faces(mesh, kCoating, kOuterMarkerLayer));
    stats.mesh_s = seconds_since(t0);
    stats.nodes = int(mesh.V.rows());
    stats.tets = int(mesh.T.rows());
}

void DomeModel::Impl::factorize() {
    auto t0 = std::chrono::steady_clock::now();
    std::vector<Material> materials(options.materials.begin(), options.materials.end());
    const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, materials);
    // Clamp the rim: every node in the plane z = 0.
    free_of_dof.assign(std::size_t(K.rows()), -1);
    int n_free = 0;
    for (int v = 0; v < mesh.V.rows(); ++v)
        if (mesh.V(v, 2) > 1e-9)
            for (int k = 0; k < 3; ++k)
                free_of_dof[3 * v + k] = n_free++;
    const Eigen::SparseMatrix<double> Kff = restrict_dofs(K, free_of_dof, n_free);
    stats.assemble_s = seconds_since(t0);
    stats.free_dofs = n_free;

    t0 = std::chrono::steady_clock::now();
    solver.compute(Kff);
    if (solver.info() != Eigen::Success)
        throw std::runtime_error("stiffness factorization failed (is the dome clamped?)");
    stats.factorize_s = seconds_since(t0);
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
    stats.candidates = int(candidates.size());
    gap_mm.resize(Eigen::Index(candidates.size()));
    for (std::size_t i = 0; i < candidates.size(); ++i)
        gap_mm(i) = R - mesh.V(candidates[i], 2);
}

void DomeModel::Impl::fill_observed(int c0, const Eigen::MatrixXd& u) {
    // u: free-dof responses to the unit forces of columns c0.. (clamped dofs do not move).
    auto node_response = [&](int node, int k) -> Eigen::RowVectorXd {
        const int d = free_of_dof[3 * node + k];
        return d < 0 ? Eigen::RowVectorXd::Zero(u.cols()) : Eigen::RowVectorXd(u.row(d));
    };
    const int nc = int(coating.nodes.size());
    for (int i = 0; i < nc; ++i)
        for (int k = 0; k < 3; ++k)
            observed_response.row(3 * i + k).segment(c0, u.cols()) =
                node_response(coating.nodes[i], k);
    for (std::size_t p = 0; p < marker_embedding.tet.size(); ++p) {
        const int t = marker_embedding.tet[p];
        for (int k = 0; k < 3; ++k) {
            Eigen::RowVectorXd row = Eigen::RowVectorXd::Zero(u.cols());
            for (int a = 0; a < 4; ++a)
                row += marker_embedding.weights[p](a) * node_response(mesh.T(t, a), k);
            observed_response.row(3 * (nc + int(p)) + k).segment(c0, u.cols()) = row;
        }
    }
}

void DomeModel::Impl::compute_compliance() {
    const auto t0 = std::chrono::steady_clock::now();
    const int n = int(candidates.size()), nc = 3 * n;
    compliance.resize(nc, nc);
    // CHOLMOD's solve is not re-entrant (one workspace): blocks of right-hand sides in turn,
    // each solved with BLAS-3 supernodal triangular solves. The same solves give the response
    // of the observed points (coating, markers), so frames need no sparse solve.
    observed_response.resize(3 * Eigen::Index(coating.nodes.size() + marker_embedding.tet.size()),
                             nc);
    constexpr int kBlock = 256;
    for (int c0 = 0; c0 < nc; c0 += kBlock) {
        const int c1 = std::min(nc, c0 + kBlock);
        Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(stats.free_dofs, c1 - c0);
        for (int c = c0; c < c1; ++c)
            rhs(free_of_dof[3 * candidates[c / 3] + c % 3], c - c0) = 1;
        const Eigen::MatrixXd u = solver.solve(rhs);
        for (int r = 0; r < nc; ++r)
            compliance.row(r).segment(c0, c1 - c0) =
                u.row(free_of_dof[3 * candidates[r / 3] + r % 3]);
        fill_observed(c0, u);
    }
    compliance = 0.5 * (compliance + compliance.transpose()).eval(); // exact symmetry
    stats.compliance_s = seconds_since(t0);
}

Eigen::VectorXd DomeModel::Impl::solve_field(const ContactSolution& contact) const {
    Eigen::VectorXd f = Eigen::VectorXd::Zero(stats.free_dofs);
    for (int j : contact.active)
        for (int k = 0; k < 3; ++k)
            f(free_of_dof[3 * candidates[j] + k]) = contact.forces_N(j, k);
    Eigen::VectorXd u_free;
    {
        const std::lock_guard<std::mutex> lock(solver_mutex);
        u_free = solver.solve(f);
    }
    Eigen::VectorXd u = Eigen::VectorXd::Zero(3 * mesh.V.rows());
    for (std::size_t d = 0; d < free_of_dof.size(); ++d)
        if (free_of_dof[d] >= 0) u(Eigen::Index(d)) = u_free(free_of_dof[d]);
    return u;
}

Eigen::VectorXd DomeModel::Impl::observed_field(const ContactSolution& contact) const {
    Eigen::VectorXd u = Eigen::VectorXd::Zero(observed_response.rows());
    for (int j : contact.active)
        u += observed_response.middleCols<3>(3 * j) * contact.forces_N.row(j).transpose();
    return u;
}

DomeModel::DomeModel(const DomeModelOptions& options) : m_impl(std::make_unique<Impl>()) {
    m_impl->options = options;
    m_impl->build_mesh();
    m_impl->factorize();
    m_impl->find_candidates();
    m_impl->compute_compliance();
}

DomeModel::~DomeModel() = default;

FrameResult DomeModel::solve(const ContactLoad& load, const FrameRequest& request) const {
    const Impl& m = *m_impl;
    FrameResult r;
    r.contact = solve_flat_contact(m.compliance, m.gap_mm, load);
    for (int j : r.contact.active) {
        r.contact_area_mm2 += m.candidate_area_mm2[j];
        r.at_candidate_edge = r.at_candidate_edge || m.candidate_edge[j];
    }
    if (request.full_field) {
        const Eigen::VectorXd u = m.solve_field(r.contact);
        r.node_displacement_mm = Eigen::Map<const Points>(u.data(), m.mesh.V.rows(), 3);
    }
    if (!request.coating && !request.markers) return r;
    const Eigen::VectorXd u = m.observed_field(r.contact);
    const Eigen::Index n_coating = Eigen::Index(m.coating.nodes.size());
    if (request.coating)
        r.coating_displacement_mm = Eigen::Map<const Points>(u.data(), n_coating, 3);
    if (request.markers)
        r.marker_points_mm =
            m.markers.points +
            Eigen::Map<const Points>(u.data() + 3 * n_coating, m.markers.points.rows(), 3);
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
