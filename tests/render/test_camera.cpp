// Tests of the fisheye camera models (render/fisheye_camera.hpp): the equidistant lens, OpenCV's
// Kannala-Brandt model against a hand-computed case, their agreement, the camera pose, and the
// checks on bad parameters.
#include "render/fisheye_camera.hpp"
#include "render/renderer.hpp"

#include <Eigen/Geometry>
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <vector>

using namespace chromasim::render;
using Catch::Matchers::Contains;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

/// Angle between two directions, rad (atan2 form: accurate for tiny angles too).
double angle_between(const Vec3& a, const Vec3& b) {
    return std::atan2(a.cross(b).norm(), a.dot(b));
}

/// A Kannala-Brandt camera as cv::fisheye::calibrate might return it for a lens slightly
/// wider than a hemisphere: fx != fy, principal point off centre, all four k non-zero.
CameraParams calibrated_camera() {
    CameraParams p;
    p.width_px = 96;
    p.height_px = 80;
    p.half_fov_deg = 95.0;
    p.model = CameraModel::kannala_brandt;
    p.fx_px = 24.0;
    p.fy_px = 25.5;
    p.cx_px = 47.2;
    p.cy_px = 38.9;
    p.k1 = 0.1;
    p.k2 = -0.05;
    p.k3 = 0.01;
    p.k4 = -0.002;
    return p;
}

/// Pixels on a grid of steps `step_px` over the whole image, including its edges.
std::vector<Eigen::Vector2d> pixel_grid(const CameraParams& p, double step_px) {
    std::vector<Eigen::Vector2d> grid;
    for (double y = 0.0; y <= p.height_px; y += step_px)
        for (double x = 0.0; x <= p.width_px; x += step_px)
            grid.emplace_back(x, y);
    return grid;
}

} // namespace

TEST_CASE("Kannala-Brandt projection matches OpenCV's cv::fisheye formula", "[render][camera]") {
    CameraParams p = calibrated_camera();
    p.width_px = 640;
    p.height_px = 480;
    p.fx_px = 400.0;
    p.fy_px = 410.0;
    p.cx_px = 320.0;
    p.cy_px = 240.0;
    const FisheyeCamera camera(p);
    // By hand, OpenCV's cv::fisheye::projectPoints for the point P = (3, 4, 5) mm:
    //   a = x/z = 0.6, b = y/z = 0.8, r = sqrt(a^2 + b^2) = 1, theta = atan(1) = pi/4
    //   theta^2 = 0.61685027506808491, theta^4 = 0.38050426185157202,
    //   theta^6 = 0.23471415858772081, theta^8 = 0.14478349328720969
    //   1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8
    //     = 1 + 0.061685027506808491 - 0.019025213092578601 + 0.0023471415858772081
    //         - 0.00028956698657441937 = 1.0447173890135326791
    //   theta_d = pi/4 * 1.0447173890135326791 = 0.82051911860060610857
    //   x_d = theta_d / r * a = 0.49231147116036366514
    //   y_d = theta_d / r * b = 0.65641529488048488686
    //   u = fx x_d + cx = 400 * 0.49231147116036366514 + 320 = 516.92458846414546606
    //   v = fy y_d + cy = 410 * 0.65641529488048488686 + 240 = 509.13027090099880361
    // chromasim's pixel coordinates put pixel centres at half-integers: (u + 0.5, v + 0.5).
    const Vec3 point(3.0, 4.0, 5.0);
    const Eigen::Vector2d expected(516.92458846414546606 + 0.5, 509.13027090099880361 + 0.5);
    const auto pixel = camera.project(point);
    REQUIRE(pixel);
    CHECK((*pixel - expected).norm() < 1e-9);
    const auto back = camera.direction(expected);
    REQUIRE(back);
    CHECK(angle_between(*back, point) < 1e-12);
    // The optical axis meets the image at the principal point, shifted to chromasim's pixels.
    CHECK((*camera.project(Vec3(0.0, 0.0, 2.0)) - Eigen::Vector2d(320.5, 240.5)).norm() == 0.0);
    CHECK((camera.centre_px() - Eigen::Vector2d(320.5, 240.5)).norm() == 0.0);
}

