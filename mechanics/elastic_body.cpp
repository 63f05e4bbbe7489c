#include "mechanics/elastic_body.hpp"

#include "mechanics/quadratic_tets.hpp"
#include "mechanics/stopwatch.hpp"
#include "mechanics/supernodal_solve.hpp"

#include <Eigen/CholmodSupport>

#include <dlfcn.h>
#include <tbb/parallel_for.h>

#include <array>
#include <chrono>
#include <mutex>
#include <stdexcept>
#include <string>

namespace chromasim::mechanics {

Embedding embed(const TetMesh& mesh, const Points& P, const char* what) {
    const TetLocator locator(mesh);
    Embedding e;
    for (int i = 0; i < P.rows(); ++i) {
        const int t = locator.locate(P.row(i).transpose());
        if (t < 0)
            throw std::runtime_error(std::string(what) + " " + std::to_string(i) +
                                     " lies outside the mesh");
        e.tet.push_back(t);
        e.weights.push_back(natural_coordinates(mesh, t, P.row(i).transpose()));
    }
    return e;
}

namespace {

/// Keeps BLAS (under CHOLMOD) on the calling thread. chromasim runs its work in parallel
/// above BLAS (TBB: fingertips, tets, pixels), and OpenBLAS's own threads spin on
/// sched_yield while they wait, taking the cores that work needs. A BLAS without the OpenBLAS
/// call is left as it is.
void keep_blas_on_calling_thread() {
    static std::once_flag once;
    std::call_once(once, [] {
        using SetThreads = void (*)(int);
        if (void* f = dlsym(RTLD_DEFAULT, "openblas_set_num_threads"))
            reinterpret_cast<SetThreads>(f)(1);
    });
}

/// CHOLMOD's supernodal LLT whose solves (of a vector or a block of columns) may run on several
/// threads at once: CHOLMOD is re-entrant when each thread brings its own cholmod_common, and a
/// solve only reads the factor.
class ConcurrentLLT : public Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> {
public:
    template <class Dense> Dense solve_concurrently(Dense b) const {
        cholmod_common common;
        cholmod_start(&common);
        cholmod_dense b_view = Eigen::viewAsCholmod(b);
        cholmod_dense* x = cholmod_solve(CHOLMOD_A, m_cholmodFactor, &b_view, &common);
        if (!x) {
            cholmod_finish(&common);
            throw std::runtime_error("CHOLMOD's back-substitution failed (out of memory?)");
        }
        Dense out = Eigen::Map<const Dense>(static_cast<double*>(x->x), b.rows(), b.cols());
        cholmod_free_dense(&x, &common);
        cholmod_finish(&common);
        return out;
    }
    const cholmod_factor& factor() const { return *m_cholmodFactor; }
};

} // namespace

struct ElasticBody::Impl {
    const TetMesh& mesh;
    std::vector<Material> materials;
    std::vector<bool> clamped;
    Volumetric volumetric = Volumetric::element;
    std::vector<int> candidates, observed_nodes;
    Embedding observed_points;
    bool factorized = false;
    std::vector<int> free_of_dof; ///< free-dof index per mesh dof, -1 where clamped
    ConcurrentLLT solver;
    SupernodalSolve single; ///< the factor in single precision (ElasticBody::precondition)
    /// Guards the factorization and the field responses, both made on demand; solves need no
    /// lock (solve_concurrently, SupernodalSolve).
    mutable std::mutex solver_mutex;
    ElasticBodyResponses responses;
    Eigen::MatrixXf field_responses; ///< 3 #V x 3n, on demand (candidate_field_responses)
    ElasticBodyStats stats;

