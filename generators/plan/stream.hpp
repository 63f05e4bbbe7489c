#pragma once
/// The plan's random streams: std::mt19937_64, whose output the standard fixes, turned into
/// doubles by hand (the std distributions differ between standard libraries), so a plan is the
/// same everywhere.
#include "generators/spec/spec.hpp"

#include <algorithm>
#include <cstdint>
#include <random>

namespace chromasim::generators {

class Stream {
public:
    explicit Stream(std::uint64_t seed) : m_engine(seed) {}
    /// Uniform in [0, 1), 53 random bits.
    double uniform() { return double(m_engine() >> 11) * 0x1.0p-53; }

private:
    std::mt19937_64 m_engine;
};

/// The index in [0, n) that a uniform u in [0, 1) falls on.
inline std::size_t pick(std::size_t n, double u) {
    return std::min(n - 1, std::size_t(u * double(n)));
}

/// The value of factor `f` that a uniform u in [0, 1) draws: a list's item, or a range's value.
inline double draw(const Factor& f, double u) {
    return f.is_range ? f.min + u * (f.max - f.min) : f.values[pick(f.values.size(), u)];
}

} // namespace chromasim::generators
