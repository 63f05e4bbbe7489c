// PathIntegrator's connections through the inner surface (manifold next-event estimation, see
// path_integrator.hpp): a chain's specular events carried to the LED plane with their Jacobian,
// the sphere model's starts, the Newton solve from them, and the point-LED sums built on it.
#include "render/path_integrator.hpp"

#include "render/sampling.hpp"
#include "render/sphere_refraction.hpp"

#include <Eigen/Geometry>
#include <Eigen/LU>

#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>

namespace chromasim::render::detail {

namespace {

/// Newton on the connection's direction: stop when the LED-plane point is this close (mm).
constexpr double kConnectTolerance_mm = 1e-6;
constexpr int kConnectIterations = 24;
/// Newton iterates in a row no closer to the LED point than the best before them, after which
/// a connection's solve gives up: a solve with no connection near otherwise runs all
/// kConnectIterations. 4 keeps the image's error as without the limit; 3 raises it.
constexpr int kConnectStall = 4;
/// Largest Newton step on the direction (rad): keeps the walk on the surface it started on.
constexpr double kConnectMaxStep = 0.1;
/// Two connections whose directions at p are this close (rad) are one (two of led_flux_point's
/// starts may find the same); the solves stop within 1e-6 mm on the LED plane, some 20 mm
/// away.
constexpr double kSameConnection = 1e-6;
/// A BSDF-sampled path and a connection solved to its LED point are the same path when their
/// directions at p are this close (rad); distinct connections lie much farther apart.
constexpr double kSamePath = 1e-4;

/// A chain followed to the LED plane.
struct PlanePoint {
    Vec3 l;         ///< on the plane z = led_z
    Vec3 x[2];      ///< on the triangles' planes
    double fresnel; ///< (1 - F) of the refraction, times F of the reflection
};

/// Columns: derivatives of a vector with respect to the direction's two tangent coordinates.
using Tangents = Eigen::Matrix<double, 3, 2>;

/// The derivative of v / |v| from v's, `unit` = v / |v|.
Tangents normalized_derivative(const Vec3& unit, double length, const Tangents& dv) {
    return (dv - unit * (unit.transpose() * dv)) / length;
}

/// p (inside the clear layers) along w through the events of `chain` on the planes of
/// `tris` (normals interpolated from the vertex normals, linearly extrapolated off the
/// triangle): refract into the air (index 1) at the first, reflect off the second from the
/// cavity side; then on to the plane z = led_z. With `J`, also the 2 x 2 Jacobian of the
/// LED-plane point (x, y) with respect to w in the tangent coordinates (b1, b2) of w
/// (orthonormal_basis; an isometry to first order, so |det J| is per steradian), carried
/// exactly through each step with the value (no extra passes for finite differences; the
/// Fresnel factors are not differentiated).
std::optional<PlanePoint> to_led_plane(const EmbreeScene::Triangle* tris, Chain chain,
                                       const Vec3& p, const Vec3& w, double eta, double led_z,
                                       Eigen::Matrix2d* J = nullptr) {
    PlanePoint out{};
    out.fresnel = 1.0;
    Vec3 pos = p, dir = w;
    // d pos and d dir: none and the tangents at the start.
    Tangents dpos = Tangents::Zero(), ddir;
    if (J) {
        Vec3 b1, b2;
        orthonormal_basis(w, b1, b2);
        ddir << b1, b2;
    }
    for (int k = 0; k < chain_length(chain); ++k) {
        const EmbreeScene::Triangle& t = tris[k];
        const Vec3 e1 = t.p[1] - t.p[0], e2 = t.p[2] - t.p[0];
        const Vec3 ng = e1.cross(e2);
        const double denom = ng.dot(dir);
        if (!(std::abs(denom) > 1e-300)) return std::nullopt;
        const double s = ng.dot(t.p[0] - pos) / denom;
        if (!(s > 0.0)) return std::nullopt;
        const Vec3 x = pos + s * dir;
        // Barycentric coordinates in the triangle's plane (outside it: linear extrapolation).
        const Vec3 q = x - t.p[0];
        const double d00 = e1.dot(e1), d01 = e1.dot(e2), d11 = e2.dot(e2);
        const double d20 = q.dot(e1), d21 = q.dot(e2);
        const double det = d00 * d11 - d01 * d01;
        if (!(det > 0.0)) return std::nullopt;
        const double b1 = (d11 * d20 - d01 * d21) / det, b2 = (d00 * d21 - d01 * d20) / det;
        const Vec3 n_raw = (1.0 - b1 - b2) * t.n[0] + b1 * t.n[1] + b2 * t.n[2];
        const double n_length = n_raw.norm();
        if (!(n_length > 0.0)) return std::nullopt;
        const double flip = n_raw.dot(dir) > 0.0 ? -1.0 : 1.0; // facing(): against dir
        const Vec3 n = flip * n_raw / n_length;
        const double cos_i = -dir.dot(n);
        // The derivatives of x, then of the normal through the barycentrics.
        Tangents dx, dn;
        if (J) {
            const Eigen::RowVector2d ds =
                -(ng.transpose() * dpos + s * (ng.transpose() * ddir)) / denom;
            dx = dpos + dir * ds + s * ddir;
            const Eigen::RowVector2d db1 = (d11 * e1 - d01 * e2).transpose() * dx / det;
            const Eigen::RowVector2d db2 = (d00 * e2 - d01 * e1).transpose() * dx / det;
            dn = normalized_derivative(n, n_length,
                                       flip * ((t.n[1] - t.n[0]) * db1 + (t.n[2] - t.n[0]) * db2));
        }
        if (k == 0) { // out of the layers
            const double sin2_t = eta * eta * (1.0 - cos_i * cos_i);
            if (sin2_t >= 1.0) return std::nullopt; // total reflection
            const double cos_t = std::sqrt(1.0 - sin2_t);
            out.fresnel *= 1.0 - fresnel_dielectric(cos_i, eta);
            // refract(), with its derivative.
            const Vec3 raw = eta * dir + (eta * cos_i - cos_t) * n;
            const double length = raw.norm();
            const Vec3 refracted = raw / length;
            if (J) {
                const Eigen::RowVector2d dcos_i = -(n.transpose() * ddir + dir.transpose() * dn);
                const Eigen::RowVector2d dcos_t = (eta * eta * cos_i / cos_t) * dcos_i;
                ddir = normalized_derivative(refracted, length,
                                             eta * ddir + n * (eta * dcos_i - dcos_t) +
                                                 (eta * cos_i - cos_t) * dn);
            }
            dir = refracted;
        } else { // off the surface, from the air
            out.fresnel *= fresnel_dielectric(cos_i, 1.0 / eta);
            const Vec3 raw = dir + 2.0 * cos_i * n;
            const double length = raw.norm();
            const Vec3 reflected = raw / length;
            if (J) {
                const Eigen::RowVector2d dcos_i = -(n.transpose() * ddir + dir.transpose() * dn);
                ddir = normalized_derivative(reflected, length,
                                             ddir + 2.0 * n * dcos_i + 2.0 * cos_i * dn);
            }
            dir = reflected;
        }
        out.x[k] = pos = x;
        if (J) dpos = dx;
    }
    if (!(dir.z() < 0.0)) return std::nullopt;
    const double r = (led_z - pos.z()) / dir.z();
    if (!(r > 0.0)) return std::nullopt;
    out.l = pos + r * dir;
    if (J) {
        const Eigen::RowVector2d dr = -(dpos.row(2) + r * ddir.row(2)) / dir.z();
        const Tangents dl = dpos + dir * dr + r * ddir;
        *J = dl.topRows<2>();
        if (!J->allFinite()) return std::nullopt;
    }
    return out;
}

/// The point on the circle of radius R about the origin, in the plane of unit vectors e1, e2,
/// at the angle of cosine c and sine s from e1, and the circle's unit tangent there.
std::pair<Vec3, Vec3> on_circle(const Vec3& e1, const Vec3& e2, double R, double c, double s) {
    return {R * (c * e1 + s * e2), -s * e1 + c * e2};
}

/// Samples of the circle when looking for the sphere model's mirror points.
constexpr int kMirrorScan = 64;

/// The reflections of a -> l off the inside of the sphere about the origin of radius R (a on
/// the sphere, l inside): the angles of the points x where the mirror law holds,
/// (x - a)^ . tau = (l - x)^ . tau, in the plane of O, a and l (e1 = a^), found by scanning
/// the circle and refining each sign change by regula falsi (illinois); arcs below the rim
/// plane z = 0 are skipped.
std::vector<Vec3> sphere_reflections(const Vec3& a, const Vec3& l, double R) {
    const Vec3 e1 = a.normalized();
    Vec3 e2 = l - l.dot(e1) * e1;
    if (!(e2.norm() > 1e-9)) return {};
    e2.normalize();
    // In the plane's coordinates a = (R, 0), l = (lx, ly), x = R (c, s) and tau = (-s, c), so
    // (x - a) . tau = R s and (l - x) . tau = ly c - lx s: a few flops and two square roots
    // instead of two vector normalisations (a direction of zero length counts as zero, as
    // normalized() leaves it).
    const double lx = l.dot(e1), ly = l.dot(e2);
    auto mismatch_at = [&](double c, double s) {
        const double to_a = std::sqrt((c - 1.0) * (c - 1.0) + s * s); // |x - a| / R
        const double dx = lx - R * c, dy = ly - R * s;
        const double to_l = std::sqrt(dx * dx + dy * dy);
        return (to_a > 0.0 ? s / to_a : 0.0) - (to_l > 0.0 ? (ly * c - lx * s) / to_l : 0.0);
    };
    constexpr double kEdge = 1e-3; // x = a is no reflection
    const double step = (2.0 * std::numbers::pi - 2.0 * kEdge) / kMirrorScan;
    const double cos_step = std::cos(step), sin_step = std::sin(step);
    // Within an arc from (c0, s0), the point turned by 2 atan(u), u in [0, tan(step / 2)]:
    // no trigonometry per evaluation.
    const double u_end = std::tan(0.5 * step);
    const auto turned = [](double c0, double s0, double u) {
        const double d = 1.0 / (1.0 + u * u), cu = (1.0 - u * u) * d, su = 2.0 * u * d;
        return std::pair<double, double>{c0 * cu - s0 * su, s0 * cu + c0 * su};
    };
    std::vector<Vec3> points;
    double c = std::cos(kEdge), s = std::sin(kEdge); // the scan turns (c, s) by step
    // The mismatch at the arc's start is evaluated only when an arc needs it: about half the
    // circle lies below the rim plane, where no arc is looked at.
    double prev_c = c, prev_s = s, prev_z = c * e1.z() + s * e2.z();
    std::optional<double> prev;
    for (int i = 1; i <= kMirrorScan; ++i) {
        const double c_next = c * cos_step - s * sin_step;
        s = s * cos_step + c * sin_step;
        c = c_next;
        const double z = c * e1.z() + s * e2.z();
        // Mirror points below the rim plane are no use (the dome is a hemisphere): skip arcs
        // whose ends both lie there (an arc of 2 pi / kMirrorScan rises at most 0.02 mm).
        if (z <= 0.0 && prev_z <= 0.0) {
            prev_c = c, prev_s = s, prev_z = z, prev.reset();
            continue;
        }
        if (!prev) prev = mismatch_at(prev_c, prev_s);
        const double f = mismatch_at(c, s);
        if ((f > 0.0) != (*prev > 0.0)) {
            const auto on_arc = [&](double u) {
                const auto [cu, su] = turned(prev_c, prev_s, u);
                return mismatch_at(cu, su);
            };
            const auto [mid, f_mid] = illinois(on_arc, 0.0, u_end, *prev, f, 1e-13);
            // A sign change across the pole of (x - a)^ is a jump, not a root.
            if (std::abs(f_mid) < 1e-6) {
                const auto [cm, sm] = turned(prev_c, prev_s, mid);
                points.push_back(on_circle(e1, e2, R, cm, sm).first);
            }
        }
        prev_c = c, prev_s = s, prev_z = z, prev = f;
    }
    return points;
}

/// sphere_refraction(p, l, R, eta) to 1e-13: by Newton from the straight line to l where it
/// gets there (the one root of the bracket, in fewer evaluations than the whole bracket's
/// regula falsi), else over the whole bracket.
Vec3 sphere_start(const Vec3& p, const Vec3& l, double R, double eta) {
    SphereRefraction solver(p, l, R, eta);
    if (const auto w = solver.newton((l - p).normalized(), 1e-13)) return *w;
    return solver.solve(1e-13);
}

/// The reflected chain's starts of the sphere model: the directions from p (in the layers)
/// that reach l by leaving the layers below p and reflecting off the sphere, one per mirror
/// point (sphere_reflections from the point below p) above the rim plane (the dome is a
/// hemisphere) that p reaches by a refraction without total internal reflection.
std::vector<Vec3> sphere_mirrors(const Vec3& p, const Vec3& l, double R, double eta) {
    std::vector<Vec3> kept;
    for (const Vec3& mirror : sphere_reflections(R * p.normalized(), l, R)) {
        if (!(mirror.z() > 0.0)) continue;
        const Vec3 w = sphere_start(p, mirror, R, eta);
        // Where w meets the sphere (from outside it, p being in the shell), and the refraction.
        const double b = p.dot(w), c = p.squaredNorm() - R * R;
        const double disc = b * b - c;
        if (!(disc >= 0.0)) continue;
        const double t = -b - std::sqrt(disc);
        if (!(t > 0.0)) continue;
        const Vec3 x = p + t * w;
        Vec3 out;
        if (!refract(w, x.normalized(), eta, out)) continue;
        // The refracted ray heads for the mirror point.
        if ((mirror - x).normalized().dot(out) > 1.0 - 1e-6) kept.push_back(w);
    }
    return kept;
}

/// The point of inner-surface triangle `prim` (of `scene`) at barycentric weights (b1, b2).
Vec3 surface_at(const EmbreeScene& scene, std::uint32_t prim, double b1, double b2) {
    const EmbreeScene::Triangle t = scene.interface_triangle(prim);
    return (1.0 - b1 - b2) * t.p[0] + b1 * t.p[1] + b2 * t.p[2];
}

/// `x` on inner-surface triangle `prim` as a material point (PointLedPaths::SurfacePoint).
PointLedPaths::SurfacePoint surface_point(const EmbreeScene& scene, std::uint32_t prim,
                                          const Vec3& x) {
    const EmbreeScene::Triangle t = scene.interface_triangle(prim);
    const Vec3 e1 = t.p[1] - t.p[0], e2 = t.p[2] - t.p[0], d = x - t.p[0];
    // The least-squares weights on the triangle's plane (Cramer's rule on its Gram matrix).
    const double g11 = e1.dot(e1), g12 = e1.dot(e2), g22 = e2.dot(e2);
    const double det = g11 * g22 - g12 * g12, r1 = e1.dot(d), r2 = e2.dot(d);
    if (!(det > 0.0)) return {};
    const double b1 = (g22 * r1 - g12 * r2) / det, b2 = (g11 * r2 - g12 * r1) / det;
    return {prim, b1, b2, surface_at(scene, prim, b1, b2)};
}

/// Where a frame's solve from p starts: towards the material point `at` on the deformed
/// surface (the connection's point moves with the surface), or along `rest` (the direction at
/// rest) where it is unknown or has not moved. Fewer Newton steps under a press, and it finds
/// connections that a start along `rest` loses (the light a pressed frame lost).
Vec3 towards(const EmbreeScene& scene, const Vec3& p, const PointLedPaths::SurfacePoint& at,
             const Vec3& rest) {
    if (at.prim >= scene.interface_triangles()) return rest;
    const Vec3 x = surface_at(scene, at.prim, at.b1, at.b2);
    if (x == at.rest_mm) return rest; // the rest's own answer, to the bit
    const Vec3 w = x - p;
    return w.norm() > 0.0 ? Vec3(w.normalized()) : rest;
}

} // namespace

std::optional<InterfaceConnection> PathIntegrator::along(const EmbreeScene& scene, Chain chain,
                                                         const std::uint32_t* prims, const Vec3& p,
                                                         const Vec3& w, Vec3* landed) const {
    EmbreeScene::Triangle tris[2];
    for (int k = 0; k < chain_length(chain); ++k)
        tris[k] = scene.interface_triangle(prims[k]);
    const double led_z = m_shading.optics().led_z_mm;
    Eigen::Matrix2d J;
    const auto point = to_led_plane(tris, chain, p, w, m_eta, led_z, &J);
    if (!point) return std::nullopt;
    if (landed) *landed = point->l;
    InterfaceConnection c;
    c.direction = w;
    for (int k = 0; k < chain_length(chain); ++k) {
        c.x_mm[k] = point->x[k];
        c.prim[k] = prims[k];
    }
    c.fresnel = point->fresnel;
    c.jacobian_mm2_per_sr = std::abs(J.determinant());
    return c;
}

std::optional<double> PathIntegrator::radius_below(const EmbreeScene& scene, const Vec3& p) const {
    const RayHit below = scene.closest_interface_hit(p, -p.normalized(), kHitGap_mm,
                                                     std::numeric_limits<double>::infinity());
    if (!below.hit()) return std::nullopt;
    return (p - below.t_mm * p.normalized()).norm();
}

int PathIntegrator::sphere_candidates(const EmbreeScene& scene, const Vec3& p, const Vec3& l,
                                      Chain chain) const {
    if (chain == Chain::refracted) return 1;
    const auto radius = radius_below(scene, p);
    return radius ? int(sphere_mirrors(p, l, *radius, m_eta).size()) : 0;
}

double PathIntegrator::nee_share(const EmbreeScene& scene, Chain chain, const Vec3& p,
                                 const Vec3& l, const Vec3& w) const {
    const auto radius = radius_below(scene, p);
    if (!radius) return 0.0;
    const std::vector<Vec3> starts = chain == Chain::refracted
                                         ? std::vector<Vec3>{sphere_start(p, l, *radius, m_eta)}
                                         : sphere_mirrors(p, l, *radius, m_eta);
    int found = 0;
    for (const Vec3& start : starts) {
        const auto c = solve_connection(scene, p, l, chain, start, int(starts.size()));
        found += c && (c->direction - w).norm() < kSamePath;
    }
    return starts.empty() ? 0.0 : double(found) / double(starts.size());
}

std::optional<InterfaceConnection> PathIntegrator::connect(const EmbreeScene& scene, const Vec3& p,
                                                           const Vec3& l, Chain chain,
                                                           double u) const {
    const auto radius = radius_below(scene, p);
    if (!radius) return std::nullopt;
    return connect(scene, p, l, chain, u, *radius);
}

std::optional<InterfaceConnection> PathIntegrator::connect(const EmbreeScene& scene, const Vec3& p,
                                                           const Vec3& l, Chain chain, double u,
                                                           double radius_mm,
                                                           const std::vector<Vec3>* known) const {
    // Start: the same chain on the sphere through the surface below p.
    Vec3 w;
    int candidates = 1;
    if (chain == Chain::refracted) {
        w = sphere_start(p, l, radius_mm, m_eta);
    } else {
        // Leave the layers at the point below p, bounce off one of the sphere's mirror points
        // (sphere_mirrors: the directions towards them).
        std::vector<Vec3> computed;
        if (!known) computed = sphere_mirrors(p, l, radius_mm, m_eta);
        const std::vector<Vec3>& starts = known ? *known : computed;
        if (starts.empty()) return std::nullopt;
        candidates = int(starts.size());
        w = starts[std::min(std::size_t(u * candidates), starts.size() - 1)];
    }
    return solve_connection(scene, p, l, chain, w, candidates);
}

std::optional<InterfaceConnection> PathIntegrator::solve_connection(const EmbreeScene& scene,
                                                                    const Vec3& p, const Vec3& l,
                                                                    Chain chain, const Vec3& w,
                                                                    int candidates) const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    const int n = chain_length(chain);
    // Newton on w in its tangent plane: each iterate traces the chain to find its triangles
    // (the first surface hit from p, then from x[0]), then solves on their planes; a step that
    // leaves the valid region (total internal reflection, a miss) is halved.
    struct Iterate {
        InterfaceConnection c;
        Vec3 landed;
        Eigen::Matrix2d J;
    };
    const double led_z = m_shading.optics().led_z_mm;
    auto evaluate = [&](const Vec3& dir) -> std::optional<Iterate> {
        EmbreeScene::Triangle tris[2];
        std::uint32_t prims[2] = {0, 0};
        Vec3 pos = p, d = dir;
        for (int k = 0; k < n; ++k) {
            const RayHit hit = scene.closest_interface_hit(pos, d, kHitGap_mm, inf);
            if (!hit.hit()) return std::nullopt;
            prims[k] = hit.prim_id;
            tris[k] = scene.interface_triangle(hit.prim_id);
            if (k + 1 == n) break;
            // Follow the refraction to find where the reflection happens.
            Vec3 out = Vec3::Zero();
            const Vec3 nx = facing(hit.shading_normal, d);
            if (!refract(d, nx, m_eta, out)) return std::nullopt;
            pos = pos + hit.t_mm * d;
            d = out;
        }
        Eigen::Matrix2d J;
        const auto point = to_led_plane(tris, chain, p, dir, m_eta, led_z, &J);
        if (!point) return std::nullopt;
        Iterate it;
        it.c.direction = dir;
        for (int k = 0; k < n; ++k) {
            it.c.x_mm[k] = point->x[k];
            it.c.prim[k] = prims[k];
        }
        it.c.fresnel = point->fresnel;
        it.c.jacobian_mm2_per_sr = std::abs(J.determinant());
        it.c.candidates = candidates;
        it.landed = point->l;
        it.J = J;
        return it;
    };
    std::optional<Iterate> current = evaluate(w);
    if (!current) return std::nullopt;
    // Where no connection is near, the iterates wander about the smallest miss without
    // closing in (reflected chains whose mirror point a press took away): such a solve stops
    // after kConnectStall iterates in a row that come no closer than the best before them.
    double best = std::numeric_limits<double>::infinity();
    int stalled = 0;
    for (int it = 0; it < kConnectIterations; ++it) {
        const Eigen::Vector2d g = (current->landed - l).head<2>();
        const double miss = g.norm();
        if (miss < kConnectTolerance_mm) return current->c;
        if (miss < best) {
            best = miss;
            stalled = 0;
        } else if (++stalled == kConnectStall) {
            return std::nullopt;
        }
        if (!(std::abs(current->J.determinant()) > 1e-12)) return std::nullopt;
        Eigen::Vector2d step = -current->J.inverse() * g;
        if (step.norm() > kConnectMaxStep) step *= kConnectMaxStep / step.norm();
        Vec3 b1, b2;
        orthonormal_basis(current->c.direction, b1, b2);
        std::optional<Iterate> next;
        for (int halving = 0; halving < 8 && !next; ++halving, step *= 0.5)
            next = evaluate((current->c.direction + step.x() * b1 + step.y() * b2).normalized());
        if (!next) return std::nullopt;
        current = next;
    }
    return std::nullopt;
}

