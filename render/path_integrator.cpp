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

constexpr double kInvPi = 1.0 / std::numbers::pi;
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

/// Power heuristic weight of the strategy with density `a` against `b`.
double power_heuristic(double a, double b) {
    const double a2 = a * a, b2 = b * b;
    return a2 + b2 > 0.0 ? a2 / (a2 + b2) : 0.0;
}

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

} // namespace

PathIntegrator::PathIntegrator(const ShadingModel& shading, bool next_event)
    : m_shading(shading), m_next_event(next_event), m_eta(shading.optics().refractive_index),
      m_led_area_mm2(shading.optics().led_width_mm * shading.optics().led_height_mm) {
    for (const Vec3& c : shading.led_positions_mm()) {
        m_led_centres.push_back(c);
        Vec3 radial(c.x(), c.y(), 0.0);
        radial = radial.norm() > 0.0 ? Vec3(radial.normalized()) : Vec3(1.0, 0.0, 0.0);
        m_led_radials.push_back(radial);
        m_led_tangents.push_back(Vec3(-radial.y(), radial.x(), 0.0));
    }
}

Vec3 PathIntegrator::led_point(int k, double u1, double u2) const {
    const OpticsParams& o = m_shading.optics();
    return m_led_centres[std::size_t(k)] + (u1 - 0.5) * o.led_width_mm * m_led_tangents[k] +
           (u2 - 0.5) * o.led_height_mm * m_led_radials[k];
}

std::optional<std::pair<double, bool>> PathIntegrator::led_hit(const Vec3& origin,
                                                               const Vec3& direction, double tnear,
                                                               double tfar) const {
    if (direction.z() == 0.0) return std::nullopt;
    const OpticsParams& o = m_shading.optics();
    const double t = (o.led_z_mm - origin.z()) / direction.z();
    if (!(t > tnear && t < tfar)) return std::nullopt;
    if (!near_led(origin + t * direction, 0.0)) return std::nullopt;
    return std::make_pair(t, direction.z() < 0.0);
}

std::optional<Vec3> PathIntegrator::led_plane_crossing(const Vec3& origin,
                                                       const Vec3& direction) const {
    if (direction.z() == 0.0) return std::nullopt;
    const double t = (m_shading.optics().led_z_mm - origin.z()) / direction.z();
    if (!(t > 0.0)) return std::nullopt;
    return origin + t * direction;
}

bool PathIntegrator::near_led(const Vec3& q, double margin_mm) const {
    const OpticsParams& o = m_shading.optics();
    for (std::size_t k = 0; k < m_led_centres.size(); ++k) {
        const Vec3 local = q - m_led_centres[k];
        if (std::abs(local.dot(m_led_tangents[k])) <= 0.5 * o.led_width_mm + margin_mm &&
            std::abs(local.dot(m_led_radials[k])) <= 0.5 * o.led_height_mm + margin_mm)
            return true;
    }
    return false;
}

bool PathIntegrator::quad_near_led(const std::array<Vec3, 4>& q, double margin_mm) const {
    // In the plane's (x, y): the quad strictly convex (its turns all of one sign), else no
    // proof.
    const auto xy = [&](int i) {
        return Eigen::Vector2d(q[std::size_t(i)].x(), q[std::size_t(i)].y());
    };
    double sign = 0.0;
    for (int i = 0; i < 4; ++i) {
        const Eigen::Vector2d a = xy((i + 1) % 4) - xy(i), b = xy((i + 2) % 4) - xy((i + 1) % 4);
        const double turn = a.x() * b.y() - a.y() * b.x();
        if (!(std::abs(turn) > 0.0) || (sign != 0.0 && turn * sign < 0.0)) return true;
        sign = turn;
    }
    const OpticsParams& o = m_shading.optics();
    for (std::size_t k = 0; k < m_led_centres.size(); ++k) {
        const Eigen::Vector2d c(m_led_centres[k].x(), m_led_centres[k].y());
        const Eigen::Vector2d t(m_led_tangents[k].x(), m_led_tangents[k].y()),
            r(m_led_radials[k].x(), m_led_radials[k].y());
        const double ht = 0.5 * o.led_width_mm + margin_mm, hr = 0.5 * o.led_height_mm + margin_mm;
        const std::array<Eigen::Vector2d, 4> box = {c - ht * t - hr * r, c + ht * t - hr * r,
                                                    c + ht * t + hr * r, c - ht * t + hr * r};
        // Separated along an axis: the two shapes' projections do not overlap.
        const auto separated = [&](const Eigen::Vector2d& axis) {
            double a_lo = std::numeric_limits<double>::infinity(), a_hi = -a_lo;
            double b_lo = a_lo, b_hi = -a_lo;
            for (int i = 0; i < 4; ++i) {
                const double pa = axis.dot(xy(i)), pb = axis.dot(box[std::size_t(i)]);
                a_lo = std::min(a_lo, pa), a_hi = std::max(a_hi, pa);
                b_lo = std::min(b_lo, pb), b_hi = std::max(b_hi, pb);
            }
            return a_hi < b_lo || b_hi < a_lo;
        };
        bool apart = separated(t) || separated(r);
        for (int i = 0; i < 4 && !apart; ++i) {
            const Eigen::Vector2d e = xy((i + 1) % 4) - xy(i);
            apart = separated(Eigen::Vector2d(-e.y(), e.x()));
        }
        if (!apart) return true;
    }
    return false;
}

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

