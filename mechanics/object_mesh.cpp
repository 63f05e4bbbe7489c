#include "mechanics/object_mesh.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>

namespace chromasim::mechanics {

namespace {

constexpr double deg = std::numbers::pi / 180.0;

[[noreturn]] void invalid(const std::string& what) {
    throw std::invalid_argument(what);
}

std::string format_row(const Eigen::Vector3d& v) {
    std::ostringstream s;
    s << '(' << v.x() << ", " << v.y() << ", " << v.z() << ')';
    return s.str();
}

// z-component of the 2-D cross product (b - a) x (p - a): twice the signed area of (a, b, p).
inline double cross2(double ax, double ay, double bx, double by, double px, double py) {
    return (bx - ax) * (py - ay) - (by - ay) * (px - ax);
}

// Triangles between two rings of a sphere cap, `a` below `b`, each given by its first vertex
// and its vertex count (1 for a pole). Walks both rings by azimuth and closes each triangle
// across the shorter of the two candidate diagonals (the usual ring-stitching rule, which keeps
// the triangles near-equilateral where the ring counts differ), oriented outwards.
void join_rings(const std::vector<Eigen::Vector3d>& V, int a0, int na, int b0, int nb,
                std::vector<Eigen::Vector3i>& out) {
    const int steps_a = na > 1 ? na : 0, steps_b = nb > 1 ? nb : 0;
    auto a = [&](int i) { return a0 + i % na; };
    auto b = [&](int j) { return b0 + j % nb; };
    auto dist2 = [&](int p, int q) {
        return (V[std::size_t(p)] - V[std::size_t(q)]).squaredNorm();
    };
    int i = 0, j = 0;
    while (i < steps_a || j < steps_b) {
        const bool advance_a =
            j == steps_b || (i < steps_a && dist2(a(i + 1), b(j)) < dist2(a(i), b(j + 1)));
        if (advance_a) {
            out.emplace_back(a(i), a(i + 1), b(j));
            ++i;
        } else {
            out.emplace_back(a(i), b(j + 1), b(j));
            ++j;
        }
    }
}

} // namespace

Eigen::Matrix3d rotation_from_roll_pitch_yaw_deg(double roll_deg, double pitch_deg,
                                                 double yaw_deg) {
    return (Eigen::AngleAxisd(yaw_deg * deg, Eigen::Vector3d::UnitZ()) *
            Eigen::AngleAxisd(pitch_deg * deg, Eigen::Vector3d::UnitY()) *
            Eigen::AngleAxisd(roll_deg * deg, Eigen::Vector3d::UnitX()))
        .toRotationMatrix();
}

bool is_degenerate_triangle(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                            const Eigen::Vector3d& c) {
    const double twice_area = (b - a).cross(c - a).norm();
    const double longest2 =
        std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
    return !(twice_area > 1e-12 * longest2); // also true for NaN and for coincident vertices
}

void validate_surface(const TriangleSurface& surface) {
    const auto nv = surface.V.rows();
    if (surface.F.rows() == 0)
        invalid("TriangleSurface: no triangles (#V = " + std::to_string(nv) +
                "); an object needs at least one triangle");
    for (Eigen::Index v = 0; v < nv; ++v)
        if (!surface.V.row(v).allFinite())
            invalid("TriangleSurface: vertex " + std::to_string(v) +
                    " has a non-finite coordinate " + format_row(surface.V.row(v)) +
                    "; coordinates must be finite (mm)");
    for (Eigen::Index f = 0; f < surface.F.rows(); ++f) {
        for (int k = 0; k < 3; ++k)
            if (surface.F(f, k) < 0 || surface.F(f, k) >= nv)
                invalid("TriangleSurface: triangle " + std::to_string(f) + " has vertex index " +
                        std::to_string(surface.F(f, k)) + ", outside [0, " + std::to_string(nv) +
                        ")");
        const Eigen::Vector3d a = surface.V.row(surface.F(f, 0)),
                              b = surface.V.row(surface.F(f, 1)),
                              c = surface.V.row(surface.F(f, 2));
        if (is_degenerate_triangle(a, b, c)) {
            std::ostringstream s;
            s << "TriangleSurface: triangle " << f << " (vertices " << surface.F(f, 0) << ", "
              << surface.F(f, 1) << ", " << surface.F(f, 2) << " at " << format_row(a) << ", "
              << format_row(b) << ", " << format_row(c) << ") is degenerate: area "
              << 0.5 * (b - a).cross(c - a).norm()
              << " mm^2; every triangle needs a non-zero area (twice the area > 1e-12 times its "
                 "longest edge squared)";
            invalid(s.str());
        }
    }
}

void validate_pose(const Pose& pose) {
    if (!pose.rotation.allFinite() || !pose.translation_mm.allFinite())
        invalid("Pose: non-finite rotation or translation; all entries must be finite");
    const double off = (pose.rotation.transpose() * pose.rotation - Eigen::Matrix3d::Identity())
                           .cwiseAbs()
                           .maxCoeff();
    if (off > 1e-9 || pose.rotation.determinant() <= 0.0) {
        std::ostringstream s;
        s << "Pose: rotation is not a proper rotation (max |R^T R - I| = " << off
          << ", det R = " << pose.rotation.determinant()
          << "); need R^T R = I within 1e-9 and det R = +1 (no scaling or mirroring)";
        invalid(s.str());
    }
}

TriangleSurface triangle_surface(const std::vector<Eigen::Vector3d>& vertices,
                                 const std::vector<Eigen::Vector3i>& triangles) {
    TriangleSurface out;
    out.V.resize(Eigen::Index(vertices.size()), 3);
    for (std::size_t v = 0; v < vertices.size(); ++v)
        out.V.row(Eigen::Index(v)) = vertices[v];
    out.F.resize(Eigen::Index(triangles.size()), 3);
    for (std::size_t f = 0; f < triangles.size(); ++f)
        out.F.row(Eigen::Index(f)) = triangles[f];
    return out;
}

TriangleSurface posed_surface(const TriangleSurface& surface, const Pose& pose) {
    TriangleSurface out;
    out.V = (surface.V * pose.rotation.transpose()).rowwise() + pose.translation_mm.transpose();
    out.F = surface.F;
    return out;
}

TriangleSurface make_sphere_cap(double radius_mm, double cap_angle_deg, double edge_mm) {
    if (!(radius_mm > 0.0) || !(edge_mm > 0.0) || !(cap_angle_deg > 0.0 && cap_angle_deg <= 180.0))
        invalid("make_sphere_cap: need radius_mm > 0, edge_mm > 0 and cap_angle_deg in (0, 180]");
    const double theta_max = cap_angle_deg * deg;
    const bool closed = cap_angle_deg == 180.0;
    const int rings = std::max(1, int(std::ceil(radius_mm * theta_max / edge_mm)));

    std::vector<Eigen::Vector3d> vertices;
    std::vector<int> first, count; // per ring
    for (int k = 0; k <= rings; ++k) {
        const double theta = theta_max * k / rings;
        const bool pole = k == 0 || (closed && k == rings);
        const int n = pole ? 1
                           : std::max(3, int(std::lround(2.0 * std::numbers::pi * radius_mm *
                                                         std::sin(theta) / edge_mm)));
        first.push_back(int(vertices.size()));
        count.push_back(n);
        for (int j = 0; j < n; ++j) {
            const double phi = 2.0 * std::numbers::pi * j / n;
            const double r = pole ? 0.0 : radius_mm * std::sin(theta);
            vertices.emplace_back(r * std::cos(phi), r * std::sin(phi),
                                  radius_mm - radius_mm * std::cos(theta));
        }
    }
    std::vector<Eigen::Vector3i> triangles;
    for (int k = 0; k < rings; ++k)
        join_rings(vertices, first[k], count[k], first[k + 1], count[k + 1], triangles);
    return triangle_surface(vertices, triangles);
}

TriangleSurface make_plate(double width_mm, double depth_mm, int divisions) {
    if (!(width_mm > 0.0) || !(depth_mm > 0.0) || divisions < 1)
        invalid("make_plate: need width_mm > 0, depth_mm > 0 and divisions >= 1");
    const int n = divisions + 1;
    TriangleSurface out;
    out.V.resize(n * n, 3);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i)
            out.V.row(j * n + i) << -0.5 * width_mm + width_mm * i / divisions,
                -0.5 * depth_mm + depth_mm * j / divisions, 0.0;
    out.F.resize(2 * divisions * divisions, 3);
    int f = 0;
    for (int j = 0; j < divisions; ++j)
        for (int i = 0; i < divisions; ++i) {
            const int v00 = j * n + i, v10 = v00 + 1, v01 = v00 + n, v11 = v01 + 1;
            out.F.row(f++) << v00, v11, v10; // both with normal -z
            out.F.row(f++) << v00, v01, v11;
        }
    return out;
}

