#include "mechanics/neo_hookean.hpp"

#include "mechanics/neo_hookean_law.hpp"

#include <Eigen/Dense>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace chromasim::mechanics {

namespace {

using namespace neo_hookean_law;
using Gradients = Eigen::Matrix<double, 4, 3>; ///< shape-function gradients, one row per node

template <class Body> void parallel_for_each(int n, Body&& body) {
    tbb::parallel_for(tbb::blocked_range<int>(0, n), [&](const tbb::blocked_range<int>& range) {
        for (int i = range.begin(); i != range.end(); ++i)
            body(i);
    });
}

/// Compressed rows (CSR) from (row, value) pairs, values of each row kept in input order.
void bucket(int rows, const std::vector<int>& row_of, const std::vector<int>& value,
            std::vector<int>& start, std::vector<int>& out) {
    start.assign(std::size_t(rows) + 1, 0);
    for (int r : row_of)
        ++start[std::size_t(r) + 1];
    for (int r = 0; r < rows; ++r)
        start[std::size_t(r) + 1] += start[std::size_t(r)];
    out.resize(row_of.size());
    std::vector<int> next(start.begin(), start.end() - 1);
    for (std::size_t k = 0; k < row_of.size(); ++k)
        out[std::size_t(next[std::size_t(row_of[k])]++)] = value[k];
}

Gradients shape_gradients(const Eigen::Matrix3d& Dm_inv) {
    Gradients G;
    G.bottomRows<3>() = Dm_inv;
    G.row(0) = -Dm_inv.colwise().sum();
    return G;
}

Kinematics kinematics(const Tets& T, int t, const Eigen::Matrix3d& Dm_inv,
                      const Eigen::VectorXd& u) {
    Eigen::Matrix3d dU;
    const Eigen::Vector3d u0 = u.segment<3>(3 * T(t, 0));
    for (int k = 0; k < 3; ++k)
        dU.col(k) = u.segment<3>(3 * T(t, k + 1)) - u0;
    return from_displacement_gradient(dU * Dm_inv);
}

/// Node forces of a tet from its stress: V P grad N_a, as a 12-vector.
Eigen::Matrix<double, 12, 1> nodal_forces(const Eigen::Matrix3d& P, const Gradients& G,
                                          double volume) {
    Eigen::Matrix<double, 12, 1> g;
    for (int a = 0; a < 4; ++a)
        g.segment<3>(3 * a) = volume * P * G.row(a).transpose();
    return g;
}

/// B^T A B with B = dvec(F)/dx (9 x 12, B(i + 3j, 3a + m) = delta_im G(a, j)), using the
/// block structure of B: K_ab = sum_jl G(a, j) G(b, l) A_jl with A_jl the 3 x 3 blocks of A.
Matrix12d element_matrix(const Matrix9d& A, const Gradients& G) {
    Eigen::Matrix<double, 12, 9> GA; // rows 3a + m: sum_j G(a, j) A_j.
    for (int a = 0; a < 4; ++a)
        GA.middleRows<3>(3 * a) = G(a, 0) * A.middleRows<3>(0) + G(a, 1) * A.middleRows<3>(3) +
                                  G(a, 2) * A.middleRows<3>(6);
    Matrix12d K;
    for (int b = 0; b < 4; ++b)
        K.middleCols<3>(3 * b) = G(b, 0) * GA.middleCols<3>(0) + G(b, 1) * GA.middleCols<3>(3) +
                                 G(b, 2) * GA.middleCols<3>(6);
    return K;
}

/// Clamps the negative eigenvalues of a symmetric matrix to zero.
void project_to_psd(Matrix12d& K) {
    const Eigen::SelfAdjointEigenSolver<Matrix12d> eig(K);
    if (eig.eigenvalues()(0) >= 0) return;
    K = eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).asDiagonal() *
        eig.eigenvectors().transpose();
}

/// A block (3 x 3) sparsity pattern in compressed columns: the block rows of block column j
/// are row[start[j] .. start[j + 1]), sorted.
struct BlockColumns {
    std::vector<int> start, row;
    int blocks() const { return int(row.size()); }
    /// Index of block (i, j), which must be in the pattern.
    int find(int i, int j) const {
        const auto first = row.begin() + start[std::size_t(j)];
        const auto last = row.begin() + start[std::size_t(j) + 1];
        return int(std::lower_bound(first, last, i) - row.begin());
    }
};

