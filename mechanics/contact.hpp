#pragma once
/// Contact of a rigid object pressed along -z onto the candidate surface nodes of a linear
/// elastic body, solved on the precomputed compliance of those nodes (no FE solve per
/// iteration). Contact forces act along z: exact for a flat, the small-slope approximation
/// (contact radius << object radius, as Hertz assumes) for a sphere.
///
/// Model (see docs/ARCHITECTURE.md "What is deliberately coarse"):
/// - normal: frictionless, unilateral, force controlled: the indentation d is found so that
///   the nodal reactions sum to the requested normal force (active set);
/// - tangential tractions act on that contact set with its normal forces unchanged (Goodman's
///   approximation, which Mindlin's solution makes too: the tangential load does not alter
///   the normal contact; the displacement field still includes every coupling);
/// - |Q| < mu P: Cattaneo-Mindlin partial slip for a load applied monotonically along Q:
///   stick nodes move by one common tangential offset s from the frictionless state, slip
///   nodes carry mu times their normal force along Q, the tractions sum to Q. No history:
///   unloading or a change of direction needs the incremental stick/slip state (not yet);
/// - |Q| >= mu P: full slip, every contact node carries mu times its normal force along the
///   pull, the transmitted tangential force is mu P and Gamma = 0.
#include <Eigen/Core>

#include <string>
#include <vector>

namespace chromasim::mechanics {

/// Rigid object shapes, centred on the z axis, approaching along -z.
struct ObjectShape {
    enum class Kind { flat, sphere };
    Kind kind = Kind::flat;
    double radius_mm = 45.0; ///< sphere radius (unused for a flat)
};

/// Initial gap (mm) of candidate positions X (n x 3) to the object at first touch: >= 0, the
/// highest node at 0. Nodes beyond a sphere's silhouette (r >= R) get an unreachable gap.
Eigen::VectorXd
object_gap(const ObjectShape& object,
           const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& X);

/// Loads of one quasi-static frame.
struct ContactLoad {
    double normal_force_N = 1.0;                  ///< P > 0, pressing the object onto the dome
    Eigen::Vector2d tangential_force_N{0.0, 0.0}; ///< Q, requested pull in the x-y plane
    double mu = 0.8;                              ///< Coulomb friction coefficient
};

/// Solution of the contact problem on the candidate nodes.
struct ContactSolution {
    Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> forces_N; ///< on each candidate
    std::vector<int> active;     ///< candidate indices in contact
    std::vector<int> slipping;   ///< those of `active` that slip (all of them when sliding)
    double indentation_mm = 0.0; ///< rigid approach d of the object
    Eigen::Vector2d tangential_force_N{0.0, 0.0}; ///< transmitted (= Q when sticking)
    double normal_force_N = 0.0; ///< sum of nodal normal forces (= P when converged)
    bool sliding = false;
    double gamma = 1.0; ///< safety margin, clamped to [0, 1]
    int iterations = 0; ///< active-set iterations, normal then stick/slip
    bool converged = false;
    std::string status = "ok"; ///< ok | max_iterations | singular | stick_slip_not_converged
};

/// Safety margin (mu P - |f_t|) / (mu P), clamped at 0 while sliding; 0 when mu P = 0.
double safety_margin(double mu, double normal_force_N, double tangential_force_N);

/// Solves the frame. `C` is the 3n x 3n compliance of the n candidate nodes (mm/N, dofs x, y,
/// z per node), `gap_mm` their initial gap to the object (object_gap).
ContactSolution solve_contact(const Eigen::MatrixXd& C, const Eigen::VectorXd& gap_mm,
                              const ContactLoad& load, int max_iterations = 200);

} // namespace chromasim::mechanics
