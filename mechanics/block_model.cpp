#include "mechanics/block_model.hpp"

#include "mechanics/half_space.hpp"
#include "mechanics/stopwatch.hpp"
#include "mechanics/tetgen_adapter.hpp"

#include <Eigen/Geometry>

#include <chrono>
#include <cmath>
#include <stdexcept>

namespace chromasim::mechanics {

namespace {

Plc box_plc(double w, double h) {
    Plc plc;
    plc.points.resize(8, 3);
    for (int i = 0; i < 8; ++i)
        plc.points.row(i) << ((i & 1) ? w : -w), ((i & 2) ? w : -w), ((i & 4) ? 0.0 : -h);
    plc.facets = {{0, 1, 3, 2}, {4, 5, 7, 6}, {0, 1, 5, 4},
                  {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 3, 7, 5}};
    plc.regions.push_back({Eigen::Vector3d(0.1 * w, 0.2 * w, -0.5 * h), 1});
    return plc;
}

/// Extra mesh points grading the mesh away from the contact: a grid of spacing h in the
/// half-ball |x| <= r0 below the top face, then spacing 2h out to 2 r0, 4h out to 4 r0, ...
/// up to `extent` (the block's half-width).
Points graded_points(double r0, double h, double extent) {
    std::vector<Eigen::Vector3d> pts;
    double inner = 0, outer = r0;
    while (inner < extent) {
        const double lim = std::min(outer, extent);
        for (double x = -lim; x <= lim + 1e-12; x += h)
            for (double y = -lim; y <= lim + 1e-12; y += h)
                for (double z = 0; z >= -lim - 1e-12; z -= h) {
                    const double r = std::sqrt(x * x + y * y + z * z);
                    if (r <= lim && r > inner - 1e-12) pts.emplace_back(x, y, z);
                }
        inner = outer;
        outer *= 2;
        h *= 2;
    }
    Points P(Eigen::Index(pts.size()), 3);
    for (std::size_t i = 0; i < pts.size(); ++i)
        P.row(Eigen::Index(i)) = pts[i].transpose();
    return P;
}

} // namespace

BlockParams block_level(const std::string& name) {
    BlockParams p;
    if (name == "coarse")
        p.fine_spacing_mm = 0.4;
    else if (name == "medium")
        p.fine_spacing_mm = 0.25;
    else if (name == "fine")
        p.fine_spacing_mm = 0.2;
    else
        throw std::invalid_argument("unknown block level '" + name +
                                    "'; allowed: coarse, medium, fine");
    return p;
}

struct BlockModel::Impl {
    BlockParams params;
    TetMesh mesh;
    Points candidate_X;
    std::vector<double> candidate_area;
    std::unique_ptr<ElasticBody> body;
    Eigen::MatrixXd compliance; ///< the body's, plus the far field's rank-3 part
    BlockStats stats;

