#pragma once
/// What built this chromasim: its version and the versions of the libraries it was compiled
/// against, as their headers state them (a dataset's manifest.json records them).
#include <string>
#include <utility>
#include <vector>

namespace chromasim::generators {

/// (library, version) in a fixed order; the version is empty where the library's headers and
/// its CMake package state none (TetGen 1.5).
std::vector<std::pair<std::string, std::string>> dependency_versions();

} // namespace chromasim::generators