TEST_CASE("direction -> project -> direction round trips for both models", "[render][camera]") {
    CameraParams equidistant{80, 60, 84.0};
    for (const CameraParams& p : {equidistant, calibrated_camera()}) {
        INFO("model " << int(p.model));
        const FisheyeCamera camera(p);
        int imaged = 0, black = 0;
        for (const Eigen::Vector2d& px : pixel_grid(p, 0.7)) {
            const auto d = camera.direction(px);
            if (!d) {
                ++black;
                continue;
            }
            ++imaged;
            REQUIRE(std::abs(d->norm() - 1.0) < 1e-12);
            const auto back_px = camera.project(12.7 * *d);
            REQUIRE(back_px);
            CHECK((*back_px - px).norm() < 1e-9);
            const auto back = camera.direction(*back_px);
            REQUIRE(back);
            CHECK(angle_between(*back, *d) < 1e-9);
        }
        // The grid covers the field and the dark corners beyond it.
        CHECK(imaged > 2000);
        CHECK(black > 100);
    }
    // The field ends at half_fov: just inside is imaged, just outside is not.
    const FisheyeCamera kb(calibrated_camera());
    const double edge = 95.0 * kDeg;
    for (double phi : {0.0, 1.0, 2.5, -2.0}) {
        const Vec3 inside(std::sin(edge - 1e-9) * std::cos(phi),
                          std::sin(edge - 1e-9) * std::sin(phi), std::cos(edge - 1e-9));
        const Vec3 outside(std::sin(edge + 1e-9) * std::cos(phi),
                           std::sin(edge + 1e-9) * std::sin(phi), std::cos(edge + 1e-9));
        const auto px = kb.project(inside);
        REQUIRE(px);
        CHECK(kb.direction(*px));
        CHECK_FALSE(kb.project(outside));
    }
    CHECK_FALSE(kb.project(Vec3::Zero()));
    CHECK_FALSE(kb.direction(Eigen::Vector2d(0.0, 0.0))); // a corner, beyond the field
}

TEST_CASE("Kannala-Brandt with k = 0 is the equidistant camera", "[render][camera]") {
    const CameraParams equidistant{80, 60, 84.0}; // circle radius 30 px
    CameraParams kb = equidistant;
    kb.model = CameraModel::kannala_brandt;
    kb.fx_px = kb.fy_px = 30.0 / (84.0 * kDeg);
    kb.cx_px = 39.5; // the image centre (40, 30) in OpenCV's convention
    kb.cy_px = 29.5;
    const CameraParams derived = with_equidistant_intrinsics(equidistant);
    CHECK(derived.model == CameraModel::kannala_brandt);
    CHECK(std::abs(derived.fx_px - kb.fx_px) < 1e-12);
    CHECK(std::abs(derived.fy_px - kb.fy_px) < 1e-12);
    CHECK(derived.cx_px == kb.cx_px);
    CHECK(derived.cy_px == kb.cy_px);

    const FisheyeCamera a(equidistant), b(kb);
    CHECK(std::abs(a.circle_radius_px() - b.circle_radius_px()) < 1e-12);
    for (double polar : {0.0, 5.0, 42.0, 83.9}) {
        for (double azimuth : {0.0, 30.0, 135.0, -100.0}) {
            const Vec3 p(std::sin(polar * kDeg) * std::cos(azimuth * kDeg),
                         std::sin(polar * kDeg) * std::sin(azimuth * kDeg), std::cos(polar * kDeg));
            const auto pa = a.project(7.0 * p), pb = b.project(7.0 * p);
            REQUIRE(pa);
            REQUIRE(pb);
            CHECK((*pa - *pb).norm() < 1e-9);
        }
    }
    for (const Eigen::Vector2d& px : pixel_grid(equidistant, 1.3)) {
        const auto da = a.direction(px), db = b.direction(px);
        // Both end the field at the same circle (ties at the exact edge aside).
        if (std::abs((px - a.centre_px()).norm() - 30.0) < 1e-9) continue;
        REQUIRE(bool(da) == bool(db));
        if (da) CHECK(angle_between(*da, *db) < 1e-12);
    }
}

