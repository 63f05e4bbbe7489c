#pragma once
/// A single-precision copy of a supernodal Cholesky factor (CHOLMOD's, L L' = P A P') and its
/// one-vector solve: x ~ A^-1 b from half the memory traffic of the double factor, with the
/// dense kernels compiled for the build's instruction set (no BLAS dispatch).
///
/// What it is for: a preconditioner. The solve reads 4 bytes per factor entry where CHOLMOD's
/// reads 8, and a back-substitution on one vector is bound by that traffic; its answer is good
/// to about cond(A) times float's round-off, so a caller that needs A^-1 b exactly uses it only
/// inside an iteration whose fixed point does not depend on it (HyperelasticContact).
#include <Eigen/Core>

#include <cstdint>
#include <vector>

struct cholmod_factor_struct;

namespace chromasim::mechanics {

class SupernodalSolve {
public:
    SupernodalSolve() = default;
    /// Copies CHOLMOD's numeric supernodal LL' factor `L` (int indices, real double entries).
    /// Throws std::invalid_argument for any other kind of factor.
    explicit SupernodalSolve(const cholmod_factor_struct& L);

    bool empty() const { return m_n == 0; }
    Eigen::Index size() const { return m_n; }

    /// x with A x = b up to the factor's single-precision round-off. Thread safe (reads only).
    Eigen::VectorXd solve(const Eigen::VectorXd& b) const;
    /// The same for the columns of `b` at once (dense block kernels), in place. Thread safe.
    void solve_in_place(Eigen::MatrixXf& b) const;

private:
    /// L z = y (forward) and L' w = z (backward) in place, supernode by supernode: the diagonal
    /// block's triangle and the rows below it. Y: a float vector or matrix.
    template <class Y> void forward(Y& y) const;
    template <class Y> void backward(Y& y) const;

    struct Supernode {
        int first_column = 0, columns = 0, rows = 0; ///< rows >= columns: the diagonal block first
        std::int64_t values = 0;                     ///< offset of its rows x columns block
        std::int64_t pattern = 0; ///< offset of its row indices below the diagonal block
    };
    Eigen::Index m_n = 0;
    int m_max_below = 0; ///< the most rows below a diagonal block
    std::vector<Supernode> m_supernodes;
    std::vector<float> m_values;    ///< each supernode's block, column-major
    std::vector<int> m_below_rows;  ///< each supernode's rows below its diagonal block
    std::vector<int> m_permutation; ///< row k of the factor is row m_permutation[k] of A
};

} // namespace chromasim::mechanics
