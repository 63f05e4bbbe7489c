#include "mechanics/contact.hpp"

// A frame's way to its load (contact.hpp): the object's gap and the steps from the previous
// frame or from rest, each solved by solve_contact_step (contact.cpp).

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <vector>

namespace chromasim::mechanics {

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

ContactLoad interpolate(const ContactLoad& a, const ContactLoad& b, double s) {
    ContactLoad l = b;
    l.normal_force_N = a.normal_force_N + s * (b.normal_force_N - a.normal_force_N);
    l.tangential_force_N = a.tangential_force_N + s * (b.tangential_force_N - a.tangential_force_N);
    l.tangential_displacement_mm =
        a.tangential_displacement_mm +
        s * (b.tangential_displacement_mm - a.tangential_displacement_mm);
    return l;
}

ContactLoad ramp_start(const ContactSolution& previous, const ContactLoad& load) {
    ContactLoad from = previous.load;
    from.tangential_displacement_mm = previous.object_displacement_mm;
    if (load.tangential == TangentialControl::force &&
        previous.load.tangential != TangentialControl::force)
        from.tangential_force_N = previous.tangential_force_N;
    return from;
}

std::vector<ContactLoad> load_steps(const ContactLoad& load, const LoadPath& path,
                                    const ContactSolution* previous) {
    std::vector<ContactLoad> steps;
    if (previous) {
        const ContactLoad from = ramp_start(*previous, load);
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