TEST_CASE("a posed camera sees the scene in its own frame", "[render][camera]") {
    const Vec3 position(1.5, -2.0, 0.5);
    const double roll = 10.0, pitch = -20.0, yaw = 30.0;
    // R = Rz(yaw) Ry(pitch) Rx(roll): the camera's axes in the dome frame.
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(yaw * kDeg, Vec3::UnitZ()) *
                               Eigen::AngleAxisd(pitch * kDeg, Vec3::UnitY()) *
                               Eigen::AngleAxisd(roll * kDeg, Vec3::UnitX()))
                                  .toRotationMatrix();
    for (CameraParams p : {CameraParams{80, 60, 84.0}, calibrated_camera()}) {
        INFO("model " << int(p.model));
        const FisheyeCamera identity(p);
        p.position_mm = position;
        p.roll_deg = roll, p.pitch_deg = pitch, p.yaw_deg = yaw;
        const FisheyeCamera posed(p);
        CHECK(posed.origin_mm() == position);
        CHECK((posed.rotation() - R).norm() < 1e-15);
        for (const Vec3& point : {Vec3(0.0, 0.0, 12.7), Vec3(3.0, 4.0, 9.0), Vec3(-6.0, 2.0, 8.0),
                                  Vec3(5.0, -7.0, 1.0)}) {
            const Vec3 in_camera = R.transpose() * (point - position);
            const auto expected = identity.project(in_camera);
            const auto got = posed.project(point);
            REQUIRE(bool(expected) == bool(got));
            if (got) CHECK((*got - *expected).norm() < 1e-9);
        }
        for (const Eigen::Vector2d& px : pixel_grid(p, 7.0)) {
            const auto d_camera = identity.direction(px);
            const auto d = posed.direction(px);
            REQUIRE(bool(d_camera) == bool(d));
            if (d) CHECK((*d - R * *d_camera).norm() < 1e-12);
        }
    }
    // The convention itself, independent of the formula above: yaw 90 deg turns the camera's
    // x axis onto the dome's +y, so a point 45 deg towards +y lands right of the centre.
    CameraParams yawed{80, 60, 84.0};
    yawed.yaw_deg = 90.0;
    const auto right = FisheyeCamera(yawed).project(Vec3(0.0, 5.0, 5.0));
    REQUIRE(right);
    CHECK((*right - Eigen::Vector2d(40.0 + 45.0 / 84.0 * 30.0, 30.0)).norm() < 1e-9);
    // Pitch 90 deg turns the optical axis onto the dome's +x.
    CameraParams pitched{80, 60, 84.0};
    pitched.pitch_deg = 90.0;
    const auto centre = FisheyeCamera(pitched).project(Vec3(5.0, 0.0, 0.0));
    REQUIRE(centre);
    CHECK((*centre - Eigen::Vector2d(40.0, 30.0)).norm() < 1e-9);
}