MeshHeightField::MeshHeightField(const TriangleSurface& surface, const Pose& pose) {
    validate_surface(surface);
    validate_pose(pose);
    m_surface = posed_surface(surface, pose);
    measure();
    for (Eigen::Index f = 0; f < m_surface.F.rows(); ++f)
        if (const auto t = project(int(f))) m_triangles.push_back(*t);
    if (m_triangles.empty()) {
        std::ostringstream s;
        s << "MeshHeightField: every triangle of the posed surface is vertical (x-y projection "
             "narrower than "
          << m_tolerance
          << " mm), so no vertical line meets it from below; tilt the object out of the "
             "vertical";
        invalid(s.str());
    }
    build_grid();
}

void MeshHeightField::measure() {
    const Points& V = m_surface.V;
    const Triangles& F = m_surface.F;
    m_lowest = V.row(F(0, 0));
    for (Eigen::Index f = 0; f < F.rows(); ++f)
        for (int k = 0; k < 3; ++k) {
            const Eigen::Vector3d p = V.row(F(f, k));
            m_bounds.extend(p);
            if (p.z() < m_lowest.z()) m_lowest = p;
        }
    const double reach = std::max({std::abs(m_bounds.min().x()), std::abs(m_bounds.min().y()),
                                   std::abs(m_bounds.max().x()), std::abs(m_bounds.max().y())});
    m_tolerance = 1e-9 * (std::max(m_bounds.sizes().x(), m_bounds.sizes().y()) + reach);
}

