#pragma once
/// Image files: the one door to OpenImageIO.
#include "render/scene_data.hpp"

#include <cstdint>
#include <filesystem>
#include <vector>

namespace chromasim::generators {

/// Writes a linear-RGB image as an 8-bit sRGB PNG (values clamped to [0, 1]).
/// Throws std::runtime_error naming the file on failure.
void write_png(const std::filesystem::path& path, const render::Image& linear_rgb);

/// An 8-bit image read back (for tests and tools): width x height x channels, row-major.
struct Image8 {
    int width = 0, height = 0, channels = 0;
    std::vector<std::uint8_t> data;
    std::uint8_t at(int x, int y, int c) const {
        return data[(std::size_t(y) * width + x) * channels + c];
    }
};
Image8 read_image8(const std::filesystem::path& path);

/// sRGB transfer function of a linear value in [0, 1].
double srgb_encode(double linear);

} // namespace chromasim::generators
