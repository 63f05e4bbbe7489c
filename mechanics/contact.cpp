#include "mechanics/contact.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

namespace chromasim::mechanics {

double safety_margin(double mu, double normal_force_N, double tangential_force_N) {
    const double strength = mu * normal_force_N;
    if (!(strength > 0)) return 0.0;
    return std::clamp((strength - tangential_force_N) / strength, 0.0, 1.0);
}

bool gross_slip(double mu, double normal_force_N, double tangential_force_N) {
    if (!(tangential_force_N > 0)) return false;
    return tangential_force_N >= std::max(0.0, mu) * normal_force_N * (1.0 - kGrossSlipTolerance);
}

FrictionLaw friction_law(const Eigen::Vector2d& t, double lambda, const Eigen::Vector2d& g,
                         double mu, double r, bool slip) {
    FrictionLaw law;
    const Eigen::Vector2d tau = t - r * g;
    if (!slip || tau.norm() == 0) { // inside the disc: phi = t - tau = r g
        law.residual = r * g;
        law.d_t.setZero();
        law.d_g = r * Eigen::Matrix2d::Identity();
        law.d_lambda.setZero();
        return law;
    }
    const Eigen::Vector2d n = tau.normalized();
    const Eigen::Matrix2d P = Eigen::Matrix2d::Identity() - n * n.transpose();
    const double kappa = mu * lambda / tau.norm(); // d(tau/|tau|)/d tau = P / |tau|
    law.residual = t - mu * lambda * n;
    law.d_t = Eigen::Matrix2d::Identity() - kappa * P;
    law.d_g = kappa * r * P;
    law.d_lambda = -mu * n;
    return law;
}

namespace {
/// Which nodes touch, and the linearized friction law of those that slip.
struct ActiveSets {
    std::vector<int> A;           ///< in contact, sorted
    std::vector<char> slip;       ///< per candidate
    std::vector<FrictionLaw> law; ///< per slipping candidate: its row d_t t + d_g g + d_l l = 0
};

/// Unknowns of the linear system for fixed sets, and its solution.
struct LinearSolution {
    Eigen::VectorXd lambda; ///< n: normal forces (>= 0 pressing)
    RowVectors2 t;          ///< n x 2: tangential forces on the body
    double d = 0;
    Eigen::Vector2d w{0, 0};
};

/// Displacements (3m rows, x y z per node of A) per unit unknown force component: column k for
/// lambda_k, columns m + 2k + c for t_k. Goodman (`coupled` false): the z rows ignore the
/// tangential forces.
Eigen::MatrixXd contact_response(const Eigen::MatrixXd& C, const std::vector<int>& A,
                                 bool coupled) {
    const Eigen::Index m = Eigen::Index(A.size());
    Eigen::MatrixXd G = Eigen::MatrixXd::Zero(3 * m, 3 * m);
    for (Eigen::Index k = 0; k < m; ++k) {
        const int j = A[std::size_t(k)];
        for (Eigen::Index i = 0; i < m; ++i) {
            const Eigen::Matrix3d Cij = C.block<3, 3>(3 * A[std::size_t(i)], 3 * j);
            G.block<3, 1>(3 * i, k) = -Cij.col(2);
            G.block<3, 2>(3 * i, m + 2 * k) = Cij.leftCols<2>();
            if (!coupled) G.block<1, 2>(3 * i + 2, m + 2 * k).setZero();
        }
    }
    return G;
}

/// The two tangential rows of every node of A, from `row` on: g = 0 for a stick node, the
/// linearized friction law for a slip node (see solve_linear). `force`: w is unknown (columns
/// from `col_w`); otherwise it is `w_given`.
void add_tangential_rows(const Eigen::MatrixXd& G, const RowVectors2& anchor,
                         const ActiveSets& sets, bool force, const Eigen::Vector2d& w_given,
                         Eigen::Index col_w, Eigen::Index row, Eigen::MatrixXd& M,
                         Eigen::VectorXd& b) {
    const std::vector<int>& A = sets.A;
    const Eigen::Index m = Eigen::Index(A.size());
    for (Eigen::Index i = 0; i < m; ++i) {
        const std::size_t j = std::size_t(A[std::size_t(i)]);
        // g = Gt y - w - a as rows: coefficients over y, the w columns, and a constant.
        Eigen::Matrix<double, 2, Eigen::Dynamic> Gg = G.middleRows<2>(3 * i);
        Eigen::Vector2d g_const = -anchor.row(Eigen::Index(j)).transpose();
        if (!force) g_const -= w_given;
        if (!sets.slip[j]) { // stick: g = 0
            M.block(row, 0, 2, 3 * m) = Gg;
            if (force) M.block<2, 2>(row, col_w) = -Eigen::Matrix2d::Identity();
            b.segment<2>(row) = -g_const;
        } else { // the linearized friction law: d_t t + d_g g + d_lambda lambda = 0
            const FrictionLaw& law = sets.law[j];
            M.block(row, 0, 2, 3 * m) = law.d_g * Gg;
            M.block<2, 2>(row, m + 2 * i) += law.d_t;
            M.block<2, 1>(row, i) += law.d_lambda;
            if (force) M.block<2, 2>(row, col_w) = -law.d_g;
            b.segment<2>(row) = -law.d_g * g_const;
        }
        row += 2;
    }
}

/// Solves the system M y = b of solve_linear (dense LU, M is not symmetric) and spreads y over
/// `out`: lambda and t on A, d, and w (`force`) or `w_given`. False when y is not finite or
/// does not solve the system (M singular for these sets).
bool solve_dense(const Eigen::MatrixXd& M, const Eigen::VectorXd& b, const std::vector<int>& A,
                 bool force, const Eigen::Vector2d& w_given, LinearSolution& out) {
    const Eigen::Index m = Eigen::Index(A.size());
    const Eigen::Index col_d = 3 * m, col_w = 3 * m + 1;
    const Eigen::PartialPivLU<Eigen::MatrixXd> lu(M);
    const Eigen::VectorXd y = lu.solve(b);
    if (!y.allFinite() || (M * y - b).norm() > 1e-6 * (b.norm() + 1e-300)) return false;
    out.lambda.setZero();
    out.t.setZero();
    for (Eigen::Index k = 0; k < m; ++k) {
        const int j = A[std::size_t(k)];
        out.lambda(j) = y(k);
        out.t.row(j) = y.segment<2>(m + 2 * k).transpose();
    }
    out.d = y(col_d);
    out.w = force ? Eigen::Vector2d(y.segment<2>(col_w)) : w_given;
    return true;
}

/// One (semi-smooth) Newton system. Unknowns: lambda and t on A, d, and w when `w_unknown`
/// (force control with friction; otherwise w = `w_given`). Forces on the body
/// F_j = (t_j, -lambda_j); u_i = sum_j C_ij F_j; slip g_j = u_t,j - w - a_j. Rows:
/// u_z,i + d = gap_i on A (contact closed); g_j = 0 for a stick node; for a slip node the
/// Alart-Curnier law t = mu lambda tau / |tau|, tau = t - r g, linearized at the last iterate
/// (friction_law: (I - kappa P) t + kappa r P g - mu n lambda = 0, P = I - n n', or a fixed
/// direction when everything slides); sum lambda = P; when w is unknown, sum t = Q. Goodman:
/// the z rows ignore the tangential forces. Dense LU (not symmetric).
bool solve_linear(const Eigen::MatrixXd& C, const Eigen::VectorXd& gap, const RowVectors2& anchor,
                  const ActiveSets& sets, const ContactLoad& load, bool w_unknown,
                  const Eigen::Vector2d& w_given, bool coupled, LinearSolution& out) {
    const std::vector<int>& A = sets.A;
    const Eigen::Index m = Eigen::Index(A.size());
    const bool force = w_unknown;
    const Eigen::Index nw = force ? 2 : 0, N = 3 * m + 1 + nw;
    const Eigen::Index col_d = 3 * m, col_w = 3 * m + 1;
    const Eigen::MatrixXd G = contact_response(C, A, coupled);
    Eigen::MatrixXd M = Eigen::MatrixXd::Zero(N, N);
    Eigen::VectorXd b = Eigen::VectorXd::Zero(N);
    Eigen::Index row = 0;
    for (Eigen::Index i = 0; i < m; ++i, ++row) { // contact closed
        M.row(row).head(3 * m) = G.row(3 * i + 2);
        M(row, col_d) = 1.0;
        b(row) = gap(A[std::size_t(i)]);
    }
    add_tangential_rows(G, anchor, sets, force, w_given, col_w, row, M, b);
    row += 2 * m;
    M.row(row).head(m).setOnes(); // sum lambda = P
    b(row++) = load.normal_force_N;
    if (force) { // sum t = Q
        for (int c = 0; c < 2; ++c, ++row) {
            for (Eigen::Index k = 0; k < m; ++k)
                M(row, m + 2 * k + c) = 1.0;
            b(row) = load.tangential_force_N(c);
        }
    }
    return solve_dense(M, b, A, force, w_given, out);
}

/// Displacements (n x 3) of every candidate under the forces of `sol` on A.
RowForces candidate_displacements(const Eigen::MatrixXd& C, const std::vector<int>& A,
                                  const LinearSolution& sol, bool normal_only) {
    const Eigen::Index n = C.rows() / 3;
    Eigen::VectorXd u = Eigen::VectorXd::Zero(3 * n);
    for (int j : A) {
        const Eigen::Vector3d F(normal_only ? 0.0 : sol.t(j, 0), normal_only ? 0.0 : sol.t(j, 1),
                                -sol.lambda(j));
        u.noalias() += C.middleCols<3>(3 * j) * F;
    }
    return Eigen::Map<const RowForces>(u.data(), n, 3);
}

/// Q / (mu P) from which a contact slipping everywhere is taken to slide.
constexpr double kUnresolvedStickZone = 0.9;

/// What a step solves for, from its load.
struct StepKind {
    bool w_unknown = false;        ///< force control with friction: the object's travel is found
    bool full_slip = false;        ///< force control at or beyond mu P: the contact slides
    bool all_slip = false;         ///< no friction: every contact node slips from the start
    Eigen::Vector2d pull{1, 0};    ///< unit direction of the pull
    ContactLoad solved;            ///< the load the system balances (a full slip's pull is mu P)
    Eigen::Vector2d w_given{0, 0}; ///< the travel when it is not found
    int sticking = -1;             ///< full slip: the candidate that sticks at the onset (-1: none)
};

/// The node that sticks while the contact slides: the previous step's sticking node furthest
/// inside its friction cone (the last of the stick zone to slip, Mindlin's centre), or -1 when
/// the previous step had none (it slid already: the travel is kept).
int last_sticking_node(const ContactSolution* previous, double mu) {
    if (!previous) return -1;
    int best = -1;
    double best_ratio = std::numeric_limits<double>::infinity();
    for (int j : previous->active) {
        if (previous->state[std::size_t(j)] != NodeContact::stick) continue;
        const double lambda = -previous->forces_N(j, 2);
        if (!(lambda > 0)) continue;
        const double ratio = previous->forces_N.row(j).head<2>().norm() / (mu * lambda);
        if (ratio < best_ratio) {
            best_ratio = ratio;
            best = j;
        }
    }
    return best;
}

/// `slides`: solve the step as a full slip even below mu P (its stick zone vanished).
StepKind step_kind(const ContactLoad& load, double mu, const ContactSolution* previous,
                   bool slides) {
    StepKind k;
    const bool force = load.tangential == TangentialControl::force;
    const double Q = load.tangential_force_N.norm(), P = load.normal_force_N;
    k.full_slip = force && (slides || gross_slip(mu, P, Q));
    k.all_slip = mu == 0 || k.full_slip;
    k.w_unknown = force && !k.full_slip && mu > 0;
    if (Q > 0) k.pull = load.tangential_force_N / Q;
    k.solved = load;
    // At and beyond mu P the step is solved at the onset of sliding: every contact node carries
    // mu lambda along the pull (the transmitted force is mu P) but the last node of the stick
    // zone, whose stick condition fixes the travel, Mindlin's finite travel at Q = mu P. A
    // quasi-static model has no slip rate: the travel stays there while the object slides.
    if (k.full_slip && mu > 0) {
        k.solved.tangential_force_N = mu * P * k.pull;
        k.sticking = last_sticking_node(previous, mu);
        k.w_unknown = k.sticking >= 0;
    }
    const Eigen::Vector2d w_prev =
        previous ? previous->object_displacement_mm : Eigen::Vector2d::Zero();
    k.w_given = force ? w_prev : load.tangential_displacement_mm;
    return k;
}

/// Where each node sticks if it is in contact in this step: its old anchor if it was in
/// contact, else where it was at the start of the step. (Anchoring a node where an iterate of
/// the active-set loop first touched would make the solution depend on that loop's path, so
/// not continuous in the data: an outer hyperelastic iteration then cycles.)
RowVectors2 start_anchors(const ContactSolution* previous, int n, const Eigen::Vector2d& w_prev,
                          const RowForces* extra_mm) {
    RowVectors2 anchor = RowVectors2::Zero(n, 2);
    if (previous)
        for (int i = 0; i < n; ++i)
            anchor.row(i) = previous->state[std::size_t(i)] != NodeContact::free
                                ? Eigen::RowVector2d(previous->anchor_mm.row(i))
                                : Eigen::RowVector2d(previous->displacement_mm.row(i).head<2>() -
                                                     w_prev.transpose());
    if (extra_mm) anchor -= extra_mm->leftCols<2>();
    return anchor;
}

/// The first iterate's sets: the previous step's contact and slip sets (warm start), or the
/// node closest to the object.
ActiveSets start_sets(const ContactSolution* previous, const Eigen::VectorXd& gap,
                      const Eigen::VectorXd& r_stiff, double mu, const StepKind& kind) {
    const std::size_t n = std::size_t(gap.size());
    // Fixed-direction row (no friction, or a sliding contact): t = mu lambda along the pull.
    const FrictionLaw along_pull{Eigen::Vector2d::Zero(), Eigen::Matrix2d::Identity(),
                                 Eigen::Matrix2d::Zero(), -mu * kind.pull};
    ActiveSets sets{{}, std::vector<char>(n, 0), std::vector<FrictionLaw>(n, along_pull)};
    if (previous && !previous->active.empty()) {
        sets.A = previous->active;
        for (int j : sets.A) {
            const Eigen::Vector2d t = previous->forces_N.row(j).head<2>().transpose();
            if (kind.all_slip || previous->state[std::size_t(j)] != NodeContact::slip ||
                t.norm() == 0)
                continue;
            sets.slip[std::size_t(j)] = 1; // on the cone: linearized there, slip along t
            sets.law[std::size_t(j)] = friction_law(t, -previous->forces_N(j, 2),
                                                    Eigen::Vector2d::Zero(), mu, r_stiff(j), true);
        }
    } else {
        Eigen::Index first = 0;
        gap.minCoeff(&first);
        sets.A = {int(first)};
    }
    if (kind.all_slip) std::fill(sets.slip.begin(), sets.slip.end(), 1);
    if (kind.sticking >= 0) sets.slip[std::size_t(kind.sticking)] = 0;
    // A travel to find needs a sticking node: after a slide, the most loaded node re-sticks.
    const auto slips = [&](int j) { return sets.slip[std::size_t(j)] != 0; };
    if (kind.w_unknown && std::all_of(sets.A.begin(), sets.A.end(), slips)) {
        const auto load = [&](int j) { return previous ? -previous->forces_N(j, 2) : 0.0; };
        sets.slip[std::size_t(*std::max_element(
            sets.A.begin(), sets.A.end(), [&](int a, int b) { return load(a) < load(b); }))] = 0;
    }
    return sets;
}

/// The friction half of a semi-smooth Newton update, on the Alart-Curnier law: trial traction
/// tau = t - r g (g the slip from the anchor); |tau| <= mu lambda: stick; else slip, linearized
/// at tau. Returns the largest violation of the law and sets `changed` when a node changes
/// state.
double update_friction(const RowForces& u, const LinearSolution& lin, const RowVectors2& anchor,
                       const Eigen::VectorXd& r_stiff, double mu, bool held, ActiveSets& sets,
                       bool& changed) {
    double law_error = 0;
    for (int j : sets.A) {
        const std::size_t jj = std::size_t(j);
        const Eigen::Vector2d t = lin.t.row(j).transpose();
        const Eigen::Vector2d g =
            u.row(j).head<2>().transpose() - lin.w - anchor.row(j).transpose();
        const Eigen::Vector2d tau = t - r_stiff(j) * g;
        const double limit = mu * std::max(lin.lambda(j), 0.0);
        // A node on the cone's surface (|tau| = mu lambda to rounding) keeps its state: both
        // give the same forces, and flipping would never settle.
        const bool slips = held ? sets.slip[jj] != 0
                                : tau.norm() > limit * (sets.slip[jj] ? 1.0 - 1e-10 : 1.0 + 1e-10);
        const Eigen::Vector2d projected = slips ? Eigen::Vector2d(limit * tau.normalized()) : tau;
        law_error = std::max(law_error, (t - projected).norm());
        changed = changed || slips != (sets.slip[jj] != 0);
        sets.slip[jj] = slips;
        if (slips)
            sets.law[jj] = friction_law(t, std::max(lin.lambda(j), 0.0), g, mu, r_stiff(j), true);
    }
    return law_error;
}

/// What the Newton iteration of one step reads; fixed for the step (n candidates).
struct StepProblem {
    const Eigen::MatrixXd& C;
    Eigen::VectorXd gap;     ///< n: gaps less the extra displacement (mm)
    Eigen::VectorXd r_stiff; ///< n: each node's own tangential stiffness 1 / C_tt
    double mu;               ///< >= 0
    const StepKind& kind;
    const ContactOptions& options;
};

/// The iterate of the Newton loop: the sets, the forces they give and the anchors.
struct NewtonIterate {
    ActiveSets sets;
    LinearSolution lin;
    RowVectors2 anchor; ///< n x 2
};

/// Internally the displacement is the part the contact forces cause through C: the extra
/// displacement moves the gaps (and start_anchors moves the anchors).
StepProblem step_problem(const Eigen::MatrixXd& C, const Eigen::VectorXd& gap_mm,
                         const RowForces* extra_mm, double mu, const StepKind& kind,
                         const ContactOptions& options) {
    const int n = int(gap_mm.size());
    Eigen::VectorXd gap = gap_mm;
    if (extra_mm) gap -= extra_mm->col(2);
    Eigen::VectorXd r_stiff(n);
    for (int j = 0; j < n; ++j)
        r_stiff(j) = 2.0 / (C(3 * j, 3 * j) + C(3 * j + 1, 3 * j + 1));
    return {C, std::move(gap), std::move(r_stiff), mu, kind, options};
}

/// Nodes that leave the contact set and nodes that enter it, each with the value that ranks it.
struct NormalChanges {
    std::vector<std::pair<double, int>> release, add;
};

/// The normal half of a semi-smooth Newton update: release the nodes of A pulling on the object
/// (except a full slip's sticking node), add the nodes out of A (`in_A`) penetrating it by more
/// than `tol_mm`. `cautious`: only the worst of each (anti-cycling). The contact stays
/// non-empty.
NormalChanges normal_changes(const StepProblem& p, const NewtonIterate& x, const RowForces& uz,
                             const std::vector<char>& in_A, double tol_mm, bool cautious) {
    const int n = int(p.gap.size());
    NormalChanges ch;
    for (int j : x.sets.A)
        if (x.lin.lambda(j) < 0.0 && j != p.kind.sticking)
            ch.release.emplace_back(x.lin.lambda(j), j);
    for (int i = 0; i < n; ++i) {
        const double g = p.gap(i) - x.lin.d - uz(i, 2);
        if (!in_A[std::size_t(i)] && g < -tol_mm) ch.add.emplace_back(g, i);
    }
    if (cautious) {
        std::sort(ch.release.begin(), ch.release.end());
        std::sort(ch.add.begin(), ch.add.end());
        if (ch.release.size() > 1) ch.release.resize(1);
        if (ch.add.size() > 1) ch.add.resize(1);
    }
    if (ch.release.size() == x.sets.A.size()) ch.release.clear(); // keep the contact non-empty
    return ch;
}

/// Applies `ch` to the membership `in_A` and the slip set: a node entering the contact sticks
/// (at its anchor, start_anchors). With `changed`, A is rebuilt (sorted) from `in_A`.
void apply_normal_changes(const StepProblem& p, const NormalChanges& ch, bool changed,
                          std::vector<char>& in_A, NewtonIterate& x) {
    const int n = int(p.gap.size());
    for (const auto& [value, j] : ch.release) {
        in_A[std::size_t(j)] = 0;
        if (!p.kind.all_slip) x.sets.slip[std::size_t(j)] = 0;
    }
    for (const auto& [value, i] : ch.add) {
        in_A[std::size_t(i)] = 1;
        if (!p.kind.all_slip) x.sets.slip[std::size_t(i)] = 0;
    }
    if (changed) {
        x.sets.A.clear();
        for (int i = 0; i < n; ++i)
            if (in_A[std::size_t(i)]) x.sets.A.push_back(i);
    }
}

/// The semi-smooth Newton loop of a step under the normal force `P`: solves the linear system
/// of the sets in `x`, updates the sets, until none changes and the friction law holds. Counts
/// the iterations in `sol` and sets its status (ok | max_iterations | singular).
void iterate_sets(const StepProblem& p, double P, NewtonIterate& x, ContactSolution& sol,
                  bool held) {
    const int n = int(p.gap.size());
    sol.status = "max_iterations";
    const double tol_mm = 1e-9 * std::max(1.0, std::min(p.gap.maxCoeff(), 1e2));
    for (int it = 0; it < p.options.max_iterations; ++it) {
        ++sol.iterations;
        if (!solve_linear(p.C, p.gap, x.anchor, x.sets, p.kind.solved, p.kind.w_unknown,
                          p.kind.w_given, p.options.coupled, x.lin)) {
            sol.status = "singular";
            break;
        }
        // Semi-smooth Newton: every set is updated from the same iterate. Normal: release the
        // nodes pulling on the object, add the nodes penetrating it (sticking at their anchor,
        // unless everything slides). Friction: update_friction. Converged when no set changes
        // and t = proj(tau) at every node. Past 30 iterations only the worst node enters or
        // leaves per iteration (anti-cycling).
        const RowForces u = candidate_displacements(p.C, x.sets.A, x.lin, false);
        const RowForces& uz =
            p.options.coupled ? u : candidate_displacements(p.C, x.sets.A, x.lin, true);
        const bool cautious = it >= 30;
        // With friction the discrete problem can cycle on a node at the contact edge (a tiny
        // tension in contact, a tiny penetration out of it): past 30 iterations a penetration
        // below 1e-3 of the indentation is accepted (it shows in residual_mm).
        const double cautious_tol_mm = std::max(tol_mm, 1e-3 * std::abs(x.lin.d));
        std::vector<char> in_A(std::size_t(n), 0);
        for (int j : x.sets.A)
            in_A[std::size_t(j)] = 1;
        const NormalChanges ch =
            held ? NormalChanges{}
                 : normal_changes(p, x, uz, in_A, cautious ? cautious_tol_mm : tol_mm, cautious);
        bool changed = !ch.release.empty() || !ch.add.empty();
        const double law_error = p.kind.all_slip ? 0.0
                                                 : update_friction(u, x.lin, x.anchor, p.r_stiff,
                                                                   p.mu, held, x.sets, changed);
        apply_normal_changes(p, ch, changed, in_A, x);
        if (changed) continue;
        if (law_error <= 1e-12 * P) {
            sol.status = "ok";
            break;
        }
    }
}

/// Forces, states, displacements (from the contact forces) and anchors at the end of the step.
/// A node on the friction cone that did not move relative to the object sticks; in a full slip
/// every node slides with the object. `force`: force control; `w_prev`: the object's travel at
/// the previous step.
void record_contact(const StepProblem& p, const NewtonIterate& x, bool force,
                    const Eigen::Vector2d& w_prev, ContactSolution& sol) {
    const std::vector<int>& A = x.sets.A;
    const LinearSolution& lin = x.lin;
    sol.active = A;
    sol.indentation_mm = lin.d;
    const RowForces u_end = candidate_displacements(p.C, A, lin, false);
    for (int j : A) {
        sol.forces_N.row(j) << lin.t(j, 0), lin.t(j, 1), -lin.lambda(j);
        const double slip_mm =
            (u_end.row(j).head<2>() - lin.w.transpose() - x.anchor.row(j)).norm();
        const bool slips = p.kind.full_slip || (x.sets.slip[std::size_t(j)] != 0 &&
                                                (p.kind.all_slip || slip_mm > 1e-13));
        sol.state[std::size_t(j)] = slips ? NodeContact::slip : NodeContact::stick;
        if (slips) sol.slipping.push_back(j);
    }
    sol.object_displacement_mm = lin.w;
    sol.sliding = p.kind.full_slip || (!force && !A.empty() && sol.slipping.size() == A.size() &&
                                       (sol.object_displacement_mm - w_prev).norm() > 0);
    sol.displacement_mm = u_end;
    const Eigen::Vector2d w = sol.object_displacement_mm;
    for (int j : A)
        sol.anchor_mm.row(j) =
            sol.state[std::size_t(j)] == NodeContact::stick
                ? Eigen::RowVector2d(x.anchor.row(j))
                : Eigen::RowVector2d(sol.displacement_mm.row(j).head<2>() - w.transpose());
}

/// Residuals of the recorded solution under the normal force `P`: contact (no penetration,
/// closed on A), stick (anchor kept), force balance, friction law; with Goodman's approximation
/// the contact is judged on the normal forces' displacement, as solved.
void record_residuals(const StepProblem& p, const NewtonIterate& x, double P,
                      ContactSolution& sol) {
    const int n = int(p.gap.size());
    const Eigen::Vector2d w = sol.object_displacement_mm;
    const RowForces uz = p.options.coupled ? sol.displacement_mm
                                           : candidate_displacements(p.C, x.sets.A, x.lin, true);
    double res_mm = 0, res_N = std::abs(sol.normal_force_N - P);
    sol.gap_mm.resize(n);
    for (int i = 0; i < n; ++i) {
        const double g = p.gap(i) - sol.indentation_mm - uz(i, 2);
        sol.gap_mm(i) = g;
        const NodeContact s = sol.state[std::size_t(i)];
        res_mm = std::max(res_mm, s == NodeContact::free ? std::max(0.0, -g) : std::abs(g));
        const double tn = sol.forces_N.row(i).head<2>().norm(), lim = p.mu * x.lin.lambda(i);
        if (s == NodeContact::stick) {
            res_mm = std::max(
                res_mm,
                (sol.displacement_mm.row(i).head<2>() - w.transpose() - x.anchor.row(i)).norm());
            res_N = std::max(res_N, tn - lim);
        } else if (s == NodeContact::slip) {
            res_N = std::max(res_N, std::abs(tn - lim));
        }
    }
    if (p.kind.w_unknown)
        res_N = std::max(res_N, (sol.tangential_force_N - p.kind.solved.tangential_force_N).norm());
    sol.residual_mm = res_mm;
    sol.residual_N = res_N;
}

/// A step's solution before it is solved: nothing touches, the object at the kind's travel.
ContactSolution untouched(const ContactLoad& load, int n, const StepKind& kind) {
    ContactSolution sol;
    sol.load = load;
    sol.forces_N = RowForces::Zero(n, 3);
    sol.displacement_mm = RowForces::Zero(n, 3);
    sol.state.assign(std::size_t(n), NodeContact::free);
    sol.anchor_mm = RowVectors2::Zero(n, 2);
    sol.object_displacement_mm = kind.w_given;
    return sol;
}

/// One step for a given kind (solve_contact_step).
ContactSolution solve_step(const Eigen::MatrixXd& C, const Eigen::VectorXd& gap_mm,
                           const ContactLoad& load, const ContactSolution* previous,
                           const ContactOptions& options, const RowForces* extra_mm,
                           const StepKind& kind, const ContactSolution* held) {
    const int n = int(gap_mm.size());
    ContactSolution sol = untouched(load, n, kind);
    const double P = load.normal_force_N;
    if (!(P > 0)) { // unloaded: nothing touches
        sol.converged = true;
        sol.gamma = safety_margin(load.mu, 0.0, 0.0);
        return sol;
    }
    const Eigen::Vector2d w_prev =
        previous ? previous->object_displacement_mm : Eigen::Vector2d::Zero();
    const double mu = std::max(0.0, load.mu);
    const StepProblem p = step_problem(C, gap_mm, extra_mm, mu, kind, options);
    NewtonIterate x{
        start_sets(held ? held : previous, p.gap, p.r_stiff, mu, kind),
        LinearSolution{Eigen::VectorXd::Zero(n), RowVectors2::Zero(n, 2), 0.0, kind.w_given},
        start_anchors(previous, n, w_prev, extra_mm)};
    iterate_sets(p, P, x, sol, held != nullptr);
    sol.converged = sol.status == "ok";

    record_contact(p, x, load.tangential == TangentialControl::force, w_prev, sol);
    sol.normal_force_N = -sol.forces_N.col(2).sum();
    sol.tangential_force_N = sol.forces_N.leftCols<2>().colwise().sum().transpose();
    sol.gamma =
        sol.sliding ? 0.0 : safety_margin(mu, sol.normal_force_N, sol.tangential_force_N.norm());
    record_residuals(p, x, P, sol);
    if (extra_mm) { // back to total displacements
        sol.displacement_mm += *extra_mm;
        for (int j : x.sets.A)
            sol.anchor_mm.row(j) += extra_mm->row(j).head<2>();
    }
    return sol;
}

} // namespace

ContactSolution solve_contact_step(const Eigen::MatrixXd& C, const Eigen::VectorXd& gap_mm,
                                   const ContactLoad& load, const ContactSolution* previous,
                                   const ContactOptions& options, const RowForces* extra_mm,
                                   bool slides, const ContactSolution* held) {
    const double mu = std::max(0.0, load.mu);
    // A contact that slid under force control keeps sliding while the pull's share of the
    // friction limit, Q / (mu P), does not drop (a firmer grip or a lighter pull re-sticks it).
    const double Q = load.tangential_force_N.norm();
    const auto share = [mu](const ContactLoad& l) {
        return l.tangential_force_N.norm() / std::max(mu * l.normal_force_N, 1e-300);
    };
    const bool slid = (slides && load.tangential == TangentialControl::force && Q > 0) ||
                      (previous && previous->sliding && Q > 0 &&
                       previous->load.tangential == TangentialControl::force &&
                       share(load) >= share(previous->load) * (1 - kGrossSlipTolerance));
    const StepKind kind = step_kind(load, mu, previous, slid);
    ContactSolution sol = solve_step(C, gap_mm, load, previous, options, extra_mm, kind, held);
    if (held) return sol;
    // Under force control a contact pulled near mu P with no sticking node left slides: its
    // stick zone is smaller than the mesh resolves (Mindlin's c = a (1 - Q / (mu P))^(1/3)),
    // and the travel of a contact slipping everywhere that close to mu P is only fixed by the
    // small spread of the slip directions (it grows without bound as Q -> mu P; with no
    // sticking node at all the travel is singular). Far from mu P (a grasp with little
    // friction slips radially everywhere) the slip directions fix the travel well.
    const bool near_limit = Q > 0 && Q >= kUnresolvedStickZone * mu * load.normal_force_N;
    const bool no_stick =
        sol.converged && !sol.active.empty() && sol.slipping.size() == sol.active.size();
    if (kind.w_unknown && !kind.full_slip && near_limit && (no_stick || sol.status == "singular"))
        sol = solve_step(C, gap_mm, load, previous, options, extra_mm,
                         step_kind(load, mu, previous, true), nullptr);
    return sol;
}

} // namespace chromasim::mechanics