std::optional<MeshHeightField::ProjectedTriangle> MeshHeightField::project(int f) const {
    const Points& V = m_surface.V;
    Eigen::Vector3d a = V.row(m_surface.F(f, 0)), b = V.row(m_surface.F(f, 1)),
                    c = V.row(m_surface.F(f, 2));
    const double area2 = cross2(a.x(), a.y(), b.x(), b.y(), c.x(), c.y());
    const double len_a = (c - b).head<2>().norm(), len_b = (a - c).head<2>().norm(),
                 len_c = (b - a).head<2>().norm();
    // Narrower than the tolerance: vertical.
    if (std::abs(area2) <= m_tolerance * std::max({len_a, len_b, len_c})) return std::nullopt;
    double slack_b = m_tolerance * len_b, slack_c = m_tolerance * len_c;
    if (area2 < 0.0) { // make it counter-clockwise seen from above
        std::swap(b, c);
        std::swap(slack_b, slack_c);
    }
    const double tol = m_tolerance;
    return ProjectedTriangle{a.x(),
                             a.y(),
                             b.x(),
                             b.y(),
                             c.x(),
                             c.y(),
                             a.z(),
                             b.z(),
                             c.z(),
                             tol * len_a,
                             slack_b,
                             slack_c,
                             std::min({a.x(), b.x(), c.x()}) - tol,
                             std::min({a.y(), b.y(), c.y()}) - tol,
                             std::max({a.x(), b.x(), c.x()}) + tol,
                             std::max({a.y(), b.y(), c.y()}) + tol,
                             f};
}