    /// Top face: tributary areas; candidates within the contact radius. Base (and with the far
    /// field, the sides): clamped. Returns the candidate nodes; `clamped` per node.
    std::vector<int> find_candidates(std::vector<bool>& clamped);
    /// Adds the far field's part to the compliance: per unit total force along x, y, z, the
    /// clamped boundary takes the half-space field and the inside follows (K_ff u_f = -K_fc
    /// u_c); the candidates' displacement R_b is added to every column of force component b.
    void add_far_field(const std::vector<int>& candidates, const std::vector<bool>& clamped);
};

std::vector<int> BlockModel::Impl::find_candidates(std::vector<bool>& clamped) {
    const std::vector<double> area =
        tributary_areas(mesh, interface_faces(mesh, 1, -1),
                        [](const Eigen::Vector3d& p) { return std::abs(p.z()) <= 1e-9; });
    std::vector<int> candidates;
    clamped.assign(std::size_t(mesh.V.rows()), false);
    const double r_max = params.contact_radius_mm;
    const double side = params.half_width_mm * (1 - 1e-12);
    for (int v = 0; v < mesh.V.rows(); ++v) {
        const bool on_side = std::abs(mesh.V(v, 0)) >= side || std::abs(mesh.V(v, 1)) >= side;
        clamped[std::size_t(v)] =
            mesh.V(v, 2) <= -params.depth_mm + 1e-9 || (params.far_field && on_side);
        const double r2 = mesh.V(v, 0) * mesh.V(v, 0) + mesh.V(v, 1) * mesh.V(v, 1);
        if (area[v] > 0 && r2 <= r_max * r_max) {
            candidates.push_back(v);
            candidate_area.push_back(area[v]);
        }
    }
    candidate_X.resize(Eigen::Index(candidates.size()), 3);
    for (std::size_t i = 0; i < candidates.size(); ++i)
        candidate_X.row(Eigen::Index(i)) = mesh.V.row(candidates[i]);
    return candidates;
}

void BlockModel::Impl::add_far_field(const std::vector<int>& candidates,
                                     const std::vector<bool>& clamped) {
    const Eigen::SparseMatrix<double> K =
        assemble_stiffness(mesh, {params.material}, params.volumetric);
    for (int b = 0; b < 3; ++b) {
        Eigen::VectorXd u_boundary = Eigen::VectorXd::Zero(3 * mesh.V.rows());
        for (int v = 0; v < mesh.V.rows(); ++v)
            if (clamped[std::size_t(v)])
                u_boundary.segment<3>(3 * v) =
                    half_space_green(mesh.V.row(v).transpose(), params.material.E_MPa,
                                     params.material.nu)
                        .col(b);
        const Eigen::VectorXd u = body->solve(-(K * u_boundary)) + u_boundary;
        for (std::size_t i = 0; i < candidates.size(); ++i)
            for (int a = 0; a < 3; ++a) {
                const double r = u(3 * candidates[i] + a);
                for (std::size_t j = 0; j < candidates.size(); ++j)
                    compliance(3 * Eigen::Index(i) + a, 3 * Eigen::Index(j) + b) += r;
            }
    }
}

BlockModel::BlockModel(const BlockParams& params) : m_impl(std::make_unique<Impl>()) {
    Impl& m = *m_impl;
    m.params = params;
    auto t0 = std::chrono::steady_clock::now();
    TetgenOptions tg;
    tg.max_volume_mm3 = params.max_volume_mm3;
    tg.preserve_surface = false; // the flat faces may take Steiner points
    tg.extra_points =
        graded_points(params.contact_radius_mm + 2 * params.fine_spacing_mm, params.fine_spacing_mm,
                      std::min(params.half_width_mm, params.depth_mm) - 1e-6);
    m.mesh = tetrahedralize(box_plc(params.half_width_mm, params.depth_mm), tg);
    m.stats.mesh_s = seconds_since(t0);
    m.stats.nodes = int(m.mesh.V.rows());
    m.stats.tets = int(m.mesh.T.rows());

    std::vector<bool> clamped;
    const std::vector<int> candidates = m.find_candidates(clamped);
    m.stats.candidates = int(candidates.size());
    t0 = std::chrono::steady_clock::now();
    m.body = std::make_unique<ElasticBody>(m.mesh, std::vector<Material>{params.material}, clamped,
                                           candidates, std::vector<int>{}, Embedding{},
                                           params.volumetric);
    m.compliance = m.body->compliance();
    if (params.far_field) m.add_far_field(candidates, clamped);
    m.stats.precompute_s = seconds_since(t0);
}

BlockModel::~BlockModel() = default;

ContactSolution BlockModel::solve(const ContactLoad& load, const ObjectShape& object,
                                  const LoadPath& path, const ContactSolution* previous,
                                  const ContactOptions& options) const {
    return solve_contact_path(m_impl->compliance, object, m_impl->candidate_X, load, path, previous,
                              options);
}

const Points& BlockModel::candidate_positions() const {
    return m_impl->candidate_X;
}
const std::vector<double>& BlockModel::candidate_areas() const {
    return m_impl->candidate_area;
}
const BlockStats& BlockModel::stats() const {
    return m_impl->stats;
}

} // namespace chromasim::mechanics
