#pragma once
/// Frictional contact of a rigid object pressed along -z onto the candidate surface nodes of a
/// linear elastic body, solved on the precomputed compliance of those nodes (no FE solve per
/// iteration). Normal contact forces act along z: exact for a flat, the small-slope
/// approximation (contact radius << object radius, as Hertz assumes) for a curved object.
///
/// Quasi-static and incremental (docs/ARCHITECTURE.md, "Contact and friction"):
/// - normal: unilateral, force controlled: the indentation d is found so that the nodal
///   reactions sum to the requested normal force (active set);
/// - tangential: Coulomb friction with stick/slip history. Each contact node remembers its
///   anchor, the tangential position relative to the object where it sticks. In a step a
///   sticking node keeps its anchor; a node whose stick traction would exceed mu times its
///   normal force slips, carrying mu times its normal force against its slip, and is
///   re-anchored where it ends; a node entering contact is anchored where it was at the
///   previous step. The tangential load is a force Q on the object (its displacement w is
///   found) or a prescribed object displacement w (the force is found);
/// - normal and tangential problems are coupled (tangential forces move nodes along z, normal
///   forces move them sideways): for fixed contact and slip sets the problem is one linear
///   system in the normal forces, the stick tractions, the indentation and the object's travel;
///   an active-set loop updates the sets (Alart-Curnier trial tractions for stick/slip). On
///   request, Goodman's approximation (the normal problem blind to the tangential forces, as
///   Mindlin's solution assumes);
/// - under force control the contact slides once |Q| >= mu P (gross_slip), or once no node
///   sticks under a pull of at least 0.9 mu P (the stick zone is below the mesh's resolution),
///   and keeps sliding while Q / (mu P) does not drop. A sliding step is solved at its onset:
///   every contact node carries mu times its normal force along the pull but the previous
///   step's node furthest inside its cone, whose stick condition fixes the object's travel
///   (Mindlin's finite travel as Q -> mu P); the transmitted force is mu P and Gamma = 0. A
///   quasi-static model has no slip rate, so a sliding object's travel stays at its onset
///   value and the contact is re-anchored there.
#include "mechanics/object_mesh.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace chromasim::mechanics {

using RowForces = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using RowVectors2 = Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>;

/// Rigid objects approaching along -z: a plane, a sphere centred on the z axis, or a posed
/// triangle mesh (its underside, as seen from below, is what touches).
struct ObjectShape {
    enum class Kind { flat, sphere, mesh };
    Kind kind = Kind::flat;
    double radius_mm = 45.0; ///< sphere radius (sphere only)
    /// Sphere only: (x, y) of its axis in the sensor frame (a posed sphere; rotations leave a
    /// sphere unchanged). A posed mesh carries its pose in `mesh`; a tilted flat is a mesh.
    Eigen::Vector2d offset_mm{0.0, 0.0};
    std::shared_ptr<const MeshHeightField> mesh; ///< posed surface (mesh only)
};

inline ObjectShape sphere_object(double radius_mm) {
    ObjectShape o;
    o.kind = ObjectShape::Kind::sphere;
    o.radius_mm = radius_mm;
    return o;
}

/// Gap (mm) of candidate positions X (n x 3) to the object at first touch: >= 0, the highest
/// node at 0. Nodes beyond a sphere's silhouette (r >= R) get an unreachable gap. With
/// `shift_mm`, the object is moved by that tangential offset, keeping the reference of the
/// unshifted first touch (so the indentation means the same before and after the shift).
Eigen::VectorXd
object_gap(const ObjectShape& object,
           const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& X,
           const Eigen::Vector2d& shift_mm = Eigen::Vector2d::Zero());

/// How the tangential load of a step is given.
enum class TangentialControl {
    force,       ///< ContactLoad::tangential_force_N pulls the object; its travel is found
    displacement ///< ContactLoad::tangential_displacement_mm moves the object; force is found
};

/// Loads at the end of one quasi-static step.
struct ContactLoad {
    double normal_force_N = 1.0;                  ///< P > 0, pressing the object onto the dome
    Eigen::Vector2d tangential_force_N{0.0, 0.0}; ///< Q, requested pull in the x-y plane
    double mu = 0.8;                              ///< Coulomb friction coefficient
    TangentialControl tangential = TangentialControl::force;
    /// Object's tangential displacement w from its first-touch position (displacement control).
    Eigen::Vector2d tangential_displacement_mm{0.0, 0.0};
};

/// State of a candidate node.
enum class NodeContact : std::uint8_t { free = 0, stick = 1, slip = 2 };

struct ContactOptions {
    /// Coupled normal and tangential problems (default); false: Goodman's approximation.
    bool coupled = true;
    int max_iterations = 200; ///< active-set iterations per step
};

