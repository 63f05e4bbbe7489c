#pragma once
/// Wall-clock timing of precompute stages (reported in stats, never asserted in tests).
#include <chrono>

namespace chromasim::mechanics {

/// Seconds elapsed since `t0`.
inline double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

} // namespace chromasim::mechanics
