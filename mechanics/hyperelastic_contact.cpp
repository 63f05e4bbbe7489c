#include "mechanics/hyperelastic_contact.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace chromasim::mechanics {

HyperelasticContact::HyperelasticContact(const TetMesh& mesh,
                                         const std::vector<Material>& materials,
                                         Volumetric volumetric, const ElasticBody& body)
    : m_body(body), m_energy(mesh, materials, volumetric),
      m_K0(m_energy.hessian(Eigen::VectorXd::Zero(3 * mesh.V.rows()), false)) {}

HyperelasticStep HyperelasticContact::step(const Eigen::VectorXd& gap_mm, const ContactLoad& load,
                                           const ContactSolution* previous,
                                           const Eigen::VectorXd* u_previous,
                                           const HyperelasticOptions& options,
                                           const ContactOptions& contact_options) const {
    const std::vector<int>& candidates = m_body.candidates();
    const Eigen::Index n = Eigen::Index(candidates.size()), dofs = m_K0.rows();
    HyperelasticStep out;
    out.u = u_previous ? *u_previous : Eigen::VectorXd::Zero(dofs);
    out.status = "max_iterations";
    // Anderson acceleration (type II) over the last `depth` iterations: x_{k+1} = g_k - dG gamma
    // with gamma minimizing |f_k - dF gamma|, f = g(x) - x the fixed-point residual.
    // The history restarts when it has not produced a new smallest increment for `patience`
    // iterations: near the fixed point an old history can hold the iteration in a cycle.
    constexpr int depth = 6, patience = 8;
    double best_increment = std::numeric_limits<double>::infinity();
    int since_best = 0;
    std::vector<Eigen::VectorXd> dF, dG;
    Eigen::VectorXd f_prev, g_prev;
    RowForces extra(n, 3);
    // Near mu P an iterate whose stick zone vanished slides (solve_contact_step) and the next
    // may stick again. The second iterate that slides decides: the step slides to its end,
    // rather than cycle between the two maps, and the history restarts on the sliding map.
    bool slides = false;
    int sliding_iterates = 0;
    const auto restart_history = [&] {
        dF.clear();
        dG.clear();
        f_prev.resize(0);
        since_best = 0;
    };
    const Eigen::MatrixXd& field = m_body.candidate_field_responses();
    for (int it = 1; it <= options.max_iterations; ++it) {
        out.iterations = it;
        // Nonlinear remainder of the internal force, moved to the right-hand side.
        const Eigen::VectorXd r = m_energy.gradient(out.u) - m_K0 * out.u;
        const Eigen::VectorXd u_r = -m_body.solve(r);
        for (Eigen::Index j = 0; j < n; ++j)
            extra.row(j) = u_r.segment<3>(3 * candidates[std::size_t(j)]).transpose();
        ContactSolution contact = solve_contact_step(m_body.compliance(), gap_mm, load, previous,
                                                     contact_options, &extra, slides);
        if (!slides && contact.sliding && ++sliding_iterates == 2) {
            slides = true;
            restart_history();
            best_increment = std::numeric_limits<double>::infinity();
        }
        if (!contact.converged) {
            out.status = "contact: " + contact.status;
            out.contact = std::move(contact);
            return out;
        }
        // K^-1 of the contact forces from the candidates' field responses: one dense product
        // in place of a second back-substitution per iteration.
        Eigen::VectorXd u_star = u_r;
        for (int j : contact.active)
            u_star.noalias() +=
                field.middleCols<3>(3 * Eigen::Index(j)) * contact.forces_N.row(j).transpose();
        const Eigen::VectorXd delta = u_star - out.u;
        out.contact = std::move(contact);
        out.increment_mm = delta.cwiseAbs().maxCoeff();
        if (out.increment_mm <= options.tolerance_mm) {
            out.u = u_star;
            out.min_jacobian = m_energy.min_jacobian(out.u);
            out.converged = out.min_jacobian > 0;
            out.status = out.converged ? "ok" : "inverted";
            return out;
        }
        if (out.increment_mm < best_increment) {
            best_increment = out.increment_mm;
            since_best = 0;
        } else if (++since_best >= patience) {
            restart_history();
        }
        if (f_prev.size()) {
            dF.push_back(delta - f_prev);
            dG.push_back(u_star - g_prev);
            if (int(dF.size()) > depth) {
                dF.erase(dF.begin());
                dG.erase(dG.begin());
            }
        }
        f_prev = delta;
        g_prev = u_star;
        Eigen::VectorXd accelerated = u_star;
        if (!dF.empty()) {
            Eigen::MatrixXd F(dofs, Eigen::Index(dF.size()));
            for (std::size_t i = 0; i < dF.size(); ++i)
                F.col(Eigen::Index(i)) = dF[i];
            const Eigen::VectorXd gamma = F.colPivHouseholderQr().solve(delta);
            for (std::size_t i = 0; i < dG.size(); ++i)
                accelerated -= gamma(Eigen::Index(i)) * dG[i];
        }
        // Keep det F > 0 (and away from 0): blend back towards the plain update, then shorten
        // it, until every J stays above the bound.
        double step = 1.0;
        Eigen::VectorXd trial = accelerated;
        while (m_energy.min_jacobian(trial) < options.min_jacobian && step > 1e-6) {
            step *= 0.5;
            trial = out.u + step * (accelerated - out.u);
            if (step < 0.3) {
                dF.clear(); // the history led astray: restart it
                dG.clear();
            }
        }
        if (step <= 1e-6) {
            out.status = "inverted";
            return out;
        }
        out.u = std::move(trial);
    }
    out.min_jacobian = m_energy.min_jacobian(out.u);
    return out;
}

} // namespace chromasim::mechanics
