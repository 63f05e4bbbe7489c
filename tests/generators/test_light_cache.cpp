// The fast integrator's light cache on disk (generators/pipeline/light_cache_store.hpp): read back
// with the same image bytes, keyed by the optics, and refused when damaged.
#include "generators/pipeline/light_cache_store.hpp"
#include "render/renderer.hpp"
#include "tests/render/test_meshes.hpp"

#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <unistd.h>
#include <vector>

using namespace chromasim::render;
using namespace chromasim::render::test;
using chromasim::generators::LightCacheOutcome;
using chromasim::generators::provide_light_cache;

// The next renderer reads the saved cache back; a corrupt, truncated or foreign file is
// refused and rebuilt.
TEST_CASE("fast integrator: a light cache saved to disk renders the same bytes and a bad one is "
          "rebuilt",
          "[render][fast][cache]") {
    namespace fs = std::filesystem;
    const fs::path dir =
        fs::temp_directory_path() / ("chromasim_light_cache_test_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    const SensorFrame frame = clear_dome(16, 64, 24, 96);
    LightCacheSettings cache;
    cache.paths_per_vertex = 8;
    cache.direct_samples = 4;
    RenderSettings settings;
    settings.integrator = Integrator::fast;
    settings.samples_per_pixel = 2;
    auto render_with = [&](const OpticsParams& optics, LightCacheOutcome* report) {
        Renderer renderer(CameraParams{24, 24, 84.0}, optics);
        // A pressed frame: its image needs the cache and the per-frame correction together.
        renderer.set_frame(pressed_flat(frame));
        *report = provide_light_cache(renderer, frame, optics, cache, dir);
        return renderer.render(settings).rgb;
    };
    LightCacheOutcome first, second, third;
    const std::vector<float> built = render_with(OpticsParams{}, &first);
    CHECK_FALSE(first.from_file);
    CHECK(first.note.empty());
    std::vector<fs::path> files;
    for (const auto& entry : fs::directory_iterator(dir))
        files.push_back(entry.path());
    REQUIRE(files.size() == 1); // no temporary left behind
    CHECK(files[0].filename().string().rfind("light-", 0) == 0);
    CHECK(render_with(OpticsParams{}, &second) == built);
    CHECK(second.from_file);

    // Another refractive index is another key: a miss, and a second file.
    OpticsParams other;
    other.refractive_index = 1.45;
    render_with(other, &third);
    CHECK_FALSE(third.from_file);
    CHECK(std::distance(fs::directory_iterator(dir), fs::directory_iterator{}) == 2);

    // One flipped byte in the payload: refused by the checksum, rebuilt with the same image,
    // and the rebuilt file is good again.
    const fs::path file = files[0];
    std::string bytes;
    {
        std::ifstream in(file, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    REQUIRE(bytes.size() > 100);
    std::string damaged = bytes;
    damaged[bytes.size() / 2] ^= 0x5A;
    std::ofstream(file, std::ios::binary | std::ios::trunc) << damaged;
    LightCacheOutcome corrupt;
    CHECK(render_with(OpticsParams{}, &corrupt) == built);
    CHECK_FALSE(corrupt.from_file);
    CHECK_THAT(corrupt.note, Catch::Contains("checksum"));
    LightCacheOutcome again;
    render_with(OpticsParams{}, &again);
    CHECK(again.from_file);

    // Truncated, and a file of another key under this key's name.
    std::ofstream(file, std::ios::binary | std::ios::trunc) << bytes.substr(0, bytes.size() / 3);
    LightCacheOutcome truncated;
    CHECK(render_with(OpticsParams{}, &truncated) == built);
    CHECK_FALSE(truncated.from_file);
    CHECK_THAT(truncated.note, Catch::Contains("checksum"));
    std::string foreign = bytes;
    foreign[8] ^= 0x01; // the stored key
    std::ofstream(file, std::ios::binary | std::ios::trunc) << foreign;
    LightCacheOutcome wrong_key;
    render_with(OpticsParams{}, &wrong_key);
    CHECK_FALSE(wrong_key.from_file);
    CHECK_THAT(wrong_key.note, Catch::Contains("another key"));

    // A cache of the other mode (RGB lanes into a spectral renderer) is refused, not read.
    OpticsParams spectral;
    spectral.spectra = load_sensor_spectra(SensorSpectraFiles::in_directory(
        std::filesystem::path(CHROMASIM_SOURCE_DIR) / "assets" / "spectra"));
    Renderer rgb_renderer(CameraParams{24, 24, 84.0}, OpticsParams{});
    rgb_renderer.set_light_cache(frame, cache);
    Renderer spectral_renderer(CameraParams{24, 24, 84.0}, spectral);
    CHECK_THROWS_WITH(spectral_renderer.set_light_cache(*rgb_renderer.light_cache(), cache, frame),
                      Catch::Contains("16 lanes") && Catch::Contains("allowed:"));
    // So is the sensor at rest with another coating (the frame's solves start from its
    // connections), and the cache in use stays.
    Renderer other_rest(CameraParams{24, 24, 84.0}, OpticsParams{});
    other_rest.set_light_cache(frame, cache);
    other_rest.set_frame(frame);
    const std::vector<float> before = other_rest.render(settings).rgb;
    CHECK_THROWS_WITH(
        other_rest.set_light_cache(*rgb_renderer.light_cache(), cache, clear_dome(12, 48, 24, 96)),
        Catch::Contains("vertices") && Catch::Contains("allowed:"));
    CHECK(other_rest.render(settings).rgb == before);
    fs::remove_all(dir);
}
