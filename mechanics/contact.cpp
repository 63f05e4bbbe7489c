#include "mechanics/contact.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>

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

Eigen::VectorXd
object_gap(const ObjectShape& object,
           const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& X,
           const Eigen::Vector2d& shift) {
    constexpr double kUnreachable_mm = 1e3;
    if (object.kind == ObjectShape::Kind::mesh && !object.mesh)
        throw std::invalid_argument("object_gap: a mesh object needs its height field");
    const Eigen::Index n = X.rows();
    // Object surface height above its lowest point, at (x, y) relative to the object's axis.
    auto height = [&](double x, double y) {
        if (object.kind == ObjectShape::Kind::mesh) {
            const std::optional<double> z = object.mesh->lowest_z(x, y);
            return z ? *z : kUnreachable_mm;
        }
        if (object.kind != ObjectShape::Kind::sphere) return 0.0;
        x -= object.offset_mm.x();
        y -= object.offset_mm.y();
        const double R = object.radius_mm, r2 = x * x + y * y;
        return r2 < R * R ? R - std::sqrt(R * R - r2) : kUnreachable_mm;
    };
    Eigen::VectorXd g(n), g_shifted(n);
    for (Eigen::Index i = 0; i < n; ++i) {
        g(i) = height(X(i, 0), X(i, 1)) - X(i, 2);
        g_shifted(i) = height(X(i, 0) - shift.x(), X(i, 1) - shift.y()) - X(i, 2);
    }
    return g_shifted.array() - g.minCoeff();
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
    // Column of unknown: lambda_k -> k, t_k -> m + 2k + c.
    // G: displacement (3m rows, x y z per contact node) per unit unknown force component.
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
    Eigen::MatrixXd M = Eigen::MatrixXd::Zero(N, N);
    Eigen::VectorXd b = Eigen::VectorXd::Zero(N);
    Eigen::Index row = 0;
    for (Eigen::Index i = 0; i < m; ++i, ++row) { // contact closed
        M.row(row).head(3 * m) = G.row(3 * i + 2);
        M(row, col_d) = 1.0;
        b(row) = gap(A[std::size_t(i)]);
    }
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
    M.row(row).head(m).setOnes(); // sum lambda = P
    b(row++) = load.normal_force_N;
    if (force) { // sum t = Q
        for (int c = 0; c < 2; ++c, ++row) {
            for (Eigen::Index k = 0; k < m; ++k)
                M(row, m + 2 * k + c) = 1.0;
            b(row) = load.tangential_force_N(c);
        }
    }
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
/// contact, else where it is when it touches (set when the active set takes it in).
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
                       const Eigen::VectorXd& r_stiff, double mu, ActiveSets& sets, bool& changed) {
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
        const bool slips = tau.norm() > limit * (sets.slip[jj] ? 1.0 - 1e-10 : 1.0 + 1e-10);
        const Eigen::Vector2d projected = slips ? Eigen::Vector2d(limit * tau.normalized()) : tau;
        law_error = std::max(law_error, (t - projected).norm());
        changed = changed || slips != (sets.slip[jj] != 0);
        sets.slip[jj] = slips;
        if (slips)
            sets.law[jj] = friction_law(t, std::max(lin.lambda(j), 0.0), g, mu, r_stiff(j), true);
    }
    return law_error;
}