    Impl(const TetMesh& m, const std::vector<Material>& mat, const std::vector<bool>& fixed,
         std::vector<int> cand, Volumetric vol)
        : mesh(m), materials(mat), clamped(fixed), volumetric(vol), candidates(std::move(cand)) {
        stats.candidates = int(candidates.size());
    }
    void factorize();
    /// Factorizes on the first call (a body built from cached responses has no factor yet).
    void ensure_factorized() {
        const std::lock_guard<std::mutex> lock(solver_mutex);
        if (!factorized) factorize();
    }
    void precompute_responses();
    /// `solve` (free dofs to free dofs) on a full-size vector: the clamped dofs' entries are
    /// ignored, and 0 in the result. Factorizes first if need be.
    template <class Solve>
    Eigen::VectorXd on_free_dofs(const Eigen::VectorXd& f_full, const Solve& solve) {
        ensure_factorized();
        Eigen::VectorXd f(stats.free_dofs);
        for (std::size_t d = 0; d < free_of_dof.size(); ++d)
            if (free_of_dof[d] >= 0) f(free_of_dof[d]) = f_full(Eigen::Index(d));
        const Eigen::VectorXd u_free = solve(std::move(f));
        Eigen::VectorXd u = Eigen::VectorXd::Zero(f_full.size());
        for (std::size_t d = 0; d < free_of_dof.size(); ++d)
            if (free_of_dof[d] >= 0) u(Eigen::Index(d)) = u_free(free_of_dof[d]);
        return u;
    }
    void fill_observed(int c0, const Eigen::MatrixXd& u);
};

void ElasticBody::Impl::factorize() {
    keep_blas_on_calling_thread();
    auto t0 = std::chrono::steady_clock::now();
    const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, materials, volumetric);
    free_of_dof.assign(std::size_t(K.rows()), -1);
    int n_free = 0;
    for (int v = 0; v < mesh.V.rows(); ++v)
        if (!clamped[std::size_t(v)])
            for (int k = 0; k < 3; ++k)
                free_of_dof[3 * v + k] = n_free++;
    const Eigen::SparseMatrix<double> Kff = restrict_dofs(K, free_of_dof, n_free);
    stats.assemble_s = seconds_since(t0);
    stats.free_dofs = n_free;

    t0 = std::chrono::steady_clock::now();
    solver.compute(Kff);
    if (solver.info() != Eigen::Success)
        throw std::runtime_error("stiffness factorization failed: the body is not held "
                                 "(no clamped node) or a material is invalid");
    single = SupernodalSolve(solver.factor());
    stats.factorize_s = seconds_since(t0);
    factorized = true;
}

void ElasticBody::Impl::fill_observed(int c0, const Eigen::MatrixXd& u) {
    // u: free-dof responses to the unit forces of columns c0.. (clamped dofs do not move).
    auto node_response = [&](int node, int k) -> Eigen::RowVectorXd {
        const int d = free_of_dof[3 * node + k];
        return d < 0 ? Eigen::RowVectorXd::Zero(u.cols()) : Eigen::RowVectorXd(u.row(d));
    };
    const int nn = int(observed_nodes.size());
    for (int i = 0; i < nn; ++i)
        for (int k = 0; k < 3; ++k)
            responses.observed.row(3 * i + k).segment(c0, u.cols()) =
                node_response(observed_nodes[i], k);
    std::array<int, 10> nodes;
    std::array<double, 10> weights;
    for (std::size_t p = 0; p < observed_points.tet.size(); ++p) {
        const int count = interpolation_stencil(mesh, observed_points.tet[p],
                                                observed_points.weights[p], nodes, weights);
        for (int k = 0; k < 3; ++k) {
            Eigen::RowVectorXd row = Eigen::RowVectorXd::Zero(u.cols());
            for (int a = 0; a < count; ++a)
                row += weights[std::size_t(a)] * node_response(nodes[std::size_t(a)], k);
            responses.observed.row(3 * (nn + int(p)) + k).segment(c0, u.cols()) = row;
        }
    }
}

void ElasticBody::Impl::precompute_responses() {
    const auto t0 = std::chrono::steady_clock::now();
    const int nc = 3 * int(candidates.size());
    Eigen::MatrixXd& compliance = responses.compliance;
    compliance.resize(nc, nc);
    responses.observed.resize(3 * Eigen::Index(observed_nodes.size() + observed_points.tet.size()),
                              nc);
    // Blocks of right-hand sides, each solved with BLAS-3 supernodal triangular solves in its
    // own CHOLMOD workspace, on all cores; each block fills its own columns.
    constexpr int kBlock = 256;
    tbb::parallel_for(0, (nc + kBlock - 1) / kBlock, [&](int block) {
        const int c0 = block * kBlock, c1 = std::min(nc, c0 + kBlock);
        Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(stats.free_dofs, c1 - c0);
        for (int c = c0; c < c1; ++c) {
            const int d = free_of_dof[3 * candidates[c / 3] + c % 3];
            if (d < 0) throw std::runtime_error("a contact candidate node is clamped");
            rhs(d, c - c0) = 1;
        }
        const Eigen::MatrixXd u = solver.solve_concurrently(std::move(rhs));
        for (int r = 0; r < nc; ++r)
            compliance.row(r).segment(c0, c1 - c0) =
                u.row(free_of_dof[3 * candidates[r / 3] + r % 3]);
        fill_observed(c0, u);
    });
    compliance = 0.5 * (compliance + compliance.transpose()).eval(); // exact symmetry
    stats.compliance_s = seconds_since(t0);
}

