#include "mechanics/supernodal_solve.hpp"

#include <suitesparse/cholmod.h>

#include <stdexcept>

namespace chromasim::mechanics {

namespace {

using BlockMap = Eigen::Map<const Eigen::MatrixXf, 0, Eigen::OuterStride<>>;

} // namespace

SupernodalSolve::SupernodalSolve(const cholmod_factor_struct& L) {
    if (!L.is_super || !L.is_ll || L.itype != CHOLMOD_INT || L.xtype != CHOLMOD_REAL ||
        L.dtype != CHOLMOD_DOUBLE || L.minor < L.n)
        throw std::invalid_argument("SupernodalSolve: not a complete real supernodal LL' "
                                    "factor with int indices");
    m_n = Eigen::Index(L.n);
    const int* super = static_cast<const int*>(L.super);
    const int* pi = static_cast<const int*>(L.pi);
    const int* px = static_cast<const int*>(L.px);
    const int* s = static_cast<const int*>(L.s);
    const double* x = static_cast<const double*>(L.x);
    const int* perm = static_cast<const int*>(L.Perm);
    m_permutation.assign(perm, perm + L.n);
    m_supernodes.resize(L.nsuper);
    for (std::size_t k = 0; k < L.nsuper; ++k) {
        Supernode& sn = m_supernodes[k];
        sn.first_column = super[k];
        sn.columns = super[k + 1] - super[k];
        sn.rows = pi[k + 1] - pi[k];
        sn.values = std::int64_t(m_values.size());
        sn.pattern = std::int64_t(m_below_rows.size());
        m_values.insert(m_values.end(), x + px[k], x + px[k] + std::int64_t(sn.rows) * sn.columns);
        m_below_rows.insert(m_below_rows.end(), s + pi[k] + sn.columns, s + pi[k + 1]);
        m_max_below = std::max(m_max_below, sn.rows - sn.columns);
    }
}

Eigen::VectorXd SupernodalSolve::solve(const Eigen::VectorXd& b) const {
    if (b.size() != m_n) throw std::invalid_argument("SupernodalSolve: wrong right-hand side");
    Eigen::MatrixXf x = b.cast<float>();
    solve_in_place(x);
    return x.col(0).cast<double>();
}

template <class Y> void SupernodalSolve::forward(Y& y) const {
    Eigen::Matrix<float, Eigen::Dynamic, Y::ColsAtCompileTime> below(m_max_below, y.cols());
    for (const Supernode& sn : m_supernodes) {
        const BlockMap block(m_values.data() + sn.values, sn.rows, sn.columns,
                             Eigen::OuterStride<>(sn.rows));
        auto z = y.middleRows(sn.first_column, sn.columns);
        block.topRows(sn.columns).template triangularView<Eigen::Lower>().solveInPlace(z);
        const int m = sn.rows - sn.columns;
        if (m == 0) continue;
        below.topRows(m).noalias() = block.bottomRows(m) * z;
        const int* rows = m_below_rows.data() + sn.pattern;
        for (int i = 0; i < m; ++i)
            y.row(rows[i]) -= below.row(i);
    }
}

template <class Y> void SupernodalSolve::backward(Y& y) const {
    Eigen::Matrix<float, Eigen::Dynamic, Y::ColsAtCompileTime> below(m_max_below, y.cols());
    for (auto it = m_supernodes.rbegin(); it != m_supernodes.rend(); ++it) {
        const Supernode& sn = *it;
        const BlockMap block(m_values.data() + sn.values, sn.rows, sn.columns,
                             Eigen::OuterStride<>(sn.rows));
        auto w = y.middleRows(sn.first_column, sn.columns);
        const int m = sn.rows - sn.columns;
        if (m > 0) {
            const int* rows = m_below_rows.data() + sn.pattern;
            for (int i = 0; i < m; ++i)
                below.row(i) = y.row(rows[i]);
            w.noalias() -= block.bottomRows(m).transpose() * below.topRows(m);
        }
        block.topRows(sn.columns)
            .template triangularView<Eigen::Lower>()
            .transpose()
            .solveInPlace(w);
    }
}

void SupernodalSolve::solve_in_place(Eigen::MatrixXf& b) const {
    if (b.rows() != m_n) throw std::invalid_argument("SupernodalSolve: wrong right-hand side");
    // L L' = P A P': y = P b, then L z = y, L' w = z, x = P' w.
    const auto permute = [&](const Eigen::MatrixXf& from, Eigen::MatrixXf& to, bool inverse) {
        for (Eigen::Index k = 0; k < m_n; ++k) {
            const Eigen::Index a = m_permutation[std::size_t(k)];
            if (inverse)
                to.row(a) = from.row(k);
            else
                to.row(k) = from.row(a);
        }
    };
    Eigen::MatrixXf y(m_n, b.cols());
    permute(b, y, false);
    if (b.cols() == 1) {
        Eigen::VectorXf v = y.col(0);
        forward(v);
        backward(v);
        y.col(0) = v;
    } else {
        forward(y);
        backward(y);
    }
    permute(y, b, true);
}

} // namespace chromasim::mechanics