/// The node pairs that share a group (a tet, a patch): groups in CSR, group g holding nodes
/// group_nodes[group_start[g] .. group_start[g + 1]).
BlockColumns shared_groups(int nodes, const std::vector<int>& group_start,
                           const std::vector<int>& group_nodes) {
    std::vector<int> group_of(group_nodes.size()), node_start, node_groups;
    for (std::size_t g = 0; g + 1 < group_start.size(); ++g)
        for (int k = group_start[g]; k < group_start[g + 1]; ++k)
            group_of[std::size_t(k)] = int(g);
    bucket(nodes, group_nodes, group_of, node_start, node_groups);
    std::vector<std::vector<int>> column(static_cast<std::size_t>(nodes));
    parallel_for_each(nodes, [&](int j) {
        std::vector<int>& rows = column[std::size_t(j)];
        for (int k = node_start[std::size_t(j)]; k < node_start[std::size_t(j) + 1]; ++k) {
            const std::size_t g = std::size_t(node_groups[std::size_t(k)]);
            rows.insert(rows.end(), group_nodes.begin() + group_start[g],
                        group_nodes.begin() + group_start[g + 1]);
        }
        std::sort(rows.begin(), rows.end());
        rows.erase(std::unique(rows.begin(), rows.end()), rows.end());
    });
    BlockColumns columns;
    columns.start.assign(1, 0);
    for (const std::vector<int>& rows : column) {
        columns.row.insert(columns.row.end(), rows.begin(), rows.end());
        columns.start.push_back(int(columns.row.size()));
    }
    return columns;
}

/// The scalar pattern (all values zero) of full 3 x 3 blocks: column 3j + k holds the rows
/// 3i + l of the blocks of block column j, so entry (3i + l, 3j + k) of the r-th block of
/// column j sits at outer[3j + k] + 3r + l.
Eigen::SparseMatrix<double> scalar_pattern(const BlockColumns& columns) {
    const int nodes = int(columns.start.size()) - 1, n = 3 * nodes;
    std::vector<int> outer(std::size_t(n) + 1), inner(std::size_t(columns.blocks()) * 9);
    std::vector<double> zeros(inner.size(), 0.0);
    outer[std::size_t(n)] = 9 * columns.blocks();
    parallel_for_each(nodes, [&](int j) {
        const int s = columns.start[std::size_t(j)], nb = columns.start[std::size_t(j) + 1] - s;
        for (int k = 0; k < 3; ++k) {
            const int o = 9 * s + 3 * k * nb;
            outer[std::size_t(3 * j + k)] = o;
            for (int r = 0; r < nb; ++r)
                for (int l = 0; l < 3; ++l)
                    inner[std::size_t(o + 3 * r + l)] = 3 * columns.row[std::size_t(s + r)] + l;
        }
    });
    return Eigen::Map<Eigen::SparseMatrix<double>>(n, n, 9 * columns.blocks(), outer.data(),
                                                   inner.data(), zeros.data());
}

void throw_if_inverted(bool inverted, const char* what) {
    if (inverted)
        throw std::domain_error(std::string("NeoHookean::") + what +
                                ": inverted element (J <= 0); check min_jacobian first");
}

} // namespace