/// One step for a given kind (solve_contact_step).
ContactSolution solve_step(const Eigen::MatrixXd& C, const Eigen::VectorXd& gap_mm,
                           const ContactLoad& load, const ContactSolution* previous,
                           const ContactOptions& options, const RowForces* extra_mm,
                           const StepKind& kind) {
    const int n = int(gap_mm.size());
    // Internally the displacement is the part the contact forces cause through C: the extra
    // displacement moves the gaps and anchors.
    Eigen::VectorXd gap = gap_mm;
    if (extra_mm) gap -= extra_mm->col(2);
    const std::size_t nz = std::size_t(n);
    ContactSolution sol;
    sol.load = load;
    sol.forces_N = RowForces::Zero(n, 3);
    sol.displacement_mm = RowForces::Zero(n, 3);
    sol.state.assign(nz, NodeContact::free);
    sol.anchor_mm = RowVectors2::Zero(n, 2);
    const Eigen::Vector2d w_prev =
        previous ? previous->object_displacement_mm : Eigen::Vector2d::Zero();
    const double mu = std::max(0.0, load.mu);
    sol.object_displacement_mm = kind.w_given;
    const double P = load.normal_force_N;
    if (!(P > 0)) { // unloaded: nothing touches
        sol.converged = true;
        sol.gamma = safety_margin(load.mu, 0.0, 0.0);
        return sol;
    }
    RowVectors2 anchor = start_anchors(previous, n, w_prev, extra_mm);
    std::vector<char> was_in_contact(nz, 0);
    if (previous)
        for (int j : previous->active)
            was_in_contact[std::size_t(j)] = 1;
    Eigen::VectorXd r_stiff(n); // each node's own tangential stiffness 1 / C_tt
    for (int j = 0; j < n; ++j)
        r_stiff(j) = 2.0 / (C(3 * j, 3 * j) + C(3 * j + 1, 3 * j + 1));
    ActiveSets sets = start_sets(previous, gap, r_stiff, mu, kind);

    LinearSolution lin{Eigen::VectorXd::Zero(n), RowVectors2::Zero(n, 2), 0.0, kind.w_given};
    sol.status = "max_iterations";
    const double tol_mm = 1e-9 * std::max(1.0, std::min(gap.maxCoeff(), 1e2));
    for (int it = 0; it < options.max_iterations; ++it) {
        ++sol.iterations;
        if (!solve_linear(C, gap, anchor, sets, kind.solved, kind.w_unknown, kind.w_given,
                          options.coupled, lin)) {
            sol.status = "singular";
            break;
        }
        // Semi-smooth Newton: every set is updated from the same iterate. Normal: release the
        // nodes pulling on the object, add the nodes penetrating it (sticking where they were,
        // unless everything slides). Friction: update_friction. Converged when no set changes
        // and t = proj(tau) at every node. Past 30 iterations only the worst node enters or
        // leaves per iteration (anti-cycling).
        const RowForces u = candidate_displacements(C, sets.A, lin, false);
        const RowForces& uz = options.coupled ? u : candidate_displacements(C, sets.A, lin, true);
        const bool cautious = it >= 30;
        // With friction the discrete problem can cycle on a node at the contact edge (a tiny
        // tension in contact, a tiny penetration out of it): past 30 iterations a penetration
        // below 1e-3 of the indentation is accepted (it shows in residual_mm).
        const double cautious_tol_mm = std::max(tol_mm, 1e-3 * std::abs(lin.d));
        std::vector<char> in_A(nz, 0);
        for (int j : sets.A)
            in_A[std::size_t(j)] = 1;
        std::vector<std::pair<double, int>> release, add;
        for (int j : sets.A)
            if (lin.lambda(j) < 0.0 && j != kind.sticking) release.emplace_back(lin.lambda(j), j);
        for (int i = 0; i < n; ++i) {
            const double g = gap(i) - lin.d - uz(i, 2);
            if (!in_A[std::size_t(i)] && g < -(cautious ? cautious_tol_mm : tol_mm))
                add.emplace_back(g, i);
        }
        if (cautious) {
            std::sort(release.begin(), release.end());
            std::sort(add.begin(), add.end());
            if (release.size() > 1) release.resize(1);
            if (add.size() > 1) add.resize(1);
        }
        if (release.size() == sets.A.size()) release.clear(); // keep the contact non-empty
        bool changed = !release.empty() || !add.empty();
        const double law_error =
            kind.all_slip ? 0.0 : update_friction(u, lin, anchor, r_stiff, mu, sets, changed);
        for (const auto& [value, j] : release) {
            in_A[std::size_t(j)] = 0;
            if (!kind.all_slip) sets.slip[std::size_t(j)] = 0;
        }
        for (const auto& [value, i] : add) { // sticks where it touches
            in_A[std::size_t(i)] = 1;
            if (!kind.all_slip) sets.slip[std::size_t(i)] = 0;
            if (!was_in_contact[std::size_t(i)])
                anchor.row(i) = u.row(i).head<2>() - lin.w.transpose();
        }
        if (changed) {
            sets.A.clear();
            for (int i = 0; i < n; ++i)
                if (in_A[std::size_t(i)]) sets.A.push_back(i);
        }
        if (changed) continue;
        if (law_error <= 1e-12 * P) {
            sol.status = "ok";
            break;
        }
    }
    sol.converged = sol.status == "ok";

    // Forces, displacements, states and anchors at the end of the step.
    sol.active = sets.A;
    sol.indentation_mm = lin.d;
    const RowForces u_end = candidate_displacements(C, sets.A, lin, false);
    for (int j : sets.A) {
        sol.forces_N.row(j) << lin.t(j, 0), lin.t(j, 1), -lin.lambda(j);
        // A node on the friction cone that did not move relative to the object sticks; in a
        // full slip every node slides with the object.
        const double slip_mm = (u_end.row(j).head<2>() - lin.w.transpose() - anchor.row(j)).norm();
        const bool slips = kind.full_slip ||
                           (sets.slip[std::size_t(j)] != 0 && (kind.all_slip || slip_mm > 1e-13));
        sol.state[std::size_t(j)] = slips ? NodeContact::slip : NodeContact::stick;
        if (slips) sol.slipping.push_back(j);
    }
    sol.object_displacement_mm = lin.w;
    const bool force = load.tangential == TangentialControl::force;
    sol.sliding =
        kind.full_slip || (!force && !sets.A.empty() && sol.slipping.size() == sets.A.size() &&
                           (sol.object_displacement_mm - w_prev).norm() > 0);
    sol.displacement_mm = u_end;
    const Eigen::Vector2d w = sol.object_displacement_mm;
    for (int j : sets.A)
        sol.anchor_mm.row(j) =
            sol.state[std::size_t(j)] == NodeContact::stick
                ? Eigen::RowVector2d(anchor.row(j))
                : Eigen::RowVector2d(sol.displacement_mm.row(j).head<2>() - w.transpose());

    sol.normal_force_N = -sol.forces_N.col(2).sum();
    sol.tangential_force_N = sol.forces_N.leftCols<2>().colwise().sum().transpose();
    sol.gamma =
        sol.sliding ? 0.0 : safety_margin(mu, sol.normal_force_N, sol.tangential_force_N.norm());

    // Residuals: contact (no penetration, closed on A), stick (anchor kept), force balance,
    // friction law; with Goodman's approximation the contact is judged on the normal forces'
    // displacement, as solved.
    const RowForces uz =
        options.coupled ? sol.displacement_mm : candidate_displacements(C, sets.A, lin, true);
    double res_mm = 0, res_N = std::abs(sol.normal_force_N - P);
    for (int i = 0; i < n; ++i) {
        const double g = gap(i) - sol.indentation_mm - uz(i, 2);
        const NodeContact s = sol.state[std::size_t(i)];
        res_mm = std::max(res_mm, s == NodeContact::free ? std::max(0.0, -g) : std::abs(g));
        const double tn = sol.forces_N.row(i).head<2>().norm(), lim = mu * lin.lambda(i);
        if (s == NodeContact::stick) {
            res_mm = std::max(
                res_mm,
                (sol.displacement_mm.row(i).head<2>() - w.transpose() - anchor.row(i)).norm());
            res_N = std::max(res_N, tn - lim);
        } else if (s == NodeContact::slip) {
            res_N = std::max(res_N, std::abs(tn - lim));
        }
    }
    if (kind.w_unknown)
        res_N = std::max(res_N, (sol.tangential_force_N - kind.solved.tangential_force_N).norm());
    sol.residual_mm = res_mm;
    sol.residual_N = res_N;
    if (extra_mm) { // back to total displacements
        sol.displacement_mm += *extra_mm;
        for (int j : sets.A)
            sol.anchor_mm.row(j) += extra_mm->row(j).head<2>();
    }
    return sol;
}

} // namespace