TEST_CASE("the renderer traces rays from the posed camera", "[render][camera]") {
    // A 1 mm white square at (3, 0, 10) facing the base, and nothing else. A narrow camera
    // (+-8 deg) at the origin looking along +z cannot see it (it lies 16.7 deg off axis); moved
    // under it, or turned towards it, its centre pixel does.
    SensorFrame frame;
    frame.coating.V.resize(4, 3);
    frame.coating.V << 2.5f, -0.5f, 10.0f, 3.5f, -0.5f, 10.0f, 3.5f, 0.5f, 10.0f, 2.5f, 0.5f, 10.0f;
    frame.coating.F.resize(2, 3);
    frame.coating.F << 0, 2, 1, 0, 3, 2;
    const auto centre_value = [&](const CameraParams& camera) {
        Renderer renderer(camera, OpticsParams{});
        renderer.set_frame(frame);
        const Image image = renderer.render({1, 1});
        return double(image.pixel(16, 16)[0]);
    };
    const CameraParams at_origin{33, 33, 8.0};
    CHECK(centre_value(at_origin) == 0.0);
    CameraParams moved = at_origin;
    moved.position_mm = Vec3(3.0, 0.0, 0.0);
    CHECK(centre_value(moved) > 0.05);
    CameraParams turned = at_origin;
    turned.pitch_deg = std::atan2(3.0, 10.0) / kDeg; // Ry(pitch) turns +z towards +x
    CHECK(centre_value(turned) > 0.05);
}

TEST_CASE("kannala_brandt_min_slope finds the smallest slope of theta_d", "[render][camera]") {
    // k1 only: slope 1 - 0.3 theta^2 falls to its end, 1 - 0.3 * 1.5^2 = 0.325.
    const SlopeMinimum falling = kannala_brandt_min_slope(-0.1, 0.0, 0.0, 0.0, 1.5);
    CHECK(std::abs(falling.slope - 0.325) < 1e-12);
    CHECK(std::abs(falling.theta_rad - 1.5) < 1e-12);
    // k1 = -0.2, k2 = 0.05: slope 1 - 0.6 s + 0.25 s^2 (s = theta^2) has its minimum inside,
    // at s = 0.6 / 0.5 = 1.2, of 1 - 0.72 + 0.36 = 0.64.
    const SlopeMinimum dip = kannala_brandt_min_slope(-0.2, 0.05, 0.0, 0.0, 1.5);
    CHECK(std::abs(dip.slope - 0.64) < 1e-12);
    CHECK(std::abs(dip.theta_rad - std::sqrt(1.2)) < 1e-7);
    // Rising slope: the minimum is 1 at theta = 0.
    const SlopeMinimum rising = kannala_brandt_min_slope(0.1, 0.0, 0.0, 0.0, 1.5);
    CHECK(rising.slope == 1.0);
    CHECK(rising.theta_rad == 0.0);
}

TEST_CASE("invalid camera parameters are rejected with what is allowed", "[render][camera]") {
    const auto with = [](auto change) {
        CameraParams p = calibrated_camera();
        change(p);
        return p;
    };
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double inf = std::numeric_limits<double>::infinity();
    CHECK_THROWS_AS(FisheyeCamera(with([=](CameraParams& p) { p.fx_px = 0.0; })),
                    std::invalid_argument);
    CHECK_THROWS_WITH(FisheyeCamera(with([=](CameraParams& p) { p.fx_px = 0.0; })),
                      Contains("fx_px = 0 is invalid") &&
                          Contains("allowed: a finite focal length > 0 (px"));
    CHECK_THROWS_WITH(FisheyeCamera(with([=](CameraParams& p) { p.fy_px = -25.0; })),
                      Contains("fy_px = -25 is invalid") && Contains("allowed: a finite"));
    CHECK_THROWS_WITH(FisheyeCamera(with([=](CameraParams& p) { p.fx_px = inf; })),
                      Contains("fx_px = inf is invalid"));
    CHECK_THROWS_WITH(FisheyeCamera(with([=](CameraParams& p) { p.cy_px = nan; })),
                      Contains("cy_px = nan is invalid") && Contains("allowed: a finite number"));
    CHECK_THROWS_AS(FisheyeCamera(with([=](CameraParams& p) { p.k3 = nan; })),
                    std::invalid_argument);
    CHECK_THROWS_WITH(FisheyeCamera(with([=](CameraParams& p) { p.k2 = inf; })),
                      Contains("k2 = inf is invalid") &&
                          Contains("allowed: a finite distortion coefficient (OpenCV's D[1])"));
    // k1 = -0.5: slope 1 - 1.5 theta^2 reaches 0 at 46.8 deg, inside an 84 deg field.
    const auto steep = [](double half_fov_deg) {
        CameraParams p = calibrated_camera();
        p.half_fov_deg = half_fov_deg;
        p.k1 = -0.5, p.k2 = p.k3 = p.k4 = 0.0;
        return p;
    };
    CHECK_THROWS_AS(FisheyeCamera(steep(84.0)), std::invalid_argument);
    CHECK_THROWS_WITH(
        FisheyeCamera(steep(84.0)),
        Contains("k1..k4 = (-0.5, 0, 0, 0)") && Contains("stop increasing within the field") &&
            Contains("at theta = 84 deg") && Contains("allowed: coefficients with 1 + 3 k1 t^2") &&
            Contains("or a smaller half_fov_deg"));
    CHECK_NOTHROW(FisheyeCamera(steep(40.0))); // the same lens over a field it covers
    // The pose applies to both models.
    CameraParams moved{64, 64, 84.0};
    moved.position_mm.y() = nan;
    CHECK_THROWS_WITH(FisheyeCamera(moved),
                      Contains("position_mm.y = nan is invalid") && Contains("allowed: a finite"));
    CameraParams turned{64, 64, 84.0};
    turned.pitch_deg = inf;
    CHECK_THROWS_WITH(FisheyeCamera(turned), Contains("pitch_deg = inf is invalid"));
    // Kannala-Brandt fields are not read by the equidistant model.
    CameraParams equidistant{64, 64, 84.0};
    equidistant.fx_px = -1.0;
    equidistant.k1 = nan;
    CHECK_NOTHROW(FisheyeCamera(equidistant));
}