NeoHookean::NeoHookean(const TetMesh& mesh, const std::vector<Material>& materials,
                       Volumetric volumetric)
    : m_nodes(int(mesh.V.rows())), m_volumetric(volumetric), m_T(mesh.T) {
    const int tets = int(m_T.rows());
    m_Dm_inv.resize(std::size_t(tets));
    m_volume.resize(std::size_t(tets));
    m_mu.resize(std::size_t(tets));
    m_kappa.resize(std::size_t(tets));
    for (int t = 0; t < tets; ++t) {
        const int region = mesh.region(t);
        if (region < 1 || region > int(materials.size()))
            throw std::runtime_error("NeoHookean: tet region without material");
        const Material& m = materials[std::size_t(region - 1)];
        Eigen::Matrix3d Dm;
        for (int k = 0; k < 3; ++k)
            Dm.col(k) = (mesh.V.row(m_T(t, k + 1)) - mesh.V.row(m_T(t, 0))).transpose();
        m_volume[std::size_t(t)] = Dm.determinant() / 6;
        if (!(m_volume[std::size_t(t)] > 0))
            throw std::runtime_error("NeoHookean: degenerate or inverted tet");
        m_Dm_inv[std::size_t(t)] = Dm.inverse();
        m_mu[std::size_t(t)] = m.E_MPa / (2 * (1 + m.nu));
        m_kappa[std::size_t(t)] = m.E_MPa / (3 * (1 - 2 * m.nu));
    }
    std::vector<int> node_of(std::size_t(tets) * 4), entry(std::size_t(tets) * 4);
    for (int e = 0; e < 4 * tets; ++e) {
        node_of[std::size_t(e)] = m_T(e / 4, e % 4);
        entry[std::size_t(e)] = e;
    }
    bucket(m_nodes, node_of, entry, m_node_start, m_node_incidence);
    if (m_volumetric == Volumetric::nodal_average) {
        std::vector<int> regions(mesh.region.data(), mesh.region.data() + tets);
        build_nodal_stencil(regions, int(materials.size()));
    }
    build_pattern();
}

/// One patch per (node, region) pair that has tets, numbered node-major.
void NeoHookean::build_nodal_stencil(const std::vector<int>& region, int regions) {
    const int tets = int(m_T.rows());
    std::vector<int> patch_of_key(std::size_t(m_nodes) * std::size_t(regions), -1);
    std::vector<char> used(patch_of_key.size(), 0);
    auto key = [&](int t, int a) {
        return std::size_t(m_T(t, a)) * std::size_t(regions) + std::size_t(region[t] - 1);
    };
    for (int t = 0; t < tets; ++t)
        for (int a = 0; a < 4; ++a)
            used[key(t, a)] = 1;
    int patches = 0;
    for (std::size_t k = 0; k < used.size(); ++k)
        if (used[k]) patch_of_key[k] = patches++;
    m_tet_patch.resize(std::size_t(tets) * 4);
    m_patch_volume.assign(std::size_t(patches), 0.0);
    m_patch_kappa.assign(std::size_t(patches), 0.0);
    std::vector<int> entry(std::size_t(tets) * 4);
    for (int t = 0; t < tets; ++t)
        for (int a = 0; a < 4; ++a) {
            const int p = patch_of_key[key(t, a)];
            m_tet_patch[std::size_t(4 * t + a)] = p;
            entry[std::size_t(4 * t + a)] = 4 * t + a;
            m_patch_volume[std::size_t(p)] += m_volume[std::size_t(t)] / 4;
            m_patch_kappa[std::size_t(p)] = m_kappa[std::size_t(t)];
        }
    bucket(patches, m_tet_patch, entry, m_patch_start, m_patch_incidence);
    // The nodes each patch touches (sorted), and the local index of every tet node in them.
    m_patch_node_start.assign(1, 0);
    m_patch_nodes.clear();
    m_patch_incidence_local.resize(m_patch_incidence.size() * 4);
    for (int p = 0; p < patches; ++p) {
        const int begin = m_patch_start[std::size_t(p)], end = m_patch_start[std::size_t(p) + 1];
        std::vector<int> nodes;
        for (int k = begin; k < end; ++k)
            for (int b = 0; b < 4; ++b)
                nodes.push_back(m_T(m_patch_incidence[std::size_t(k)] / 4, b));
        std::sort(nodes.begin(), nodes.end());
        nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
        for (int k = begin; k < end; ++k)
            for (int b = 0; b < 4; ++b) {
                const int node = m_T(m_patch_incidence[std::size_t(k)] / 4, b);
                m_patch_incidence_local[std::size_t(4 * k + b)] =
                    int(std::lower_bound(nodes.begin(), nodes.end(), node) - nodes.begin());
            }
        m_patch_nodes.insert(m_patch_nodes.end(), nodes.begin(), nodes.end());
        m_patch_node_start.push_back(int(m_patch_nodes.size()));
    }
}

