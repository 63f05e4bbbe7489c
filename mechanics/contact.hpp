#pragma once
/// Contact of a rigid flat object with the candidate surface nodes of a linear elastic body,
/// solved on the precomputed compliance of those nodes (no full FE solve per iteration).
///
/// Model (foundation level, see docs/ARCHITECTURE.md "What is deliberately coarse"):
/// - normal: frictionless, unilateral, force controlled: the indentation d is found so that
///   the nodal reactions sum to the requested normal force (active set);
/// - tangential tractions act on that contact set with its normal forces unchanged (Goodman's
///   approximation, which Mindlin's solution makes too: the tangential load does not alter
///   the normal contact; the displacement field still includes every coupling);
/// - |Q| < mu P: the contact patch sticks as a whole (tied): every contact node moves by the
///   same tangential offset s from the frictionless state and the tractions sum to Q; no
///   partial slip yet;
/// - |Q| >= mu P: full slip, every contact node carries mu times its normal force along the
///   pull, the transmitted tangential force is mu P and Gamma = 0.
#include <Eigen/Core>

#include <string>
#include <vector>

namespace chromasim::mechanics {

/// Loads of one quasi-static frame.
struct ContactLoad {
    double normal_force_N = 1.0;                  ///< P > 0, pressing the object onto the dome
    Eigen::Vector2d tangential_force_N{0.0, 0.0}; ///< Q, requested pull in the x-y plane
    double mu = 0.8;                              ///< Coulomb friction coefficient
};

/// Solution of the contact problem on the candidate nodes.
struct ContactSolution {
    Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> forces_N; ///< on each candidate
    std::vector<int> active;                      ///< candidate indices in contact
    double indentation_mm = 0.0;                  ///< rigid approach d of the object
    Eigen::Vector2d tangential_force_N{0.0, 0.0}; ///< transmitted (= Q when sticking)
    double normal_force_N = 0.0; ///< sum of nodal normal forces (= P when converged)
    bool sliding = false;
    double gamma = 1.0; ///< safety margin, clamped to [0, 1]
    int iterations = 0; ///< active-set iterations (all phases)
    bool converged = false;
    std::string status = "ok"; ///< ok | max_iterations | singular
};

/// Safety margin (mu P - |f_t|) / (mu P), clamped at 0 while sliding; 0 when mu P = 0.
double safety_margin(double mu, double normal_force_N, double tangential_force_N);

/// Solves the frame. `C` is the 3n x 3n compliance of the n candidate nodes (mm/N, dofs x, y,
/// z per node), `gap_mm` their initial normal gap to the object's lowest point (>= 0).
ContactSolution solve_flat_contact(const Eigen::MatrixXd& C, const Eigen::VectorXd& gap_mm,
                                   const ContactLoad& load, int max_iterations = 200);

} // namespace chromasim::mechanics