void MeshHeightField::build_grid() {
    // Cell side: the mean box side, enlarged until there are at most 4 #F + 64 cells.
    m_grid_box.setEmpty();
    double mean_side = 0.0;
    for (const auto& t : m_triangles) {
        m_grid_box.extend(Eigen::Vector2d(t.x0, t.y0)).extend(Eigen::Vector2d(t.x1, t.y1));
        mean_side += std::max(t.x1 - t.x0, t.y1 - t.y0);
    }
    mean_side /= double(m_triangles.size());
    const Eigen::Vector2d extent = m_grid_box.sizes();
    const double max_cells = 4.0 * double(m_triangles.size()) + 64.0;
    m_cell = std::max(mean_side, 1e-6 * extent.maxCoeff());
    while (std::ceil(extent.x() / m_cell) * std::ceil(extent.y() / m_cell) > max_cells)
        m_cell *= 1.25;
    m_nx = std::max(1, int(std::ceil(extent.x() / m_cell)));
    m_ny = std::max(1, int(std::ceil(extent.y() / m_cell)));

    // Compressed rows: count, prefix sum, fill. A triangle goes into every cell its grown box
    // overlaps, computed with the same cell_x / cell_y as the queries, so a query inside the
    // box always visits a cell holding the triangle.
    m_cell_start.assign(std::size_t(m_nx) * std::size_t(m_ny) + 1, 0);
    auto for_cells = [&](const ProjectedTriangle& t, auto&& visit) {
        const int i0 = cell_x(t.x0), i1 = cell_x(t.x1), j0 = cell_y(t.y0), j1 = cell_y(t.y1);
        for (int j = j0; j <= j1; ++j)
            for (int i = i0; i <= i1; ++i)
                visit(std::size_t(j) * std::size_t(m_nx) + std::size_t(i));
    };
    for (const auto& t : m_triangles)
        for_cells(t, [&](std::size_t c) { ++m_cell_start[c + 1]; });
    for (std::size_t c = 1; c < m_cell_start.size(); ++c)
        m_cell_start[c] += m_cell_start[c - 1];
    m_cell_triangles.resize(std::size_t(m_cell_start.back()));
    std::vector<int> cursor(m_cell_start.begin(), m_cell_start.end() - 1);
    for (std::size_t k = 0; k < m_triangles.size(); ++k)
        for_cells(m_triangles[k], [&](std::size_t c) { m_cell_triangles[cursor[c]++] = int(k); });
}

int MeshHeightField::cell_x(double x) const {
    const double q = std::floor((x - m_grid_box.min().x()) / m_cell);
    return int(std::clamp(q, 0.0, double(m_nx - 1)));
}

int MeshHeightField::cell_y(double y) const {
    const double q = std::floor((y - m_grid_box.min().y()) / m_cell);
    return int(std::clamp(q, 0.0, double(m_ny - 1)));
}

std::optional<HeightHit> MeshHeightField::hit(double x, double y) const {
    // Written so that NaN coordinates miss.
    if (!(x >= m_grid_box.min().x() && x <= m_grid_box.max().x() && y >= m_grid_box.min().y() &&
          y <= m_grid_box.max().y()))
        return std::nullopt;
    const std::size_t c = std::size_t(cell_y(y)) * std::size_t(m_nx) + std::size_t(cell_x(x));
    double best = std::numeric_limits<double>::infinity();
    int best_triangle = -1;
    for (int k = m_cell_start[c]; k < m_cell_start[c + 1]; ++k) {
        const ProjectedTriangle& t = m_triangles[std::size_t(m_cell_triangles[std::size_t(k)])];
        if (x < t.x0 || x > t.x1 || y < t.y0 || y > t.y1) continue;
        // Edge functions: twice the signed areas opposite each vertex, >= 0 inside.
        double wa = cross2(t.bx, t.by, t.cx, t.cy, x, y);
        double wb = cross2(t.cx, t.cy, t.ax, t.ay, x, y);
        double wc = cross2(t.ax, t.ay, t.bx, t.by, x, y);
        if (wa < -t.slack_a || wb < -t.slack_b || wc < -t.slack_c) continue;
        wa = std::max(wa, 0.0), wb = std::max(wb, 0.0), wc = std::max(wc, 0.0);
        const double z = (wa * t.za + wb * t.zb + wc * t.zc) / (wa + wb + wc);
        if (z < best) {
            best = z;
            best_triangle = t.index;
        }
    }
    if (best_triangle < 0) return std::nullopt;
    return HeightHit{best, best_triangle};
}

Eigen::VectorXd MeshHeightField::lowest_z_all(const Eigen::Ref<const Points>& X) const {
    Eigen::VectorXd z(X.rows());
    for (Eigen::Index i = 0; i < X.rows(); ++i) {
        const auto h = hit(X(i, 0), X(i, 1));
        z(i) = h ? h->z_mm : std::numeric_limits<double>::infinity();
    }
    return z;
}

} // namespace chromasim::mechanics
