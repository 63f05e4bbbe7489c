// The committed reference image (tests/data/reference_dome_path.exr, written by
// `chromasim verify render --write-reference FILE --reference-spp 4096`) against a fresh render
// with another seed: they must agree within their noise.
#include "generators/io/image_io.hpp"
#include "generators/validation/verify_render.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <string>

using namespace chromasim;
using namespace chromasim::generators;

TEST_CASE("the undeformed dome, path-traced afresh, matches the committed reference image "
          "within its noise",
          "[generators][render][path]") {
    const ImageF ref = read_image_float(std::filesystem::path(CHROMASIM_SOURCE_DIR) / "tests" /
                                        "data" / "reference_dome_path.exr");
    REQUIRE(ref.width == kReferenceDomeSize_px);
    REQUIRE(ref.height == kReferenceDomeSize_px);
    const render::Image img = render_reference_dome(192, 2);
    const char* channel[3] = {"R", "G", "B"};
    for (int c = 0; c < 3; ++c) {
        // Per channel over the image: the mean difference against its standard error, and the
        // RMS difference against the noise the two variance channels predict.
        double diff = 0, diff2 = 0, var_sum = 0, level = 0;
        int n = 0;
        for (int y = 0; y < img.height; ++y)
            for (int x = 0; x < img.width; ++x) {
                const std::size_t p = std::size_t(y) * img.width + x;
                const double r = ref.at(x, y, channel[c]);
                const double d = img.rgb[3 * p + c] - r;
                const double var =
                    img.variance[3 * p + c] + ref.at(x, y, std::string("variance.") + channel[c]);
                diff += d, diff2 += d * d, var_sum += var, level += r;
                ++n;
            }
        const double mean_diff = diff / n, rms = std::sqrt(diff2 / n),
                     predicted = std::sqrt(var_sum / n);
        INFO(channel[c] << ": mean level " << level / n << ", mean difference " << mean_diff
                        << " (standard error " << predicted / std::sqrt(n) << "), RMS difference "
                        << rms << " against " << predicted << " predicted");
        CHECK(std::abs(mean_diff) < 4.0 * predicted / std::sqrt(n));
        CHECK(rms == Approx(predicted).epsilon(0.3));
        // The comparison can see a 2 % shift of the image's mean.
        CHECK(4.0 * predicted / std::sqrt(n) < 0.02 * level / n);
    }
}