template <class Visit>
void PathIntegrator::for_each_connection(const EmbreeScene& scene, const Vec3& p, const Vec3& n,
                                         const Vec3& l, double u_choice, double radius_mm,
                                         Visit&& visit, int chains,
                                         const std::vector<Vec3>* mirrors) const {
    for (Chain chain : {Chain::refracted, Chain::refracted_reflected}) {
        if (!(chains & int(chain))) continue;
        const auto c = connect(scene, p, l, chain, u_choice, radius_mm, mirrors);
        if (!c) continue;
        if (const auto cos_p = arriving_cosine(scene, *c, chain, n, l)) visit(*c, *cos_p);
    }
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

template <int N>
LanesN<N> PathIntegrator::next_event(const EmbreeScene& scene, const Vec3& p, const Vec3& n,
                                     const LaneOptics<N>& lanes, PixelRng& rng) const {
    const int leds = led_count();
    const int k = std::min(int(rng.uniform() * leds), leds - 1);
    const double u1 = rng.uniform(), u2 = rng.uniform();
    const Vec3 l = led_point(k, u1, u2);
    const double pdf_area = 1.0 / (leds * m_led_area_mm2);
    const LanesN<N> emitted = lanes.led / m_led_area_mm2; // Lambertian radiance
    if (!scene.has_interface()) {
        const Vec3 to_led = l - p;
        const double d2 = to_led.squaredNorm();
        const Vec3 w = to_led / std::sqrt(d2);
        const double cos_p = n.dot(w), cos_l = -w.z();
        if (!(cos_p > 0.0 && cos_l > 0.0)) return LanesN<N>::Zero();
        const LanesN<N> T = m_shading.transmittance(scene, l, p, lanes);
        const double pdf_nee = pdf_area * d2 / cos_l;
        return emitted * T * (cos_p / pdf_nee * power_heuristic(pdf_nee, cos_p * kInvPi));
    }
    LanesN<N> total = LanesN<N>::Zero();
    const double u_choice = rng.uniform();
    const auto radius = radius_below(scene, p); // the sphere model's, for both chains
    if (!radius) return total;
    for_each_connection(
        scene, p, n, l, u_choice, *radius, [&](const InterfaceConnection& c, double cos_p) {
            const LanesN<N> T = m_shading.transmittance(scene, c.x_mm[0], p, lanes, kHitGap_mm);
            const double pdf_nee = pdf_area * c.jacobian_mm2_per_sr / c.candidates;
            const double pdf_bsdf = cos_p * kInvPi * c.fresnel;
            total +=
                emitted * T * (c.fresnel * cos_p / pdf_nee * power_heuristic(pdf_nee, pdf_bsdf));
        });
    return total;
}

Vec3 PathIntegrator::led_flux_sample(const EmbreeScene& scene, const Vec3& p, const Vec3& n, int k,
                                     double u1, double u2, double u_choice, double bsdf_per_nee,
                                     std::optional<double> radius_mm) const {
    const Vec3 l = led_point(k, u1, u2);
    if (!scene.has_interface()) {
        const Vec3 to_led = l - p;
        const double d2 = to_led.squaredNorm();
        const Vec3 w = to_led / std::sqrt(d2);
        const double cos_p = n.dot(w), cos_l = -w.z();
        if (!(cos_p > 0.0 && cos_l > 0.0)) return Vec3::Zero();
        if (m_shading.crosses_mount(p, w, 0.0, std::sqrt(d2)) ||
            scene.closest_hit(p, w, kHitGap_mm, std::sqrt(d2) - kHitGap_mm).hit())
            return Vec3::Zero();
        return (cos_l / d2) * w;
    }
    const auto radius = radius_mm ? radius_mm : radius_below(scene, p);
    if (!radius) return Vec3::Zero();
    Vec3 sum = Vec3::Zero();
    for_each_connection(
        scene, p, n, l, u_choice, *radius, [&](const InterfaceConnection& c, double cos_p) {
            // MIS against indirect()'s cosine samples (power heuristic with
            // the sample counts' ratio).
            const double pdf_nee = c.jacobian_mm2_per_sr / (c.candidates * m_led_area_mm2);
            const double pdf_bsdf = cos_p * kInvPi * c.fresnel;
            sum += (c.fresnel * c.candidates / c.jacobian_mm2_per_sr *
                    power_heuristic(pdf_nee, bsdf_per_nee * pdf_bsdf)) *
                   c.direction;
        });
    return sum;
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
    std::array<std::vector<Vec3>, 2> solved; // per chain, the directions
    const auto add = [&](const std::optional<InterfaceConnection>& c, Chain chain) {
        if (!c) return false;
        std::vector<Vec3>& seen = solved[chain == Chain::refracted ? 0 : 1];
        for (const Vec3& w : seen)
            if ((w - c->direction).squaredNorm() < kSameConnection * kSameConnection) return false;
        seen.push_back(c->direction);
        if (!arriving_cosine(scene, *c, chain, n, l)) return false;
        sum += (c->fresnel / c->jacobian_mm2_per_sr) * c->direction;
        return true;
    };
    // From the rest's connections, continued as the surface deforms (the sphere model's
    // refraction where the rest had none), else from the sphere model's.
    const bool from_rest = starts && starts->refracted.squaredNorm() > 0.0;
    const auto c = from_rest ? solve_connection(scene, p, l, Chain::refracted, starts->refracted, 1)
                             : connect(scene, p, l, Chain::refracted, 0.5, *radius);
    if (add(c, Chain::refracted) && refracted) *refracted = *c;
    if (starts) {
        for (const Vec3& w : starts->reflected)
            add(solve_connection(scene, p, l, Chain::refracted_reflected, w, 1),
                Chain::refracted_reflected);
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
    }
    return sum;
}

Vec3 PathIntegrator::refracted_direction(const Vec3& p_mm, const Vec3& led_point_mm,
                                         double radius_mm) const {
    // 1e-9 in the sines: the direction to within about 1e-9 rad, 1e-8 mm across the layers.
    return sphere_refraction(p_mm, led_point_mm, radius_mm, m_eta, 1e-9);
}

template <int N>
LanesN<N> PathIntegrator::radiance(const EmbreeScene& scene, const Vec3& origin,
                                   const Vec3& direction, const LaneOptics<N>& lanes,
                                   PixelRng& rng) const {
    return trace(scene, origin, direction, lanes, rng, nullptr, 0.0);
}

template <int N>
LanesN<N> PathIntegrator::indirect(const EmbreeScene& scene, const Vec3& p_mm, const Vec3& normal,
                                   const LaneOptics<N>& lanes, PixelRng& rng,
                                   double nee_per_bsdf) const {
    const double u1 = rng.uniform(), u2 = rng.uniform();
    const Vec3 d = cosine_direction(normal, u1, u2);
    if (!(normal.dot(d) > 0.0)) return LanesN<N>::Zero();
    return trace(scene, p_mm, d, lanes, rng, &normal, nee_per_bsdf);
}

template <int N>
LanesN<N> PathIntegrator::trace(const EmbreeScene& scene, const Vec3& origin, const Vec3& direction,
                                const LaneOptics<N>& lanes, PixelRng& rng, const Vec3* start_normal,
                                double start_nee_per_bsdf) const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    const OpticsParams& optics = m_shading.optics();
    const double pdf_area = 1.0 / (led_count() * m_led_area_mm2);
    LanesN<N> L = LanesN<N>::Zero();
    LanesN<N> beta = LanesN<N>::Ones();
    Vec3 o = origin, d = direction;
    double tnear = 0.0;
    MarkerPath path(0.0);
    // The last diffuse vertex and what happened since, for the MIS weight of an LED hit.
    struct {
        bool diffuse = false;
        Vec3 p, w;                       ///< the vertex and the direction sampled there
        double pdf_bsdf = 0.0;           ///< cos / pi
        int events = 0;                  ///< interface events since, while they form a Chain
        bool chain = true;               ///< false once they no longer do
        std::uint32_t prims[2] = {0, 0}; ///< their triangles
    } last;
    int bounces = 0;
    // indirect(): the path starts at a diffuse vertex, whose light straight from the LEDs
    // through a Chain (next-event estimation's domain) is left out.
    bool at_start = start_normal != nullptr;
    if (at_start) {
        last.diffuse = true;
        last.p = origin;
        last.w = direction;
        last.pdf_bsdf = start_normal->dot(direction) * kInvPi;
        tnear = kHitGap_mm;
        bounces = 1;
    }
    // The current ray's hits (RayHits: its markers and the next other surface from one
    // traversal), traced anew whenever the path turns.
    std::optional<RayHits> hits;
    // Lambertian scattering at p (normal n facing the incoming ray): NEE, then a new direction.
    auto scatter = [&](const Vec3& p, const Vec3& n, const LanesN<N>& albedo) -> bool {
        at_start = false;
        if (m_next_event) L += beta * albedo * kInvPi * next_event(scene, p, n, lanes, rng);
        beta *= albedo;
        if (++bounces > kMaxBounces) return false;
        if (bounces >= 3) {
            const double q = std::min(1.0, beta.maxCoeff());
            if (!(rng.uniform() < q)) return false;
            beta /= q;
        }
        const double u1 = rng.uniform(), u2 = rng.uniform();
        d = cosine_direction(n, u1, u2);
        last.diffuse = true;
        last.p = p;
        last.w = d;
        last.pdf_bsdf = std::max(0.0, n.dot(d)) * kInvPi;
        last.events = 0;
        last.chain = true;
        o = p;
        tnear = kHitGap_mm;
        path = MarkerPath(0.0);
        hits.reset();
        return last.pdf_bsdf > 0.0;
    };
    for (int event = 0; event < kMaxBounces * kMaxHits; ++event) {
        if (!hits) hits.emplace(scene, o, d, tnear, inf);
        const RayHit hit = hits->next(tnear);
        const double tfar = hit.hit() ? hit.t_mm : inf;
        if (m_shading.crosses_mount(o, d, tnear, tfar)) break; // absorbed by the black frame
        if (const auto led = led_hit(o, d, tnear, tfar)) {
            if (!led->second) break; // the black back of an LED
            double weight = 1.0;
            if (at_start && last.chain && !scene.has_interface() && last.events == 0)
                break; // straight light of the start vertex: led_flux_sample's
            if (at_start && last.chain && scene.has_interface() && last.events > 0) {
                // Light of the start vertex through a Chain: led_flux_sample's share under
                // MIS (weight 1 where no start of its solve finds this path).
                const Vec3 l = o + led->first * d;
                const Chain chain = Chain(last.events);
                const auto c = along(scene, chain, last.prims, last.p, last.w);
                const double share = c ? nee_share(scene, chain, last.p, l, last.w) : 0.0;
                if (share > 0.0)
                    weight = power_heuristic(last.pdf_bsdf * c->fresnel,
                                             start_nee_per_bsdf * c->jacobian_mm2_per_sr * share /
                                                 m_led_area_mm2);
                L += beta * (lanes.led / m_led_area_mm2) * weight;
                break;
            }
            if (m_next_event && last.diffuse && last.chain) {
                const Vec3 l = o + led->first * d;
                if (!scene.has_interface() && last.events == 0) {
                    const double pdf_nee = pdf_area * (l - last.p).squaredNorm() / -d.z();
                    weight = power_heuristic(last.pdf_bsdf, pdf_nee);
                } else if (scene.has_interface() && last.events > 0) {
                    // The density next-event estimation gives this chain (what next_event does).
                    const Chain chain = Chain(last.events);
                    const auto c = along(scene, chain, last.prims, last.p, last.w);
                    const double share = c ? nee_share(scene, chain, last.p, l, last.w) : 0.0;
                    if (share > 0.0)
                        weight = power_heuristic(last.pdf_bsdf * c->fresnel,
                                                 pdf_area * c->jacobian_mm2_per_sr * share);
                }
            }
            L += beta * (lanes.led / m_led_area_mm2) * weight;
            break;
        }
        if (!hit.hit()) break;
        if (!(hit.normal.squaredNorm() > 0.5)) { // a zero-area triangle: no surface there
            tnear = hit.t_mm + kHitGap_mm;
            continue;
        }
        const Vec3 p = o + hit.t_mm * d;
        const double cos_g = hit.normal.dot(d);
        bool go_on = true;
        switch (hit.kind) {
        case SurfaceKind::coating:
            go_on = scatter(p, facing(hit.normal, d), lanes.coating_albedo);
            break;
        case SurfaceKind::inner_marker:
        case SurfaceKind::outer_marker: {
            tnear = hit.t_mm + kHitGap_mm;
            if (cos_g == 0.0) break; // degenerate or edge-on face: no entry, no exit
            const bool outer = hit.kind == SurfaceKind::outer_marker;
            const double inside = path.cross(outer, hit.t_mm, cos_g < 0.0);
            if (inside >= 0.0)
                beta *= m_shading.marker_absorption(lanes, outer, inside);
            else if (outer && rng.uniform() < optics.outer_marker_scatter_fraction)
                go_on = scatter(p, facing(hit.normal, d), lanes.outer_albedo);
            break;
        }
        case SurfaceKind::inner_surface: {
            if (cos_g == 0.0) {
                tnear = hit.t_mm + kHitGap_mm;
                break;
            }
            // The winding makes the normal point into the cavity: against it, air -> layers.
            const double eta = cos_g < 0.0 ? 1.0 / m_eta : m_eta;
            const Vec3 n_geometric = facing(hit.normal, d);
            const Vec3 n = facing(hit.shading_normal, d);
            const double cos_i = -d.dot(n);
            Vec3 next = Vec3::Zero();
            if (rng.uniform() < fresnel_dielectric(cos_i, eta)) {
                next = (d + 2.0 * cos_i * n).normalized();
                // A reflection in the cavity after the refraction continues a Chain.
                if (last.events == 1 && cos_g < 0.0)
                    last.prims[last.events++] = hit.prim_id;
                else
                    last.chain = false;
                go_on = next.dot(n_geometric) > 0.0; // shading normal sent it through
            } else {
                go_on = refract(d, n, eta, next) && next.dot(n_geometric) < 0.0;
                // A refraction out of the layers starts a Chain.
                if (last.events == 0 && cos_g > 0.0)
                    last.prims[last.events++] = hit.prim_id;
                else
                    last.chain = false;
            }
            o = p;
            d = next;
            tnear = kHitGap_mm;
            path = MarkerPath(0.0);
            hits.reset();
            break;
        }
        case SurfaceKind::none:
            break;
        }
        if (!go_on) break;
    }
    return L;
}

template LanesN<kRgbLanes> PathIntegrator::indirect(const EmbreeScene&, const Vec3&, const Vec3&,
                                                    const LaneOptics<kRgbLanes>&, PixelRng&,
                                                    double) const;
template LanesN<kSpectralLanes> PathIntegrator::indirect(const EmbreeScene&, const Vec3&,
                                                         const Vec3&,
                                                         const LaneOptics<kSpectralLanes>&,
                                                         PixelRng&, double) const;
template LanesN<kRgbLanes> PathIntegrator::radiance(const EmbreeScene&, const Vec3&, const Vec3&,
                                                    const LaneOptics<kRgbLanes>&, PixelRng&) const;
template LanesN<kSpectralLanes> PathIntegrator::radiance(const EmbreeScene&, const Vec3&,
                                                         const Vec3&,
                                                         const LaneOptics<kSpectralLanes>&,
                                                         PixelRng&) const;

} // namespace chromasim::render::detail
