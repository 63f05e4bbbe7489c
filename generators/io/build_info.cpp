#include "generators/io/build_info.hpp"

// Version headers only: none of these declares an API (the libraries stay behind their
// adapters: render/ for Embree, image_io.cpp for OpenImageIO, mechanics/ for TetGen).
#include <Eigen/Core>
#include <OpenEXR/OpenEXRConfig.h>
#include <OpenImageIO/oiioversion.h>
#include <embree3/rtcore_config.h>
#include <nlohmann/json.hpp>
#include <oneapi/tbb/version.h>
#include <openssl/opensslv.h>
#include <suitesparse/cholmod.h>

namespace chromasim::generators {

namespace {
#define CHROMASIM_STR2(x) #x
#define CHROMASIM_STR(x) CHROMASIM_STR2(x)
} // namespace

std::vector<std::pair<std::string, std::string>> dependency_versions() {
    return {
        {"embree", RTC_VERSION_STRING},
        {"openimageio", OIIO_VERSION_STRING},
        {"openexr", OPENEXR_VERSION_STRING},
        {"tetgen", ""}, // tetgen.h defines no version macro; Debian's libtet1.5-dev
        {"eigen", CHROMASIM_STR(EIGEN_WORLD_VERSION) "." CHROMASIM_STR(
                      EIGEN_MAJOR_VERSION) "." CHROMASIM_STR(EIGEN_MINOR_VERSION)},
        {"cholmod", CHROMASIM_STR(CHOLMOD_MAIN_VERSION) "." CHROMASIM_STR(
                        CHOLMOD_SUB_VERSION) "." CHROMASIM_STR(CHOLMOD_SUBSUB_VERSION)},
        {"yaml-cpp", CHROMASIM_YAML_CPP_VERSION}, // from its CMake package (no header macro)
        {"tbb", TBB_VERSION_STRING},
        {"tinygltf", CHROMASIM_TINYGLTF_VERSION}, // from its CMake package (no header macro)
        {"openssl", OPENSSL_FULL_VERSION_STR},
        {"nlohmann_json",
         CHROMASIM_STR(NLOHMANN_JSON_VERSION_MAJOR) "." CHROMASIM_STR(
             NLOHMANN_JSON_VERSION_MINOR) "." CHROMASIM_STR(NLOHMANN_JSON_VERSION_PATCH)},
    };
}

} // namespace chromasim::generators
