#include "mechanics/dome_geometry.hpp"

#include "mechanics/quadratic_tets.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <numbers>
#include <random>
#include <set>
#include <stdexcept>

namespace chromasim::mechanics {

namespace {

constexpr double kPi = std::numbers::pi;
double deg(double d) {
    return d * kPi / 180.0;
}

/// The angular grid shared by all five hemispheres. Ring i = 1..n-1 at polar angle
/// (i - 1/2) * step, ring n the rim (pi/2). The top is a small flat polygon with an odd vertex
/// count rather than a pole vertex, so that no mesh edge runs along the axis through the apex
/// markers; the azimuths are offset by an arbitrary angle for the same reason.
struct AngularGrid {
    std::vector<std::vector<Eigen::Vector3d>> rings; ///< unit directions per ring
};

/// Rings of constant polar angle; `edge_at(theta)` is the target edge there (mm). Each ring
/// has about 2 pi R sin(theta) / edge points; rings are one local edge apart (marching from
/// half an edge off the apex, then stretched so that the last ring lies in z = 0).
AngularGrid graded_angular_grid(double R, const std::function<double(double)>& edge_at) {
    constexpr double kAzimuthOffset = 0.1234;
    std::vector<double> thetas{0.5 * edge_at(0.0) / R};
    while (thetas.back() < 0.5 * kPi) {
        const double t = thetas.back();
        thetas.push_back(t + edge_at(t) / R);
    }
    // The last ring goes to pi/2: drop an overshooting ring that would sit less than half a
    // gap beyond it, then stretch the others so that the last one lands in z = 0.
    if (thetas.size() > 2 &&
        (thetas.back() - 0.5 * kPi) > 0.5 * (thetas.back() - thetas[thetas.size() - 2]))
        thetas.pop_back();
    const double stretch = (0.5 * kPi) / thetas.back();
    AngularGrid grid;
    for (std::size_t i = 0; i < thetas.size(); ++i) {
        const bool last = i + 1 == thetas.size();
        const double theta = last ? 0.5 * kPi : thetas[i] * stretch;
        int m = std::max(5, int(std::lround(2 * kPi * std::sin(theta) * R / edge_at(theta))));
        if (i == 0) m |= 1; // odd: no chord of the top polygon passes through the axis
        std::vector<Eigen::Vector3d> ring;
        const double phase = ((i + 1) % 2) * 0.5;
        for (int j = 0; j < m; ++j) {
            const double phi = 2 * kPi * (j + phase) / m + kAzimuthOffset;
            ring.emplace_back(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                              last ? 0.0 : std::cos(theta));
        }
        grid.rings.push_back(std::move(ring));
    }
    return grid;
}

AngularGrid angular_grid(double outer_radius_mm, double edge_mm) {
    constexpr double kAzimuthOffset = 0.1234;
    const int n = std::max(3, int(std::ceil(0.5 * kPi * outer_radius_mm / edge_mm)));
    const double step = 0.5 * kPi / (n - 0.5);
    AngularGrid grid;
    for (int i = 1; i <= n; ++i) {
        const double theta = i == n ? 0.5 * kPi : step * (i - 0.5);
        int m =
            std::max(5, int(std::lround(2 * kPi * std::sin(theta) * outer_radius_mm / edge_mm)));
        if (i == 1) m |= 1; // odd: no chord of the top polygon passes through the axis
        std::vector<Eigen::Vector3d> ring;
        const double phase = (i % 2) * 0.5; // stagger alternate rings for better triangles
        for (int j = 0; j < m; ++j) {
            const double phi = 2 * kPi * (j + phase) / m + kAzimuthOffset;
            ring.emplace_back(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                              i == n ? 0.0 : std::cos(theta));
        }
        grid.rings.push_back(std::move(ring));
    }
    return grid;
}

double azimuth(const Eigen::Vector3d& d) {
    double a = std::atan2(d.y(), d.x());
    return a < 0 ? a + 2 * kPi : a;
}

/// Triangulates the band between two rings (indices into a vertex list, each counter-
/// clockwise about +z) by merging them in azimuth order: the classic "zipper" of two closed
/// polylines. Azimuths are unwrapped from ring a's first vertex, and ring b is walked from its
/// first vertex at or after it, so no band crosses the seam where azimuths wrap at 2 pi.
void zip_rings(const std::vector<int>& a, const std::vector<int>& b_ring,
               const std::vector<Eigen::Vector3d>& dirs, std::vector<std::array<int, 3>>& out) {
    const double ref = azimuth(dirs[std::size_t(a[0])]);
    auto rel = [&](int v) { // azimuth from a[0], in [0, 2 pi)
        const double t = std::fmod(azimuth(dirs[std::size_t(v)]) - ref + 4 * kPi, 2 * kPi);
        return t >= 2 * kPi ? 0.0 : t;
    };
    std::size_t start = 0;
    for (std::size_t k = 1; k < b_ring.size(); ++k)
        if (rel(b_ring[k]) < rel(b_ring[start])) start = k;
    std::vector<int> b(b_ring.begin() + std::ptrdiff_t(start), b_ring.end());
    b.insert(b.end(), b_ring.begin(), b_ring.begin() + std::ptrdiff_t(start));
    std::size_t i = 0, j = 0;
    const std::size_t na = a.size(), nb = b.size();
    auto angle_a = [&](std::size_t k) { return k >= na ? 2 * kPi : rel(a[k]); };
    auto angle_b = [&](std::size_t k) { return k >= nb ? 2 * kPi + rel(b[0]) : rel(b[k]); };
    while (i < na || j < nb) {
        const double ta = angle_a(i + 1);
        const double tb = angle_b(j + 1);
        if (j >= nb || (i < na && ta < tb)) {
            out.push_back({a[i % na], b[j % nb], a[(i + 1) % na]});
            ++i;
        } else {
            out.push_back({a[i % na], b[j % nb], b[(j + 1) % nb]});
            ++j;
        }
    }
}

/// The disk z = 0, r <= r_inner closing the soft fill: concentric rings about `edge_mm` apart,
/// the outermost being the inner sphere's rim ring (points `rim` of plc), zipped; the
/// innermost ring is a small polygon. New points are appended to plc.points.
void add_fill_base(Plc& plc, const std::vector<int>& rim, double r_inner, double edge_mm) {
    constexpr double kAzimuthOffset = 0.1234;
    std::vector<Eigen::Vector3d> pos;    // local vertices
    std::vector<int> plc_id;             // local vertex -> plc point
    std::vector<std::vector<int>> rings; // local ids per ring, outermost first
    rings.emplace_back();
    for (int p : rim) {
        rings.back().push_back(int(pos.size()));
        pos.push_back(plc.points.row(p).transpose());
        plc_id.push_back(p);
    }
    const int n = std::max(2, int(std::lround(r_inner / edge_mm)));
    int next_id = int(plc.points.rows());
    for (int k = 1; k < n; ++k) {
        const double r = r_inner * (n - k) / n;
        int m = std::max(5, int(std::lround(2 * kPi * r / edge_mm)));
        if (k + 1 == n) m |= 1; // odd: no chord of the centre polygon passes through the axis
        const double phase = (k % 2) * 0.5;
        rings.emplace_back();
        for (int j = 0; j < m; ++j) {
            const double phi = 2 * kPi * (j + phase) / m + kAzimuthOffset;
            rings.back().push_back(int(pos.size()));
            pos.emplace_back(r * std::cos(phi), r * std::sin(phi), 0.0);
            plc_id.push_back(next_id++);
        }
    }
    plc.points.conservativeResize(next_id, 3);
    for (std::size_t v = rim.size(); v < pos.size(); ++v)
        plc.points.row(plc_id[v]) = pos[v].transpose();
    std::vector<std::array<int, 3>> tris;
    for (std::size_t i = 0; i + 1 < rings.size(); ++i)
        zip_rings(rings[i], rings[i + 1], pos, tris);
    for (const auto& t : tris) {
        plc.facets.push_back({plc_id[t[0]], plc_id[t[1]], plc_id[t[2]]});
        plc.facet_markers.push_back(20);
    }
    std::vector<int> centre;
    for (int v : rings.back())
        centre.push_back(plc_id[v]);
    plc.facets.push_back(centre);
    plc.facet_markers.push_back(20);
}

Plc dome_plc_from_grid(const DomeParams& dome, const AngularGrid& grid, bool fill,
                       double base_edge_mm) {
    std::vector<Eigen::Vector3d> dirs;
    std::vector<std::vector<int>> ring_ids; // direction indices per ring
    for (const auto& ring : grid.rings) {
        ring_ids.emplace_back();
        for (const auto& d : ring) {
            ring_ids.back().push_back(int(dirs.size()));
            dirs.push_back(d);
        }
    }
    std::vector<std::array<int, 3>> cap; // triangles in direction indices
    for (std::size_t i = 0; i + 1 < ring_ids.size(); ++i)
        zip_rings(ring_ids[i], ring_ids[i + 1], dirs, cap);

    const int nd = int(dirs.size());
    const int ns = kLayerCount + 1;
    Plc plc;
    plc.points.resize(std::size_t(nd) * ns, 3);
    for (int s = 0; s < ns; ++s)
        for (int d = 0; d < nd; ++d)
            plc.points.row(s * nd + d) = dome.radii_mm[s] * dirs[d];
    for (int s = 0; s < ns; ++s) {
        std::vector<int> top; // the flat top polygon (first ring) closing the cap
        for (int d : ring_ids.front())
            top.push_back(s * nd + d);
        plc.facets.push_back(top);
        plc.facet_markers.push_back(s + 1);
        for (const auto& tri : cap) {
            plc.facets.push_back({s * nd + tri[0], s * nd + tri[1], s * nd + tri[2]});
            plc.facet_markers.push_back(s + 1);
        }
    }
    // Rim annuli in z = 0: one planar quad per rim segment between neighbouring spheres.
    const auto& rim = ring_ids.back();
    for (int s = 0; s + 1 < ns; ++s)
        for (std::size_t j = 0; j < rim.size(); ++j) {
            const int a = rim[j], b = rim[(j + 1) % rim.size()];
            plc.facets.push_back({s * nd + a, s * nd + b, (s + 1) * nd + b, (s + 1) * nd + a});
            plc.facet_markers.push_back(10 + s);
        }
    // Region seeds at mid-thickness, 45 degrees off the axis, between two grid directions.
    const Eigen::Vector3d seed_dir = Eigen::Vector3d(0.3, 0.2, 1.0).normalized();
    for (int l = 0; l < kLayerCount; ++l)
        plc.regions.push_back({0.5 * (dome.radii_mm[l] + dome.radii_mm[l + 1]) * seed_dir, l + 1});
    if (fill) { // on sphere s = 0 the point ids are the direction ids
        add_fill_base(plc, rim, dome.radii_mm[0], base_edge_mm);
        plc.regions.push_back({0.5 * dome.radii_mm[0] * seed_dir, kFill});
    }
    return plc;
}

} // namespace

MeshLevel mesh_level(const std::string& name) {
    // Edge lengths are on the outer sphere; the volume bound keeps interior tets of the 1.2 mm
    // clear layer no larger than the surface triangles imply.
    if (name == "very_coarse") return {name, 2.0, 1.4};
    if (name == "coarse") return {name, 1.2, 0.30};
    if (name == "medium") return {name, 0.8, 0.09};
    if (name == "fine") return {name, 0.5, 0.025};
    if (name == "refined") return {name, 1.2, 0.30, 0.5, 40};
    if (name == "reference") return {name, 0.8, 0.09, 0.3, 40};
    throw std::invalid_argument(
        "unknown mesh level '" + name +
        "'; allowed: very_coarse, coarse, medium, fine, refined, reference");
}

namespace {

/// A tangent frame (t1, t2) of the unit sphere at n, (t1, t2, n) right-handed.
std::pair<Eigen::Vector3d, Eigen::Vector3d> tangent_frame(const Eigen::Vector3d& n) {
    const Eigen::Vector3d t1 =
        (std::abs(n.z()) > 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitZ())
            .cross(n)
            .normalized();
    return {t1, n.cross(t1)};
}

/// The markers' mid-thickness radius in layer `layer` (0 inner, 1 outer).
double marker_mid_radius(const DomeParams& dome, int layer) {
    return 0.5 * (dome.radii_mm[std::size_t(2 * layer)] + dome.radii_mm[std::size_t(2 * layer + 1)]);
}

/// Moves each direction by an offset uniform in a disc of `jitter_mm` on the sphere of radius
/// `r_mm` (std::mt19937_64 seeded per layer and marker, turned into doubles by hand).
void jitter(std::vector<Eigen::Vector3d>& dirs, double jitter_mm, double r_mm,
            std::uint64_t seed) {
    for (std::size_t m = 0; m < dirs.size(); ++m) {
        std::mt19937_64 engine(seed * 0x9E3779B97F4A7C15ull + m);
        const double u = double(engine() >> 11) * 0x1.0p-53, v = double(engine() >> 11) * 0x1.0p-53;
        const double rho = jitter_mm * std::sqrt(u), phi = 2 * kPi * v;
        const auto [t1, t2] = tangent_frame(dirs[m]);
        dirs[m] = (dirs[m] + rho / r_mm * (std::cos(phi) * t1 + std::sin(phi) * t2)).normalized();
    }
}

} // namespace

std::vector<Eigen::Vector3d> marker_directions(const DomeParams& dome, int layer) {
    std::vector<Eigen::Vector3d> dirs{Eigen::Vector3d::UnitZ()};
    const double step = deg(dome.ring_step_deg);
    for (int k = 1; k <= dome.ring_count; ++k) {
        const int m = int(std::lround(6.0 * std::sin(k * step) / std::sin(step)));
        for (int j = 0; j < m; ++j) {
            const double phi = 2 * kPi * j / m;
            dirs.emplace_back(std::sin(k * step) * std::cos(phi),
                              std::sin(k * step) * std::sin(phi), std::cos(k * step));
        }
    }
    if (dome.marker_jitter_mm > 0)
        jitter(dirs, dome.marker_jitter_mm, marker_mid_radius(dome, layer),
               dome.marker_jitter_seed * 2 + std::uint64_t(layer));
    return dirs;
}

std::vector<double> marker_face_margins_mm(const DomeParams& dome, const TetMesh& mesh) {
    const std::array<std::vector<Eigen::Vector3d>, 2> layer_dirs{marker_directions(dome, 0),
                                                                 marker_directions(dome, 1)};
    std::vector<double> margin(2 * layer_dirs[0].size(), 0.0);
    // Interfaces bounding each marker layer: inner surface and 1|2; 3|2 and 3|4 (the coating).
    const std::array<std::array<int, 4>, 4> interfaces{{{kInnerMarkerLayer, -1, 0, 0},
                                                        {kInnerMarkerLayer, kClearLayer, 1, 0},
                                                        {kOuterMarkerLayer, kClearLayer, 2, 1},
                                                        {kOuterMarkerLayer, kCoating, 3, 1}}};
    for (const auto& [a, b, radius, layer] : interfaces) {
        const double r = dome.radii_mm[std::size_t(radius)];
        const double cos_near = std::cos((dome.marker_radius_mm + 1.0) / r);
        const Triangles F = split_faces(mesh, interface_faces(mesh, a, b));
        for (int f = 0; f < F.rows(); ++f) {
            const Eigen::Vector3d v0 = mesh.V.row(F(f, 0)), v1 = mesh.V.row(F(f, 1)),
                                  v2 = mesh.V.row(F(f, 2));
            const Eigen::Vector3d n = (v1 - v0).cross(v2 - v0).normalized();
            const Eigen::Vector3d centre = ((v0 + v1 + v2) / 3).normalized();
            // Facets of the sphere only (not of the rim plane, where a triangle may also have
            // its three vertices on the rim circle).
            if (std::abs(n.dot(centre)) < 0.9) continue;
            const double sag = r - std::abs(n.dot(v0));
            const auto& dirs = layer_dirs[std::size_t(layer)];
            for (std::size_t m = 0; m < dirs.size(); ++m)
                if (dirs[m].dot(centre) >= cos_near) {
                    double& mm = margin[std::size_t(layer) * dirs.size() + m];
                    mm = std::max(mm, sag);
                }
        }
    }
    for (double& m : margin)
        m += 0.005;
    return margin;
}

MarkerDiscs marker_discs(const DomeParams& dome, const std::vector<double>& margin_mm) {
    const std::array<std::vector<Eigen::Vector3d>, 2> layer_dirs{marker_directions(dome, 0),
                                                                 marker_directions(dome, 1)};
    const auto& dirs = layer_dirs[0];
    const int rim = dome.marker_rim_points;
    MarkerDiscs discs;
    discs.markers_per_layer = int(dirs.size());
    discs.rim_points = rim;
    discs.points_per_marker = 3 * (1 + rim);
    discs.points.resize(2 * dirs.size() * std::size_t(discs.points_per_marker), 3);
    // Markers sit at mid-thickness of the inner (layer 1) and outer (layer 3) marker layers.
    const double mid[2] = {marker_mid_radius(dome, 0), marker_mid_radius(dome, 1)};
    if (!margin_mm.empty() && margin_mm.size() != 2 * dirs.size())
        throw std::invalid_argument("marker_discs: one margin per marker needed");
    int row = 0;
    for (int l = 0; l < 2; ++l)
        for (const Eigen::Vector3d& n : layer_dirs[std::size_t(l)]) {
            const std::size_t m = discs.thickness_mm.size();
            const double layer = dome.radii_mm[2 * l + 1] - dome.radii_mm[2 * l];
            const double margin = margin_mm.empty() ? 0.005 : margin_mm[m];
            discs.thickness_mm.push_back(std::min(dome.marker_thickness_mm, layer - 2 * margin));
            const auto [t1, t2] = tangent_frame(n); // any frame: the disc is round
            for (const double offset : {0.0, -0.5, 0.5}) {
                const double r = mid[l] + offset * discs.thickness_mm[m];
                discs.points.row(row++) = r * n;
                // The rim on the sphere of radius r: the tangent-plane circle of the disc's
                // radius, projected radially (a flat rim would rise 0.01 mm out of its layer).
                for (int k = 0; k < rim; ++k) {
                    const double a = 2 * kPi * k / rim;
                    const Eigen::Vector3d flat =
                        mid[l] * n + dome.marker_radius_mm * (std::cos(a) * t1 + std::sin(a) * t2);
                    discs.points.row(row++) = r * flat.normalized();
                }
            }
        }
    return discs;
}

Plc dome_plc(const DomeParams& dome, const MeshLevel& level, bool fill) {
    const double R = dome.radii_mm.back();
    if (!(level.contact_edge_mm > 0) || level.contact_edge_mm >= level.edge_mm)
        return dome_plc(dome, level.edge_mm, fill);
    const double theta_c = level.contact_angle_deg * kPi / 180;
    const auto edge_at = [&](double theta) {
        const double beyond = std::max(0.0, theta - theta_c) * R; // arc length past the cap
        return std::min(level.edge_mm, level.contact_edge_mm + 0.25 * beyond);
    };
    Plc plc = dome_plc_from_grid(dome, graded_angular_grid(R, edge_at), fill, level.edge_mm);
    plc.point_size_mm.resize(std::size_t(plc.points.rows()));
    for (Eigen::Index i = 0; i < plc.points.rows(); ++i) {
        const Eigen::Vector3d p = plc.points.row(i);
        // Points of the fill's base disk (inside the inner rim) take the far edge length.
        const bool base = p.z() == 0.0 && p.norm() < dome.radii_mm[0] * (1 - 1e-9);
        plc.point_size_mm[std::size_t(i)] =
            base ? level.edge_mm : edge_at(std::acos(std::clamp(p.z() / p.norm(), -1.0, 1.0)));
    }
    return plc;
}

Plc dome_plc(const DomeParams& dome, double edge_mm, bool fill) {
    return dome_plc_from_grid(dome, angular_grid(dome.radii_mm.back(), edge_mm), fill, edge_mm);
}

double dome_layer_volume(const DomeParams& dome, int layer) {
    auto hemi = [](double r) { return 2.0 / 3.0 * kPi * r * r * r; };
    if (layer < 0) return hemi(dome.radii_mm.back()) - hemi(dome.radii_mm.front());
    if (layer == kFill) return hemi(dome.radii_mm.front());
    return hemi(dome.radii_mm[layer]) - hemi(dome.radii_mm[layer - 1]);
}

namespace {

/// Index of the dome sphere that p lies on (to 1e-9 relative), or -1.
int sphere_of(const DomeParams& dome, const Eigen::Vector3d& p) {
    const double r = p.norm();
    for (int i = 0; i <= kLayerCount; ++i)
        if (std::abs(r - dome.radii_mm[std::size_t(i)]) <= 1e-9 * dome.radii_mm[std::size_t(i)])
            return i;
    return -1;
}

/// The edges (sorted corner pairs) of the boundary and interface faces that lie on a sphere.
std::set<std::pair<int, int>> curved_edges(const DomeParams& dome, const TetMesh& mesh) {
    static constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
    std::map<std::array<int, 3>, std::vector<int>> regions_of;
    for (int t = 0; t < mesh.T.rows(); ++t)
        for (const auto& f : kFace) {
            std::array<int, 3> key{mesh.T(t, f[0]), mesh.T(t, f[1]), mesh.T(t, f[2])};
            std::sort(key.begin(), key.end());
            regions_of[key].push_back(mesh.region(t));
        }
    std::set<std::pair<int, int>> edges;
    for (const auto& [key, regions] : regions_of) {
        if (regions.size() == 2 && regions[0] == regions[1]) continue; // inside a region
        const int s = sphere_of(dome, mesh.V.row(key[0]));
        if (s < 0 || sphere_of(dome, mesh.V.row(key[1])) != s ||
            sphere_of(dome, mesh.V.row(key[2])) != s)
            continue;
        edges.emplace(key[0], key[1]);
        edges.emplace(key[1], key[2]);
        edges.emplace(key[0], key[2]);
    }
    return edges;
}

} // namespace

void make_dome_quadratic(const DomeParams& dome, TetMesh& mesh) {
    const std::set<std::pair<int, int>> curved = curved_edges(dome, mesh);
    make_quadratic(mesh, [&](int a, int b) {
        const Eigen::Vector3d mid = 0.5 * (mesh.V.row(a) + mesh.V.row(b)).transpose();
        if (!curved.count({std::min(a, b), std::max(a, b)})) return mid;
        const int s = sphere_of(dome, mesh.V.row(a));
        return Eigen::Vector3d(dome.radii_mm[std::size_t(s)] * mid.normalized());
    });
    // A flat tet with all four corners on one sphere folds when its facet edges bulge into it:
    // such tets (and their neighbours across those edges) keep straight edges.
    constexpr double kLowestRatio = 0.2;
    for (bool changed = true; changed;) {
        changed = false;
        for (int t = 0; t < mesh.T10.rows(); ++t) {
            if (jacobian_ratio(mesh, t) >= kLowestRatio) continue;
            for (int e = 0; e < 6; ++e) {
                const int a = mesh.T10(t, kTetEdges[e][0]), b = mesh.T10(t, kTetEdges[e][1]);
                const Eigen::RowVector3d mid = 0.5 * (mesh.V.row(a) + mesh.V.row(b));
                if ((mesh.V.row(mesh.T10(t, 4 + e)) - mid).norm() == 0) continue;
                mesh.V.row(mesh.T10(t, 4 + e)) = mid;
                changed = true;
            }
        }
    }
}

} // namespace chromasim::mechanics
