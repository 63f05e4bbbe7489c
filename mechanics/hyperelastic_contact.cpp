#include "mechanics/hyperelastic_contact.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>
#include <vector>

namespace chromasim::mechanics {

namespace {

/// Anderson acceleration (type II) over the last `kDepth` iterations: x_{k+1} = g_k - dG gamma
/// with gamma minimizing |f_k - dF gamma|, f = g(x) - x the fixed-point residual.
/// The history restarts when it has not produced a new smallest increment for `kPatience`
/// iterations: near the fixed point an old history can hold the iteration in a cycle.
class AndersonMixing {
public:
    /// Forgets the history and the patience count.
    void restart() {
        m_dF.clear();
        m_dG.clear();
        m_f_prev.resize(0);
        m_since_best = 0;
    }

    /// Forgets the smallest increment seen so far.
    void forget_best() { m_best_increment = std::numeric_limits<double>::infinity(); }

    /// Drops the differences of the history (the last iterate stays).
    void drop_history() {
        m_dF.clear();
        m_dG.clear();
    }

    /// Counts an iteration's largest increment (mm) towards the patience.
    void note_increment(double increment_mm) {
        if (increment_mm < m_best_increment) {
            m_best_increment = increment_mm;
            m_since_best = 0;
        } else if (++m_since_best >= kPatience) {
            restart();
        }
    }

    /// The next iterate after one with image `g` and residual `f` = g - x, added to the history.
    Eigen::VectorXd next(const Eigen::VectorXd& f, const Eigen::VectorXd& g) {
        if (m_f_prev.size()) {
            m_dF.push_back(f - m_f_prev);
            m_dG.push_back(g - m_g_prev);
            if (int(m_dF.size()) > kDepth) {
                m_dF.erase(m_dF.begin());
                m_dG.erase(m_dG.begin());
            }
        }
        m_f_prev = f;
        m_g_prev = g;
        Eigen::VectorXd accelerated = g;
        if (!m_dF.empty()) {
            Eigen::MatrixXd F(g.size(), Eigen::Index(m_dF.size()));
            for (std::size_t i = 0; i < m_dF.size(); ++i)
                F.col(Eigen::Index(i)) = m_dF[i];
            const Eigen::VectorXd gamma = F.colPivHouseholderQr().solve(f);
            for (std::size_t i = 0; i < m_dG.size(); ++i)
                accelerated -= gamma(Eigen::Index(i)) * m_dG[i];
        }
        return accelerated;
    }

private:
    static constexpr int kDepth = 10, kPatience = 8;
    double m_best_increment = std::numeric_limits<double>::infinity();
    int m_since_best = 0;
    std::vector<Eigen::VectorXd> m_dF, m_dG;
    Eigen::VectorXd m_f_prev, m_g_prev;
};

/// The candidates' rows (n x 3) of the full displacement `u` (3 #V).
void gather_candidates(const Eigen::VectorXd& u, const std::vector<int>& candidates,
                       RowForces& out) {
    for (Eigen::Index j = 0; j < Eigen::Index(candidates.size()); ++j)
        out.row(j) = u.segment<3>(3 * candidates[std::size_t(j)]).transpose();
}

/// The contact forces of `contact` on its active candidates (n x 3, zero elsewhere).
RowForces active_forces(const ContactSolution& contact, Eigen::Index n) {
    RowForces F = RowForces::Zero(n, 3);
    for (int j : contact.active)
        F.row(j) = contact.forces_N.row(j);
    return F;
}

/// `u` plus K^-1 of the force change `dF` on the candidates (n x 3), from the candidates'
/// field responses: one dense product in place of a second back-substitution per iteration.
Eigen::VectorXd with_force_change(Eigen::VectorXd u, const Eigen::MatrixXf& field,
                                  const RowForces& dF) {
    Eigen::VectorXf du = Eigen::VectorXf::Zero(u.size());
    for (Eigen::Index j = 0; j < dF.rows(); ++j)
        if (dF.row(j).squaredNorm() > 0)
            du.noalias() += field.middleCols<3>(3 * j) * dF.row(j).transpose().cast<float>();
    return u + du.cast<double>();
}

/// The candidates' compliance times the forces `F` (n x 3), as n x 3 rows.
RowForces compliance_times(const Eigen::MatrixXd& C, const RowForces& F) {
    Eigen::VectorXd out = Eigen::VectorXd::Zero(C.rows());
    for (Eigen::Index j = 0; j < F.rows(); ++j)
        if (F.row(j).squaredNorm() > 0)
            out.noalias() += C.middleCols<3>(3 * j) * F.row(j).transpose();
    return Eigen::Map<const RowForces>(out.data(), F.rows(), 3);
}

/// Keeps det F > 0 (and away from 0) with no pass of its own over the elements: an update is
/// taken whole, and the next gradient's pass (which finds every J) shortens it when some J fell
/// below the bound: blended back towards where it started, halving, until every J is at or above
/// it (the mixing's history dropped once the step is below 0.3; given up below 1e-6). A start
/// from a guess falls back to the previous step's displacement instead.
class LazyRelaxation {
public:
    void guess(Eigen::VectorXd fallback) {
        m_fallback = std::move(fallback);
        m_guess = true;
    }
    void update(Eigen::VectorXd from, Eigen::VectorXd to) {
        m_from = std::move(from);
        m_to = std::move(to);
        m_step = 1.0;
    }
    /// The gradient at `u` (shortened as above; `gradient(u, min_j)` gives both), or none when
    /// the step fell below 1e-6. A start with J below the bound is kept (the step's first).
    template <class Gradient>
    std::optional<Eigen::VectorXd> gradient(const Gradient& gradient, double bound,
                                            AndersonMixing& mixing, Eigen::VectorXd& u) {
        double min_j = 0;
        Eigen::VectorXd g = gradient(u, min_j);
        while (min_j < bound && (m_guess || m_step > 0)) {
            if (m_guess) {
                u = std::move(m_fallback);
                m_guess = false;
            } else {
                m_step *= 0.5;
                if (m_step <= 1e-6) return std::nullopt;
                if (m_step < 0.3) mixing.drop_history(); // the history led astray: restart it
                u = m_from + m_step * (m_to - m_from);
            }
            g = gradient(u, min_j);
        }
        m_guess = false;
        m_step = 0;
        return g;
    }

private:
    Eigen::VectorXd m_fallback, m_from, m_to;
    bool m_guess = false;
    double m_step = 0; ///< of the update in progress; 0: none
};

/// Near its fixed point the map is only piecewise smooth where a node sits on the friction
/// cone's edge: the node flips between stick and slip and the mixing cycles (seed000_train's
/// 8th trial, mu 1.13 at 2.5 N). After `kHoldAfter` iterations within `kNear` tolerances the
/// contact and slip sets of the last iterate are held, so the map is smooth; at its fixed point
/// the sets are released for one free iteration, which converges if they were right, else holds
/// the sets it found (at most `kMaxHolds` times). An iteration still far from its fixed point
/// (a large step) never holds: its sets are still moving.
class SetHolding {
public:
    enum class Action { iterate, converged, hold, release };
    const ContactSolution* held() const { return m_holding ? &m_sets : nullptr; }
    /// What to do after an iteration whose increment is `small` (<= the tolerance) or `near`
    /// (<= kNear tolerances) and whose contact solution is `contact`.
    Action next(bool small, bool near, const ContactSolution& contact) {
        if (m_holding) {
            if (!small) return Action::iterate;
            m_holding = false;
            m_checking = true;
            return Action::release;
        }
        if (small) return Action::converged;
        if (near) ++m_near_iterations;
        const bool stalled = m_checking || m_near_iterations >= kHoldAfter;
        m_checking = false;
        if (!stalled || m_holds == kMaxHolds) return Action::iterate;
        ++m_holds;
        m_holding = true;
        m_sets = contact;
        return Action::hold;
    }