ContactSolution solve_contact_step(const Eigen::MatrixXd& C, const Eigen::VectorXd& gap_mm,
                                   const ContactLoad& load, const ContactSolution* previous,
                                   const ContactOptions& options, const RowForces* extra_mm,
                                   bool slides) {
    const double mu = std::max(0.0, load.mu);
    // A contact that slid under force control keeps sliding while the pull does not drop.
    const double Q = load.tangential_force_N.norm();
    const bool slid = (slides && load.tangential == TangentialControl::force && Q > 0) ||
                      (previous && previous->sliding && Q > 0 &&
                       previous->load.tangential == TangentialControl::force &&
                       Q >= previous->load.tangential_force_N.norm() * (1 - kGrossSlipTolerance));
    const StepKind kind = step_kind(load, mu, previous, slid);
    ContactSolution sol = solve_step(C, gap_mm, load, previous, options, extra_mm, kind);
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
                         step_kind(load, mu, previous, true));
    return sol;
}

namespace {

ContactLoad interpolate(const ContactLoad& a, const ContactLoad& b, double s) {
    ContactLoad l = b;
    l.normal_force_N = a.normal_force_N + s * (b.normal_force_N - a.normal_force_N);
    l.tangential_force_N = a.tangential_force_N + s * (b.tangential_force_N - a.tangential_force_N);
    l.tangential_displacement_mm =
        a.tangential_displacement_mm +
        s * (b.tangential_displacement_mm - a.tangential_displacement_mm);
    return l;
}

} // namespace

