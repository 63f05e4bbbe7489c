#pragma once
/// Large-deformation frames: the body as a compressible neo-Hookean solid (neo_hookean.hpp)
/// under the same frictional contact as the linear model (contact.hpp).
///
/// Method: an initial-stiffness iteration (modified Newton) on the linear factorization that
/// the linear model already holds. The neo-Hookean internal force is split as
/// f_int(u) = K0 u + r(u), with K0 the small-strain stiffness (the neo-Hookean Hessian at
/// rest) and r the nonlinear remainder. Each iteration moves r to the right-hand side:
///   u_r = -K0^-1 r(u_k) = u_k - K0^-1 f_int(u_k)   (one back-substitution)
///   contact forces F on the candidates from the compliance C of K0, with u_r as an extra
///     displacement of the candidates (solve_contact_step: history, friction, force control)
///   u* = u_r + K0^-1 B' F                     (the candidates' field responses, one product)
/// and accelerates the sequence with Anderson mixing over the last 10 iterations, restarted when
/// it stalls; a step that cycles near its fixed point on a node at the friction cone's edge
/// holds its contact sets until it converges on them, then checks them (SetHolding). The update
/// is shortened while any tet's (or nodal) J would fall below `min_jacobian`: the iteration
/// never leaves the set det F > 0. At the fixed point f_int(u) = B' F and the contact
/// conditions hold on u. No tangent factorization per iteration: one back-substitution, one
/// gradient and one contact solve each.
#include "mechanics/contact.hpp"
#include "mechanics/elastic_body.hpp"
#include "mechanics/neo_hookean.hpp"
#include "mechanics/neo_hookean_quadratic.hpp"

#include <variant>

namespace chromasim::mechanics {

struct HyperelasticOptions {
    int max_iterations = 200;
    /// Converged when an iteration changes no displacement by more than this (mm). The error
    /// is larger by about 1 / (1 - rate) of the linear convergence: 0.1 um is 1e-3 px at 224 px.
    double tolerance_mm = 1e-4;
    /// The relaxation keeps every tet's J (and nodal J) at or above this.
    double min_jacobian = 0.05;
    /// The first iteration moves this share of its increment (the later ones are Anderson's).
    /// The plain map overshoots along a frame's increment (its second increment is about -1.6
    /// times the first): a caller passes the previous step's next_first_step.
    double first_step = 1.0;
};

/// One step's result.
struct HyperelasticStep {
    ContactSolution contact; ///< displacements there are total (mm)
    Eigen::VectorXd u;       ///< every node's displacement, 3 #V (mm)
    int iterations = 0;
    double increment_mm = 0; ///< largest displacement change of the last iteration
    double min_jacobian = 1; ///< smallest tet or nodal J of u
    /// The first step's share for the next step (HyperelasticOptions::first_step), from the
    /// map's ratio along this step's first increment: the one that would have cancelled it.
    double next_first_step = 1;
    bool converged = false;
    std::string status = "ok"; ///< ok | max_iterations | contact: <status> | inverted
};

class HyperelasticContact {
public:
    /// `body` holds the linear factorization and the candidates' compliance of the same mesh,
    /// materials and volumetric formulation. Keeps references to `mesh` and `body`. A quadratic
    /// mesh gets NeoHookeanQuadratic (`volumetric` is then not used).
    HyperelasticContact(const TetMesh& mesh, const std::vector<Material>& materials,
                        Volumetric volumetric, const ElasticBody& body);

    /// One quasi-static step to `load` from `previous` (its contact history and its full
    /// displacement `u_previous`, 3 #V; both null: rest). `gap_mm` as for solve_contact_step.
    /// `u_guess` (optional, 3 #V): where the iteration starts instead of `u_previous` (a
    /// predictor), unless some tet's J there is below options.min_jacobian.
    /// Thread safe.
    HyperelasticStep step(const Eigen::VectorXd& gap_mm, const ContactLoad& load,
                          const ContactSolution* previous, const Eigen::VectorXd* u_previous,
                          const HyperelasticOptions& options = {},
                          const ContactOptions& contact_options = {},
                          const Eigen::VectorXd* u_guess = nullptr) const;

private:
    Eigen::VectorXd gradient(const Eigen::VectorXd& u) const;
    /// The gradient and min_jacobian(u) (one pass on quadratic tets); empty where it is <= 0.
    Eigen::VectorXd gradient(const Eigen::VectorXd& u, double& min_j) const;
    double min_jacobian(const Eigen::VectorXd& u) const;

    const ElasticBody& m_body;
    std::variant<NeoHookean, NeoHookeanQuadratic> m_energy;
    Eigen::Index m_dofs; ///< 3 #V
};

} // namespace chromasim::mechanics