ElasticBody::ElasticBody(const TetMesh& mesh, const std::vector<Material>& materials,
                         const std::vector<bool>& clamped, std::vector<int> candidates,
                         std::vector<int> observed_nodes, Embedding observed_points,
                         Volumetric volumetric)
    : m_impl(std::make_unique<Impl>(mesh, materials, clamped, std::move(candidates), volumetric)) {
    Impl& m = *m_impl;
    m.observed_nodes = std::move(observed_nodes);
    m.observed_points = std::move(observed_points);
    m.factorize();
    m.precompute_responses();
}

ElasticBody::ElasticBody(const TetMesh& mesh, const std::vector<Material>& materials,
                         const std::vector<bool>& clamped, std::vector<int> candidates,
                         Volumetric volumetric, ElasticBodyResponses responses)
    : m_impl(std::make_unique<Impl>(mesh, materials, clamped, std::move(candidates), volumetric)) {
    Impl& m = *m_impl;
    const Eigen::Index nc = 3 * Eigen::Index(m.candidates.size());
    if (responses.compliance.rows() != nc || responses.compliance.cols() != nc ||
        responses.observed.cols() != nc)
        throw std::runtime_error("precomputed responses do not match the contact candidates");
    m.responses = std::move(responses);
}

ElasticBody::~ElasticBody() = default;

const Eigen::MatrixXd& ElasticBody::compliance() const {
    return m_impl->responses.compliance;
}
const ElasticBodyResponses& ElasticBody::responses() const {
    return m_impl->responses;
}
const std::vector<int>& ElasticBody::candidates() const {
    return m_impl->candidates;
}
const ElasticBodyStats& ElasticBody::stats() const {
    return m_impl->stats;
}

Points ElasticBody::observed_displacement(const Eigen::Ref<const Points>& forces_N,
                                          const std::vector<int>& active) const {
    const Eigen::MatrixXd& R = m_impl->responses.observed;
    Eigen::VectorXd u = Eigen::VectorXd::Zero(R.rows());
    for (int j : active)
        u += R.middleCols<3>(3 * j) * forces_N.row(j).transpose();
    return Eigen::Map<const Points>(u.data(), R.rows() / 3, 3);
}

Eigen::VectorXd ElasticBody::solve(const Eigen::VectorXd& f_full) const {
    return m_impl->on_free_dofs(
        f_full, [&](Eigen::VectorXd f) { return m_impl->solver.solve_concurrently(std::move(f)); });
}

Eigen::VectorXd ElasticBody::precondition(const Eigen::VectorXd& f_full) const {
    return m_impl->on_free_dofs(f_full,
                                [&](const Eigen::VectorXd& f) { return m_impl->single.solve(f); });
}

const Eigen::MatrixXf& ElasticBody::candidate_field_responses() const {
    Impl& m = *m_impl;
    const std::lock_guard<std::mutex> lock(m.solver_mutex);
    if (m.field_responses.size() > 0) return m.field_responses;
    if (!m.factorized) m.factorize();
    const int nc = 3 * int(m.candidates.size());
    Eigen::MatrixXf out = Eigen::MatrixXf::Zero(Eigen::Index(m.free_of_dof.size()), nc);
    constexpr int kBlock = 64;
    tbb::parallel_for(0, (nc + kBlock - 1) / kBlock, [&](int block) {
        const int c0 = block * kBlock, c1 = std::min(nc, c0 + kBlock);
        Eigen::MatrixXf u = Eigen::MatrixXf::Zero(m.stats.free_dofs, c1 - c0);
        for (int c = c0; c < c1; ++c)
            u(m.free_of_dof[3 * m.candidates[c / 3] + c % 3], c - c0) = 1;
        m.single.solve_in_place(u);
        for (std::size_t d = 0; d < m.free_of_dof.size(); ++d)
            if (m.free_of_dof[d] >= 0)
                out.row(Eigen::Index(d)).segment(c0, c1 - c0) = u.row(m.free_of_dof[d]);
    });
    m.field_responses = std::move(out);
    return m.field_responses;
}

Points ElasticBody::full_displacement(const Eigen::Ref<const Points>& forces_N,
                                      const std::vector<int>& active) const {
    Impl& m = *m_impl;
    m.ensure_factorized();
    Eigen::VectorXd f = Eigen::VectorXd::Zero(m.stats.free_dofs);
    for (int j : active)
        for (int k = 0; k < 3; ++k)
            f(m.free_of_dof[3 * m.candidates[j] + k]) = forces_N(j, k);
    const Eigen::VectorXd u_free = m.solver.solve_concurrently(std::move(f));
    Points U = Points::Zero(m.mesh.V.rows(), 3);
    for (std::size_t d = 0; d < m.free_of_dof.size(); ++d)
        if (m.free_of_dof[d] >= 0)
            U(Eigen::Index(d / 3), Eigen::Index(d % 3)) = u_free(m.free_of_dof[d]);
    return U;
}

} // namespace chromasim::mechanics