/// Block pattern: node pairs sharing a tet (element) or a patch (nodal_average); then the
/// scalar pattern and, for every block, the list of terms that add to it, in a fixed order.
void NeoHookean::build_pattern() {
    const int tets = int(m_T.rows());
    std::vector<int> tet_start(std::size_t(tets) + 1);
    for (int t = 0; t <= tets; ++t)
        tet_start[std::size_t(t)] = 4 * t;
    const std::vector<int> tet_nodes(m_T.data(), m_T.data() + 4 * tets); // row-major
    const bool nodal = m_volumetric == Volumetric::nodal_average;
    // Every tet lies in the patches of its nodes: the patch pairs cover the tet pairs.
    const BlockColumns columns = nodal ? shared_groups(m_nodes, m_patch_node_start, m_patch_nodes)
                                       : shared_groups(m_nodes, tet_start, tet_nodes);
    m_block_start = columns.start;
    m_pattern = scalar_pattern(columns);
    // Element terms: the 3 x 3 block (a, b) of tet t sits at 144 t + 12 (3 b) + 3 a.
    std::vector<int> target(std::size_t(tets) * 16), offset(std::size_t(tets) * 16);
    parallel_for_each(tets, [&](int t) {
        for (int a = 0; a < 4; ++a)
            for (int b = 0; b < 4; ++b) {
                target[std::size_t(16 * t + 4 * a + b)] = columns.find(m_T(t, a), m_T(t, b));
                offset[std::size_t(16 * t + 4 * a + b)] = 144 * t + 36 * b + 3 * a;
            }
    });
    bucket(columns.blocks(), target, offset, m_element_term_start, m_element_terms);
    if (!nodal) return;
    // Rank-one terms h_i h_j^T of every patch, over the pairs (i, j) of its nodes.
    target.clear();
    std::vector<int> first, second, start;
    for (std::size_t p = 0; p + 1 < m_patch_node_start.size(); ++p)
        for (int i = m_patch_node_start[p]; i < m_patch_node_start[p + 1]; ++i)
            for (int j = m_patch_node_start[p]; j < m_patch_node_start[p + 1]; ++j) {
                target.push_back(
                    columns.find(m_patch_nodes[std::size_t(i)], m_patch_nodes[std::size_t(j)]));
                first.push_back(i);
                second.push_back(j);
            }
    bucket(columns.blocks(), target, first, m_rank_one_start, m_rank_one_i);
    bucket(columns.blocks(), target, second, start, m_rank_one_j); // same order
}

std::vector<double> NeoHookean::element_jacobians_minus_one(const Eigen::VectorXd& u) const {
    std::vector<double> jm1(m_volume.size());
    parallel_for_each(int(m_T.rows()), [&](int t) {
        jm1[std::size_t(t)] = kinematics(m_T, t, m_Dm_inv[std::size_t(t)], u).jm1;
    });
    return jm1;
}

std::vector<double> NeoHookean::nodal_jacobians_minus_one(const std::vector<double>& jm1) const {
    std::vector<double> patch(m_patch_volume.size());
    parallel_for_each(int(patch.size()), [&](int p) {
        double sum = 0;
        for (int k = m_patch_start[std::size_t(p)]; k < m_patch_start[std::size_t(p) + 1]; ++k) {
            const int t = m_patch_incidence[std::size_t(k)] / 4;
            sum += m_volume[std::size_t(t)] / 4 * jm1[std::size_t(t)];
        }
        patch[std::size_t(p)] = sum / m_patch_volume[std::size_t(p)];
    });
    return patch;
}

std::vector<double> NeoHookean::element_pressures(const std::vector<double>& jm1) const {
    std::vector<double> pressure(jm1.size());
    if (m_volumetric == Volumetric::element) {
        for (std::size_t t = 0; t < jm1.size(); ++t)
            pressure[t] = m_kappa[t] * jm1[t];
        return pressure;
    }
    const std::vector<double> patch = nodal_jacobians_minus_one(jm1);
    parallel_for_each(int(jm1.size()), [&](int t) {
        double sum = 0;
        for (int a = 0; a < 4; ++a)
            sum += patch[std::size_t(m_tet_patch[std::size_t(4 * t + a)])];
        pressure[std::size_t(t)] = m_kappa[std::size_t(t)] / 4 * sum;
    });
    return pressure;
}

