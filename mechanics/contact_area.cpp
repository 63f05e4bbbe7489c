#include "mechanics/contact_area.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <set>

namespace chromasim::mechanics {

namespace {

/// A convex polygon in 3D with two linear fields at its vertices: the contact level phi and
/// the stick indicator psi.
struct Polygon {
    std::vector<Eigen::Vector3d> p;
    std::vector<double> phi, psi;
};

/// The part of `in` where the field (phi if `on_phi`, else psi) is <= 0 (Sutherland-Hodgman
/// against one linear field).
Polygon clip(const Polygon& in, bool on_phi) {
    Polygon out;
    const std::size_t n = in.p.size();
    const std::vector<double>& f = on_phi ? in.phi : in.psi;
    for (std::size_t a = 0; a < n; ++a) {
        const std::size_t b = (a + 1) % n;
        if (f[a] <= 0) {
            out.p.push_back(in.p[a]);
            out.phi.push_back(in.phi[a]);
            out.psi.push_back(in.psi[a]);
        }
        if ((f[a] <= 0) != (f[b] <= 0)) {
            const double t = f[a] / (f[a] - f[b]);
            out.p.push_back(in.p[a] + t * (in.p[b] - in.p[a]));
            out.phi.push_back(in.phi[a] + t * (in.phi[b] - in.phi[a]));
            out.psi.push_back(in.psi[a] + t * (in.psi[b] - in.psi[a]));
        }
    }
    return out;
}

double area(const Polygon& poly) {
    Eigen::Vector3d twice = Eigen::Vector3d::Zero();
    for (std::size_t k = 1; k + 1 < poly.p.size(); ++k)
        twice += (poly.p[k] - poly.p[0]).cross(poly.p[k + 1] - poly.p[0]);
    return 0.5 * twice.norm();
}

} // namespace

ContactAreaMeter::ContactAreaMeter(const Triangles& F, int n) : m_F(F) {
    std::vector<std::set<int>> adjacent(static_cast<std::size_t>(n));
    for (Eigen::Index f = 0; f < F.rows(); ++f)
        for (int k = 0; k < 3; ++k)
            for (int l = 0; l < 3; ++l)
                if (k != l) adjacent[std::size_t(F(f, k))].insert(F(f, l));
    m_neighbours.reserve(adjacent.size());
    for (const std::set<int>& s : adjacent)
        m_neighbours.emplace_back(s.begin(), s.end());
}

Eigen::Vector3d ContactAreaMeter::slope(const Points& x, const Eigen::VectorXd& phi,
                                        const std::vector<char>& closed, int j) const {
    std::set<int> ring;
    for (int k : m_neighbours[std::size_t(j)]) {
        if (closed[std::size_t(k)]) continue;
        ring.insert(k);
        for (int m : m_neighbours[std::size_t(k)])
            if (!closed[std::size_t(m)]) ring.insert(m);
    }
    ring.erase(j);
    if (ring.size() < 2) return Eigen::Vector3d::Zero();
    // Least squares in the plane of the neighbours (their scatter's two main directions).
    const Eigen::Vector3d xj = x.row(j).transpose();
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (int k : ring) {
        const Eigen::Vector3d d = x.row(k).transpose() - xj;
        scatter += d * d.transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
    const Eigen::Matrix<double, 3, 2> basis = eig.eigenvectors().rightCols<2>();
    Eigen::Matrix2d normal = Eigen::Matrix2d::Zero();
    Eigen::Vector2d rhs = Eigen::Vector2d::Zero();
    for (int k : ring) {
        const Eigen::Vector2d d = basis.transpose() * (x.row(k).transpose() - xj);
        normal += d * d.transpose();
        rhs += d * (phi(k) - phi(j));
    }
    if (!(normal.determinant() > 1e-12 * normal.squaredNorm())) return Eigen::Vector3d::Zero();
    return basis * normal.ldlt().solve(rhs);
}

Eigen::VectorXd ContactAreaMeter::level(const Points& x, const Eigen::VectorXd& gap,
                                        const std::vector<char>& closed) const {
    const Eigen::Index n = gap.size();
    Eigen::VectorXd phi(n);
    for (Eigen::Index i = 0; i < n; ++i)
        phi(i) = closed[std::size_t(i)] ? -1.0 : std::cbrt(std::pow(std::max(0.0, gap(i)), 2));
    std::vector<Eigen::Vector3d> slopes(static_cast<std::size_t>(n));
    std::vector<char> has_slope(std::size_t(n), 0);
    Eigen::VectorXd extended = phi;
    for (Eigen::Index i = 0; i < n; ++i) {
        if (!closed[std::size_t(i)]) continue;
        double sum = 0;
        int count = 0;
        for (int j : m_neighbours[std::size_t(i)]) {
            if (closed[std::size_t(j)]) continue;
            if (!has_slope[std::size_t(j)]) {
                slopes[std::size_t(j)] = slope(x, phi, closed, j);
                has_slope[std::size_t(j)] = 1;
            }
            sum += phi(j) + slopes[std::size_t(j)].dot((x.row(i) - x.row(j)).transpose());
            ++count;
        }
        // On the edge: the extension, never above 0; inside (no free neighbour): -1.
        if (count) extended(i) = std::min(0.0, sum / count);
    }
    return extended;
}

ContactAreas ContactAreaMeter::measure(const Points& x, const ContactSolution& contact) const {
    ContactAreas out;
    const std::size_t n = contact.state.size();
    if (contact.active.empty() || std::size_t(contact.gap_mm.size()) != n) return out;
    std::vector<char> closed(n, 0), sticks(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
        closed[i] = contact.state[i] != NodeContact::free;
        sticks[i] = contact.state[i] == NodeContact::stick;
    }
    // A free node ringed by nodes in contact is inside the patch; it sticks if they all do.
    const auto touching = [&](int k) { return contact.state[std::size_t(k)] != NodeContact::free; };
    const auto sticking = [&](int k) { return contact.state[std::size_t(k)] == NodeContact::stick; };
    for (std::size_t i = 0; i < n; ++i) {
        const std::vector<int>& ring = m_neighbours[i];
        if (closed[i] || ring.empty()) continue;
        closed[i] = std::all_of(ring.begin(), ring.end(), touching);
        sticks[i] = closed[i] && std::all_of(ring.begin(), ring.end(), sticking);
    }
    const Eigen::VectorXd phi = level(x, contact.gap_mm, closed);
    for (Eigen::Index f = 0; f < m_F.rows(); ++f) {
        Polygon tri;
        for (int k = 0; k < 3; ++k) {
            const int v = m_F(f, k);
            tri.p.push_back(x.row(v).transpose());
            tri.phi.push_back(phi(v));
            tri.psi.push_back(sticks[std::size_t(v)] ? -1.0 : 1.0);
        }
        if (*std::min_element(tri.phi.begin(), tri.phi.end()) > 0) continue;
        const Polygon touching = clip(tri, true);
        out.contact_mm2 += area(touching);
        out.stick_mm2 += area(clip(touching, false));
    }
    return out;
}

} // namespace chromasim::mechanics
