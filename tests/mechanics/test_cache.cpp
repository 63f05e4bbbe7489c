// The on-disk cache of mesh and responses: hits reproduce the computed model exactly; torn or
// corrupt files are rejected and recomputed; any change of input changes the key.
#include "mechanics/dome_model.hpp"
#include "mechanics/model_cache.hpp"

#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <unistd.h>

namespace fs = std::filesystem;
using namespace chromasim::mechanics;

namespace {
int files_in(const fs::path& dir) {
    int n = 0;
    for (const auto& e : fs::directory_iterator(dir))
        n += e.path().extension() == ".bin";
    return n;
}
} // namespace

TEST_CASE("dome model cache: miss, hit with identical results, corrupt file rejected",
          "[mechanics][cache]") {
    const fs::path dir =
        fs::temp_directory_path() / ("chromasim_cache_test_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    DomeModelOptions options;
    options.cache_dir = dir;
    const ContactLoad load{1.5, {0.6, 0.2}, 0.8};
    const FrameRequest all{true, true, true};

    const DomeModel computed(options);
    CHECK(computed.stats().cache == "miss");
    REQUIRE(files_in(dir) == 1);
    const FrameResult a = computed.solve(load, all);

    const DomeModel loaded(options);
    CHECK(loaded.stats().cache == "hit");
    CHECK(loaded.stats().nodes == computed.stats().nodes);
    const FrameResult b = loaded.solve(load, all); // full field: factorizes on demand
    CHECK(b.contact.active == a.contact.active);
    CHECK(b.contact.forces_N == a.contact.forces_N);
    CHECK(b.coating_displacement_mm == a.coating_displacement_mm);
    CHECK(b.marker_points_mm == a.marker_points_mm);
    CHECK((b.node_displacement_mm - a.node_displacement_mm).cwiseAbs().maxCoeff() < 1e-12);

    // Flip one byte in the middle: the checksum catches it, the model is recomputed.
    const fs::path file = fs::directory_iterator(dir)->path();
    {
        std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
        f.seekp(std::streamoff(fs::file_size(file) / 2));
        f.put('\x5a');
    }
    const DomeModel recomputed(options);
    CHECK(recomputed.stats().cache == "rejected");
    CHECK(recomputed.stats().cache_note.find("checksum") != std::string::npos);
    CHECK(recomputed.solve(load, all).marker_points_mm == a.marker_points_mm);
    CHECK(DomeModel(options).stats().cache == "hit"); // rewritten

    // Another input, another entry.
    options.materials[1].E_MPa = 0.25;
    CHECK(DomeModel(options).stats().cache == "miss");
    CHECK(files_in(dir) == 2);
    fs::remove_all(dir);
}

TEST_CASE("cache files for another key or truncated are refused", "[mechanics][cache]") {
    const fs::path dir =
        fs::temp_directory_path() / ("chromasim_cache_unit_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    TetMesh mesh;
    mesh.V = Points::Random(5, 3);
    mesh.T = Tets::Zero(2, 4);
    mesh.region = Eigen::VectorXi::Ones(2);
    ElasticBodyResponses r{Eigen::MatrixXd::Random(6, 6), Eigen::MatrixXd::Random(9, 6)};
    REQUIRE(save_cached_model(dir, 42, mesh, r));
    std::string problem;
    const auto back = load_cached_model(dir, 42, &problem);
    REQUIRE(back);
    CHECK(back->mesh.V == mesh.V);
    CHECK(back->responses.observed == r.observed);
    fs::rename(cache_file(dir, 42), cache_file(dir, 43));
    CHECK_FALSE(load_cached_model(dir, 43, &problem));
    CHECK(problem.find("another key") != std::string::npos);
    fs::resize_file(cache_file(dir, 43), 30);
    CHECK_FALSE(load_cached_model(dir, 43, &problem));
    CHECK_FALSE(load_cached_model(dir, 44)); // absent: no file, no problem
    fs::remove_all(dir);
}