std::optional<double> PathIntegrator::arriving_cosine(const EmbreeScene& scene,
                                                      const InterfaceConnection& c, Chain chain,
                                                      const Vec3& n, const Vec3& l) const {
    const double cos_p = n.dot(c.direction);
    if (!(cos_p > 0.0)) return std::nullopt;
    // Nothing in the way in the cavity (the surface again, a marker poking out, the frame).
    const int last = chain_length(chain) - 1;
    for (int k = 0; k <= last; ++k) {
        const Vec3 from = c.x_mm[k], to = k == last ? l : c.x_mm[k + 1];
        const Vec3 seg = to - from;
        const double len = seg.norm();
        if (len > 2.0 * kHitGap_mm &&
            (m_shading.crosses_mount(from, seg / len, 0.0, len) ||
             scene.closest_hit(from, seg / len, kHitGap_mm, len - kHitGap_mm).hit()))
            return std::nullopt;
    }
    return cos_p;
}

Vec3 PathIntegrator::led_flux_point(const EmbreeScene& scene, const Vec3& p, const Vec3& n, int k,
                                    std::optional<double> radius_mm, InterfaceConnection* refracted,
                                    const PointLedPaths* starts, PointLedPaths* found) const {
    const Vec3 l = led_point(k, 0.5, 0.5);
    if (!scene.has_interface()) return led_flux_sample(scene, p, n, k, 0.5, 0.5, 0.5, 0.0);
    const auto radius = radius_mm ? radius_mm : radius_below(scene, p);
    if (!radius) return Vec3::Zero();
    Vec3 sum = Vec3::Zero();
    // Each connection counted once (two starts may find the same: within kSameConnection),
    // where it arrives in front of the normal with nothing in the way.
    std::array<std::vector<Vec3>, 2> solved;                    // per chain, the directions
    std::array<std::vector<PointLedPaths::SurfacePoint>, 2> at; // and their first surface points
    const auto add = [&](const std::optional<InterfaceConnection>& c, Chain chain) {
        if (!c) return false;
        const int ch = chain == Chain::refracted ? 0 : 1;
        std::vector<Vec3>& seen = solved[std::size_t(ch)];
        for (const Vec3& w : seen)
            if ((w - c->direction).squaredNorm() < kSameConnection * kSameConnection) return false;
        seen.push_back(c->direction);
        if (found) at[std::size_t(ch)].push_back(surface_point(scene, c->prim[0], c->x_mm[0]));
        if (!arriving_cosine(scene, *c, chain, n, l)) return false;
        sum += (c->fresnel / c->jacobian_mm2_per_sr) * c->direction;
        return true;
    };
    // From the rest's connections, continued as the surface deforms (the sphere model's
    // refraction where the rest had none), else from the sphere model's.
    const bool from_rest = starts && starts->refracted.squaredNorm() > 0.0;
    const auto c =
        from_rest ? solve_connection(scene, p, l, Chain::refracted,
                                     towards(scene, p, starts->refracted_at, starts->refracted), 1)
                  : connect(scene, p, l, Chain::refracted, 0.5, *radius);
    if (add(c, Chain::refracted) && refracted) *refracted = *c;
    if (starts) {
        for (std::size_t i = 0; i < starts->reflected.size(); ++i) {
            const bool known = i < starts->reflected_at.size();
            const Vec3 w =
                towards(scene, p, known ? starts->reflected_at[i] : PointLedPaths::SurfacePoint{},
                        starts->reflected[i]);
            add(solve_connection(scene, p, l, Chain::refracted_reflected, w, 1),
                Chain::refracted_reflected);
        }
    } else {
        // The sphere model's starts once (sphere_candidates and each connect would otherwise
        // scan the circle again).
        const std::vector<Vec3> mirrors = sphere_mirrors(p, l, *radius, m_eta);
        const int candidates = int(mirrors.size());
        for (int i = 0; i < candidates; ++i)
            add(connect(scene, p, l, Chain::refracted_reflected, (i + 0.5) / candidates, *radius,
                        &mirrors),
                Chain::refracted_reflected);
    }
    if (found) {
        found->refracted = solved[0].empty() ? Vec3::Zero() : solved[0].front();
        found->reflected = solved[1];
        found->refracted_at = at[0].empty() ? PointLedPaths::SurfacePoint{} : at[0].front();
        found->reflected_at = at[1];
    }
    return sum;
}

Vec3 PathIntegrator::refracted_direction(const Vec3& p_mm, const Vec3& led_point_mm,
                                         double radius_mm) const {
    // 1e-9 in the sines: the direction to within about 1e-9 rad, 1e-8 mm across the layers.
    return sphere_refraction(p_mm, led_point_mm, radius_mm, m_eta, 1e-9);
}

} // namespace chromasim::render::detail