    static constexpr double kNear = 10;

private:
    static constexpr int kHoldAfter = 30, kMaxHolds = 4;
    ContactSolution m_sets;
    bool m_holding = false, m_checking = false;
    int m_near_iterations = 0, m_holds = 0;
};

std::variant<NeoHookean, NeoHookeanQuadratic>
make_energy(const TetMesh& mesh, const std::vector<Material>& materials, Volumetric volumetric) {
    if (mesh.quadratic())
        return std::variant<NeoHookean, NeoHookeanQuadratic>(
            std::in_place_type<NeoHookeanQuadratic>, mesh, materials);
    return std::variant<NeoHookean, NeoHookeanQuadratic>(std::in_place_type<NeoHookean>, mesh,
                                                         materials, volumetric);
}

/// The first step's share that cancels the map's component along the first increment d1: with
/// share w, the second increment d2 is (1 + w (lambda - 1)) d1 along it, so w / (1 - d2.d1 /
/// d1.d1) makes it vanish; kept in [0.1, 1] (a share above 1 would extrapolate).
double next_first_step(double share, const Eigen::VectorXd& d1, const Eigen::VectorXd& d2) {
    const double ratio = d2.dot(d1) / d1.squaredNorm();
    if (!std::isfinite(ratio) || ratio >= 1.0) return 1.0;
    return std::clamp(share / (1.0 - ratio), 0.1, 1.0);
}

} // namespace

HyperelasticContact::HyperelasticContact(const TetMesh& mesh,
                                         const std::vector<Material>& materials,
                                         Volumetric volumetric, const ElasticBody& body)
    : m_body(body), m_energy(make_energy(mesh, materials, volumetric)), m_dofs(3 * mesh.V.rows()) {}

Eigen::VectorXd HyperelasticContact::gradient(const Eigen::VectorXd& u) const {
    return std::visit([&](const auto& e) { return e.gradient(u); }, m_energy);
}

Eigen::VectorXd HyperelasticContact::gradient(const Eigen::VectorXd& u, double& min_j) const {
    if (const auto* quadratic = std::get_if<NeoHookeanQuadratic>(&m_energy))
        return quadratic->gradient(u, min_j);
    min_j = min_jacobian(u);
    return min_j > 0 ? gradient(u) : Eigen::VectorXd();
}

double HyperelasticContact::min_jacobian(const Eigen::VectorXd& u) const {
    return std::visit([&](const auto& e) { return e.min_jacobian(u); }, m_energy);
}

HyperelasticStep HyperelasticContact::step(const Eigen::VectorXd& gap_mm, const ContactLoad& load,
                                           const ContactSolution* previous,
                                           const Eigen::VectorXd* u_previous,
                                           const HyperelasticOptions& options,
                                           const ContactOptions& contact_options,
                                           const Eigen::VectorXd* u_guess) const {
    const std::vector<int>& candidates = m_body.candidates();
    const Eigen::Index n = Eigen::Index(candidates.size()), dofs = m_dofs;
    HyperelasticStep out;
    out.u = u_previous ? *u_previous : Eigen::VectorXd::Zero(dofs);
    LazyRelaxation relaxation;
    if (u_guess) {
        relaxation.guess(std::move(out.u));
        out.u = *u_guess;
    }
    out.status = "max_iterations";
    AndersonMixing mixing;
    RowForces extra(n, 3);
    // Near mu P an iterate whose stick zone vanished slides (solve_contact_step) and the next
    // may stick again. The second iterate that slides decides: the step slides to its end,
    // rather than cycle between the two maps, and the history restarts on the sliding map.
    bool slides = false;
    int sliding_iterates = 0;
    const Eigen::MatrixXf& field = m_body.candidate_field_responses();
    // The contact forces the right-hand side holds (the last iterate's; the previous step's to
    // start): only their change goes through the field responses, so that the fixed point is
    // exact whatever the single-precision factor's round-off.
    RowForces lagged = previous ? active_forces(*previous, n) : RowForces::Zero(n, 3);
    out.next_first_step = options.first_step;
    Eigen::VectorXd first_increment;
    // Contact sets held once the iteration cycles on them (SetHolding).
    SetHolding holding;
    for (int it = 1; it <= options.max_iterations; ++it) {
        out.iterations = it;
        // The nonlinear remainder r = f_int - K0 u moved to the right-hand side with the lagged
        // contact forces: u_r = u - K0^-1 (f_int - B' F_lag) (no product with K0).
        std::optional<Eigen::VectorXd> gradient_here = relaxation.gradient(
            [this](const Eigen::VectorXd& u, double& min_j) { return gradient(u, min_j); },
            options.min_jacobian, mixing, out.u);
        if (!gradient_here) {
            out.status = "inverted";
            return out;
        }
        Eigen::VectorXd f = gradient_here->size() ? std::move(*gradient_here) : gradient(out.u);
        for (Eigen::Index j = 0; j < n; ++j)
            f.segment<3>(3 * candidates[std::size_t(j)]) -= lagged.row(j).transpose();
        const Eigen::VectorXd u_r = out.u - m_body.precondition(f);
        gather_candidates(u_r, candidates, extra);
        extra -= compliance_times(m_body.compliance(), lagged);
        ContactSolution contact =
            solve_contact_step(m_body.compliance(), gap_mm, load, previous, contact_options, &extra,
                               slides, holding.held());
        if (!slides && contact.sliding && ++sliding_iterates == 2) {
            slides = true;
            mixing.restart();
            mixing.forget_best();
        }
        if (!contact.converged) {
            out.status = "contact: " + contact.status;
            out.contact = std::move(contact);
            return out;
        }
        // The fixed-point map's image and its increment.
        RowForces forces = active_forces(contact, n);
        const Eigen::VectorXd u_star = with_force_change(u_r, field, forces - lagged);
        lagged = std::move(forces);
        const Eigen::VectorXd delta = u_star - out.u;
        out.contact = std::move(contact);
        out.increment_mm = delta.cwiseAbs().maxCoeff();
        if (it == 2)
            out.next_first_step = next_first_step(options.first_step, first_increment, delta);
        const SetHolding::Action action =
            holding.next(out.increment_mm <= options.tolerance_mm,
                         out.increment_mm <= SetHolding::kNear * options.tolerance_mm, out.contact);
        if (action == SetHolding::Action::release) { // the sets' fixed point: check them
            out.u = u_star;
            mixing.drop_history();
            continue;
        }
        if (action == SetHolding::Action::converged) {
            out.u = u_star;
            out.min_jacobian = min_jacobian(out.u);
            out.converged = out.min_jacobian > 0;
            out.status = out.converged ? "ok" : "inverted";
            return out;
        }
        // Accelerate; the next gradient keeps every J above the bound.
        mixing.note_increment(out.increment_mm);
        if (action == SetHolding::Action::hold) {
            mixing.restart();
            mixing.forget_best();
        }
        Eigen::VectorXd accelerated = mixing.next(delta, u_star);
        if (it == 1) first_increment = delta;
        if (it == 1 || action == SetHolding::Action::hold) // a new map: damped, as the first
            accelerated = out.u + options.first_step * delta;
        relaxation.update(std::move(out.u), accelerated);
        out.u = std::move(accelerated);
    }
    out.min_jacobian = min_jacobian(out.u);
    return out;
}

} // namespace chromasim::mechanics