std::vector<ContactLoad> load_steps(const ContactLoad& load, const LoadPath& path,
                                    const ContactSolution* previous) {
    std::vector<ContactLoad> steps;
    if (previous) {
        ContactLoad from = previous->load;
        from.tangential_displacement_mm = previous->object_displacement_mm;
        if (load.tangential == TangentialControl::force &&
            previous->load.tangential != TangentialControl::force)
            from.tangential_force_N = previous->tangential_force_N;
        const int k = std::max(1, path.steps_from_previous);
        for (int i = 1; i <= k; ++i)
            steps.push_back(interpolate(from, load, double(i) / k));
    } else {
        ContactLoad rest = load, grasp = load;
        rest.normal_force_N = 0;
        rest.tangential_force_N.setZero();
        rest.tangential_displacement_mm.setZero();
        grasp.tangential_force_N.setZero();
        grasp.tangential_displacement_mm.setZero();
        if (path.frictionless_indentation) rest.mu = grasp.mu = 0.0;
        const int kn = std::max(1, path.normal_steps);
        for (int i = 1; i <= kn; ++i)
            steps.push_back(interpolate(rest, grasp, double(i) / kn));
        const bool tangential = load.tangential_force_N.norm() > 0 ||
                                load.tangential_displacement_mm.norm() > 0 ||
                                (path.frictionless_indentation && load.mu > 0);
        if (tangential) {
            grasp.mu = load.mu;
            const int kt = std::max(1, path.tangential_steps);
            for (int i = 1; i <= kt; ++i)
                steps.push_back(interpolate(grasp, load, double(i) / kt));
        }
    }
    return steps;
}

ContactSolution solve_contact_path(
    const Eigen::MatrixXd& C, const ObjectShape& object,
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& X,
    const ContactLoad& load, const LoadPath& path, const ContactSolution* previous,
    const ContactOptions& options) {
    const std::vector<ContactLoad> steps = load_steps(load, path, previous);
    // A step that does not converge is split in two halves (from the same start), down to
    // 1/64 of a step: the stick/slip sets then change little per step.
    int iterations = 0;
    auto step_from = [&](auto&& self, const ContactSolution* from, const ContactLoad& start,
                         const ContactLoad& target, int depth) -> ContactSolution {
        const Eigen::Vector2d shift = from ? from->object_displacement_mm : Eigen::Vector2d::Zero();
        ContactSolution next =
            solve_contact_step(C, object_gap(object, X, shift), target, from, options);
        iterations += next.iterations;
        if (next.converged || depth >= 6) return next;
        const ContactLoad middle = interpolate(start, target, 0.5);
        const ContactSolution half = self(self, from, start, middle, depth + 1);
        if (!half.converged) return half;
        return self(self, &half, middle, target, depth + 1);
    };
    ContactSolution current;
    const ContactSolution* last = previous;
    ContactLoad start = previous ? previous->load : load; // the load the first step starts from
    if (previous) {
        start.tangential_displacement_mm = previous->object_displacement_mm;
    } else {
        start.normal_force_N = 0;
        start.tangential_force_N.setZero();
        start.tangential_displacement_mm.setZero();
    }
    for (const ContactLoad& step : steps) {
        ContactLoad from = start;
        from.mu = step.mu;
        current = step_from(step_from, last, from, step, 0);
        last = &current;
        start = step;
        if (!current.converged) break;
    }
    current.iterations = iterations;
    return current;
}

} // namespace chromasim::mechanics
