#pragma once
/// Wall-clock timing of the pipeline's stages (reported in stats and logs, never asserted).
#include <chrono>

namespace chromasim::generators {

/// Seconds elapsed since `t0`.
inline double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

} // namespace chromasim::generators