double NeoHookean::min_jacobian(const Eigen::VectorXd& u) const {
    const std::vector<double> jm1 = element_jacobians_minus_one(u);
    double lowest = std::numeric_limits<double>::infinity();
    for (double j : jm1)
        lowest = std::min(lowest, j);
    if (m_volumetric == Volumetric::nodal_average)
        for (double j : nodal_jacobians_minus_one(jm1))
            lowest = std::min(lowest, j);
    return 1 + lowest;
}

double NeoHookean::energy(const Eigen::VectorXd& u) const {
    const bool element = m_volumetric == Volumetric::element;
    std::vector<double> jm1(m_volume.size()), energy(m_volume.size());
    parallel_for_each(int(m_T.rows()), [&](int t) {
        const std::size_t i = std::size_t(t);
        const Kinematics k = kinematics(m_T, t, m_Dm_inv[i], u);
        jm1[i] = k.jm1;
        if (!(k.jm1 > -1)) { // also catches NaN
            energy[i] = std::numeric_limits<double>::infinity();
            return;
        }
        energy[i] = m_volume[i] * isochoric_density(k, m_mu[i]);
        if (element) energy[i] += m_volume[i] * m_kappa[i] / 2 * k.jm1 * k.jm1;
    });
    double W = 0;
    for (double e : energy) // serial: the same sum for every thread count
        W += e;
    if (element || !std::isfinite(W)) return W;
    const std::vector<double> patch = nodal_jacobians_minus_one(jm1);
    for (std::size_t p = 0; p < patch.size(); ++p)
        W += m_patch_volume[p] * m_patch_kappa[p] / 2 * patch[p] * patch[p];
    return W;
}

Eigen::VectorXd NeoHookean::gather_nodal(const std::vector<double>& per_tet) const {
    Eigen::VectorXd g(3 * m_nodes);
    parallel_for_each(m_nodes, [&](int j) {
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        for (int k = m_node_start[std::size_t(j)]; k < m_node_start[std::size_t(j) + 1]; ++k) {
            const int e = m_node_incidence[std::size_t(k)]; // 4 t + a
            sum += Eigen::Map<const Eigen::Vector3d>(per_tet.data() + 12 * (e / 4) + 3 * (e % 4));
        }
        g.segment<3>(3 * j) = sum;
    });
    return g;
}

Eigen::VectorXd NeoHookean::gradient(const Eigen::VectorXd& u) const {
    const bool element = m_volumetric == Volumetric::element;
    std::vector<double> pressure;
    if (!element) pressure = element_pressures(element_jacobians_minus_one(u));
    std::vector<double> forces(m_volume.size() * 12);
    std::atomic<bool> inverted{false};
    parallel_for_each(int(m_T.rows()), [&](int t) {
        const std::size_t i = std::size_t(t);
        const Kinematics k = kinematics(m_T, t, m_Dm_inv[i], u);
        if (!(k.jm1 > -1)) inverted = true;
        const double p = element ? m_kappa[i] * k.jm1 : pressure[i];
        Eigen::Map<Eigen::Matrix<double, 12, 1>>(forces.data() + 12 * i) =
            nodal_forces(first_piola(k, m_mu[i], p), shape_gradients(m_Dm_inv[i]), m_volume[i]);
    });
    throw_if_inverted(inverted, "gradient");
    return gather_nodal(forces);
}

Eigen::SparseMatrix<double> NeoHookean::hessian(const Eigen::VectorXd& u, bool project_psd) const {
    Eigen::SparseMatrix<double> H;
    hessian(u, project_psd, H);
    return H;
}