TEST_CASE("field_coverage is the share of a pixel inside the image circle", "[render][camera]") {
    // An equidistant camera (circle of radius 30 px about (40, 30)) and a Kannala-Brandt one
    // with fx != fy (an ellipse of semi-axes fx theta_d_max and fy theta_d_max), both inside
    // their images, so that the coverages add up to the ellipse's area.
    CameraParams kb = calibrated_camera();
    kb.fx_px = 20.0;
    kb.fy_px = 17.0;
    for (const CameraParams& params : {CameraParams{80, 60, 84.0}, kb}) {
        INFO("model " << int(params.model));
        const FisheyeCamera camera(params);
        const double a = camera.circle_radius_px();
        const double b = params.model == CameraModel::equidistant ? a : a * kb.fy_px / kb.fx_px;
        double total = 0.0;
        int edge = 0, checked = 0;
        for (int y = 0; y < params.height_px; ++y)
            for (int x = 0; x < params.width_px; ++x) {
                const double c = camera.field_coverage(x, y);
                REQUIRE(c >= 0.0);
                REQUIRE(c <= 1.0);
                total += c;
                // Every corner inside: exactly 1; no point of the square inside: exactly 0.
                const auto in = [&](double px, double py) {
                    return bool(camera.direction(Eigen::Vector2d(px, py)));
                };
                if (in(x, y) && in(x + 1, y) && in(x, y + 1) && in(x + 1, y + 1)) {
                    CHECK(c == 1.0);
                    continue;
                }
                if (c == 0.0 || c == 1.0) continue;
                // At the edge: against the share of a 200 x 200 grid's points the camera
                // images (round-off of that count: about one row of 200, 0.005).
                if (++edge % 5 != 0) continue;
                ++checked;
                int seen = 0;
                for (int j = 0; j < 200; ++j)
                    for (int i = 0; i < 200; ++i)
                        seen += in(x + (i + 0.5) / 200.0, y + (j + 0.5) / 200.0) ? 1 : 0;
                CHECK(c == Approx(seen / 40000.0).margin(3e-3));
            }
        CHECK(total == Approx(std::numbers::pi * a * b).epsilon(1e-12));
        CHECK(edge > 100);
        CHECK(checked > 20);
        // Off the image, far from the circle: none of it.
        CHECK(camera.field_coverage(-50, -50) == 0.0);
    }
}