/// Solution of one step on the candidate nodes; also the history the next step starts from.
struct ContactSolution {
    RowForces forces_N;             ///< on each candidate (n x 3); z < 0 presses
    RowForces displacement_mm;      ///< of each candidate (n x 3), from all the forces
    std::vector<NodeContact> state; ///< per candidate
    RowVectors2 anchor_mm;          ///< per candidate in contact: u_t - w where it sticks
    std::vector<int> active;        ///< candidate indices in contact
    std::vector<int> slipping;      ///< those of `active` that slip (all of them when sliding)
    /// Per candidate: its gap to the object as the step solved it (mm; 0 where closed).
    Eigen::VectorXd gap_mm;
    double indentation_mm = 0.0;    ///< rigid approach d of the object
    Eigen::Vector2d object_displacement_mm{0.0, 0.0}; ///< object's tangential travel w
    Eigen::Vector2d tangential_force_N{0.0, 0.0};     ///< transmitted (= Q when sticking)
    double normal_force_N = 0.0; ///< sum of nodal normal forces (= P when converged)
    ContactLoad load;            ///< the load this step reached
    bool sliding = false;
    double gamma = 1.0; ///< safety margin, clamped to [0, 1]
    int iterations = 0; ///< active-set iterations (summed over the steps of a path)
    /// Largest violation at the end: of the contact and stick conditions (mm) and of the
    /// force balance and the friction law (N). Reported so a frame can be judged.
    double residual_mm = 0.0, residual_N = 0.0;
    bool converged = false;
    /// ok | max_iterations (the sets kept changing) | singular (no solution for the sets)
    std::string status = "ok";
};

/// Coulomb's law of one contact node in Alart-Curnier form, as the solver linearizes it:
/// residual phi = t - proj(tau), tau = t - r g, proj onto the disc |.| <= mu lambda; t the
/// tangential force on the node (N), lambda its normal force (N), g its slip from its anchor
/// (mm), r > 0 a stiffness (N/mm). `slip` picks the branch: the disc's boundary
/// (proj = mu lambda tau / |tau|) or its inside (proj = tau, phi = r g). phi is positively
/// homogeneous of degree 1 in (t, lambda, g), so phi = d_t t + d_g g + d_lambda lambda: the
/// Newton rows d_t t + d_g g + d_lambda lambda = 0 need no right-hand side.
struct FrictionLaw {
    Eigen::Vector2d residual;
    Eigen::Matrix2d d_t, d_g;
    Eigen::Vector2d d_lambda;
};
FrictionLaw friction_law(const Eigen::Vector2d& t, double lambda, const Eigen::Vector2d& g,
                         double mu, double r, bool slip);

/// Relative tolerance of gross_slip: a pull equal to mu P up to rounding reaches it.
inline constexpr double kGrossSlipTolerance = 1e-9;

/// Whether a pull of `tangential_force_N` (> 0) under force control slides the object:
/// Q >= mu P (1 - kGrossSlipTolerance). The plan's slip phase and the solver use this one test.
bool gross_slip(double mu, double normal_force_N, double tangential_force_N);

/// Safety margin (mu P - |f_t|) / (mu P), clamped at 0 while sliding; 0 when mu P = 0.
double safety_margin(double mu, double normal_force_N, double tangential_force_N);

/// One quasi-static step from `previous` (nullptr: the undeformed, unloaded body) to `load`.
/// `C` is the 3n x 3n compliance of the n candidate nodes (mm/N, dofs x, y, z per node),
/// `gap_mm` their gap to the object in its position at the start of the step (object_gap,
/// shifted by the previous step's object displacement). `extra_mm` (n x 3, optional) is a
/// displacement of the candidates that the contact forces do not cause (the nonlinear
/// correction of a hyperelastic solve): the total displacement is C F + extra. `slides`: under
/// force control, solve the step as sliding (earlier solves of the same step found its stick
/// zone vanished near mu P), so that an outer iteration does not cycle between the two.
/// `held` (optional): keep its contact and slip sets instead of updating them (an outer
/// iteration that cycles on a node at the cone's edge converges on held sets, then checks them).
ContactSolution solve_contact_step(const Eigen::MatrixXd& C, const Eigen::VectorXd& gap_mm,
                                   const ContactLoad& load, const ContactSolution* previous,
                                   const ContactOptions& options = {},
                                   const RowForces* extra_mm = nullptr, bool slides = false,
                                   const ContactSolution* held = nullptr);

/// How a frame's load is reached from rest: the normal force ramps up in `normal_steps` equal
/// steps with the tangential load at zero, then the tangential load ramps up in
/// `tangential_steps` with the normal force held. Friction acts during the indentation (as in
/// a real grasp) unless `frictionless_indentation` (Mindlin's assumption, for validation).
struct LoadPath {
    int normal_steps = 4;
    int tangential_steps = 4;
    bool frictionless_indentation = false;
    /// Steps from a previous frame (frames of a trial are small increments of each other).
    int steps_from_previous = 1;
};

/// The load `s` of the way from `a` to `b` (0: a, 1: b): forces and travel linear in s; mu and
/// the tangential control are b's.
ContactLoad interpolate(const ContactLoad& a, const ContactLoad& b, double s);

/// Where a ramp from `previous` to `load` starts: the previous load with its achieved travel,
/// and its achieved tangential force when `load` switches to force control.
ContactLoad ramp_start(const ContactSolution& previous, const ContactLoad& load);

/// The loads of the steps that take `previous` (nullptr: rest) to `load` along `path`.
std::vector<ContactLoad> load_steps(const ContactLoad& load, const LoadPath& path,
                                    const ContactSolution* previous);

/// Steps from `previous` (nullptr: rest, following `path`) to `load`: from a previous state
/// the loads ramp linearly in `path.steps_from_previous` steps. The object's gap is
/// re-evaluated at each step's start for its tangential travel so far.
ContactSolution solve_contact_path(
    const Eigen::MatrixXd& C, const ObjectShape& object,
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& X,
    const ContactLoad& load, const LoadPath& path, const ContactSolution* previous = nullptr,
    const ContactOptions& options = {});

} // namespace chromasim::mechanics