void NeoHookean::hessian(const Eigen::VectorXd& u, bool project_psd,
                         Eigen::SparseMatrix<double>& H) const {
    const bool element = m_volumetric == Volumetric::element;
    const std::size_t tets = m_volume.size();
    // 1. Pressures (nodal_average: from the J of every tet around each node).
    std::vector<double> pressure;
    if (!element) pressure = element_pressures(element_jacobians_minus_one(u));
    // 2. Element blocks (12 x 12, column-major), and, for nodal_average, the gradients of the
    //    deformed volumes V_e dJ_e/dx that the rank-one terms are made of.
    std::vector<double> blocks(tets * 144), volume_gradients(element ? 0 : tets * 12);
    std::atomic<bool> inverted{false};
    parallel_for_each(int(tets), [&](int t) {
        const std::size_t i = std::size_t(t);
        const Kinematics k = kinematics(m_T, t, m_Dm_inv[i], u);
        if (!(k.jm1 > -1)) inverted = true;
        const Gradients G = shape_gradients(m_Dm_inv[i]);
        const double p = element ? m_kappa[i] * k.jm1 : pressure[i];
        const Matrix9d A =
            m_volume[i] * stress_derivative(k, m_mu[i], p, element ? m_kappa[i] : 0.0);
        Matrix12d K = element_matrix(A, G);
        if (project_psd && may_be_indefinite(A)) project_to_psd(K);
        Eigen::Map<Matrix12d>(blocks.data() + 144 * i) = K;
        if (!element)
            Eigen::Map<Eigen::Matrix<double, 12, 1>>(volume_gradients.data() + 12 * i) =
                nodal_forces(cofactor(k.F), G, m_volume[i]);
    });
    throw_if_inverted(inverted, "hessian");
    // 3. nodal_average: the rank-one factors h of the (node, region) pairs.
    const std::vector<double> h = element ? std::vector<double>() : patch_factors(volume_gradients);
    // 4. Every 3 x 3 block sums its terms in a fixed order, into the fixed pattern.
    if (H.rows() != m_pattern.rows() || H.nonZeros() != m_pattern.nonZeros() || !H.isCompressed())
        H = m_pattern;
    sum_blocks(blocks, h, H);
}

std::vector<double> NeoHookean::patch_factors(const std::vector<double>& volume_gradients) const {
    std::vector<double> h(m_patch_nodes.size() * 3, 0.0);
    parallel_for_each(int(m_patch_volume.size()), [&](int p) {
        const std::size_t q = std::size_t(p);
        // h = sqrt(kappa V_ar) dJ_ar/dx with dJ_ar/dx = sum over the patch of V_e/4 dJ_e/dx / V_ar.
        const double scale = std::sqrt(m_patch_kappa[q] / m_patch_volume[q]) / 4;
        double* hp = h.data() + 3 * m_patch_node_start[q];
        for (int k = m_patch_start[q]; k < m_patch_start[q + 1]; ++k) {
            const double* dv =
                volume_gradients.data() + 12 * (m_patch_incidence[std::size_t(k)] / 4);
            for (int b = 0; b < 4; ++b) {
                const int local = m_patch_incidence_local[std::size_t(4 * k + b)];
                for (int l = 0; l < 3; ++l)
                    hp[3 * local + l] += scale * dv[3 * b + l];
            }
        }
    });
    return h;
}

void NeoHookean::sum_blocks(const std::vector<double>& blocks, const std::vector<double>& h,
                            Eigen::SparseMatrix<double>& H) const {
    const int* outer = H.outerIndexPtr();
    double* values = H.valuePtr();
    parallel_for_each(m_nodes, [&](int j) {
        const int s = m_block_start[std::size_t(j)], nb = m_block_start[std::size_t(j) + 1] - s;
        for (int r = 0; r < nb; ++r) {
            const std::size_t q = std::size_t(s + r);
            Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
            for (int k = m_element_term_start[q]; k < m_element_term_start[q + 1]; ++k) {
                const double* src = blocks.data() + m_element_terms[std::size_t(k)];
                for (int c = 0; c < 3; ++c)
                    M.col(c) += Eigen::Map<const Eigen::Vector3d>(src + 12 * c);
            }
            if (!h.empty())
                for (int k = m_rank_one_start[q]; k < m_rank_one_start[q + 1]; ++k)
                    M.noalias() += Eigen::Map<const Eigen::Vector3d>(
                                       h.data() + 3 * m_rank_one_i[std::size_t(k)]) *
                                   Eigen::Map<const Eigen::Vector3d>(
                                       h.data() + 3 * m_rank_one_j[std::size_t(k)])
                                       .transpose();
            for (int c = 0; c < 3; ++c)
                for (int l = 0; l < 3; ++l)
                    values[outer[3 * j + c] + 3 * r + l] = M(l, c);
        }
    });
}

} // namespace chromasim::mechanics
