#pragma once
/// Image files: the one door to OpenImageIO.
#include "render/scene_data.hpp"

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace chromasim::generators {

/// Writes a linear-RGB image as an 8-bit sRGB PNG (values clamped to [0, 1]).
/// Written as "<stem>.tmp.png" and renamed: complete or absent. Throws std::runtime_error naming
/// the file on failure.
void write_png(const std::filesystem::path& path, const render::Image& linear_rgb);

/// Writes a linear-RGB image as a float OpenEXR file (ZIP compressed) with channels R, G, B, then
/// the extra channels the image holds: variance.R, variance.G, variance.B (variance of the
/// mean), inner_marker_id and outer_marker_id (float, -1 where none; exact as integers).
/// Written as "<stem>.tmp.exr" and renamed. Throws std::runtime_error naming the file on failure.
void write_exr(const std::filesystem::path& path, const render::Image& image);

/// A float image read back (for tests and tools): channel names and interleaved values.
struct ImageF {
    int width = 0, height = 0;
    std::vector<std::string> channels;
    std::vector<float> data;
    double image_per_radiance = 0.0; ///< the header's chromasim:image_per_radiance (0: none)
    /// Value of the named channel at (x, y); throws std::out_of_range if there is none.
    float at(int x, int y, const std::string& channel) const;
};
ImageF read_image_float(const std::filesystem::path& path);

/// An 8-bit image read back (for tests and tools): width x height x channels, row-major.
struct Image8 {
    int width = 0, height = 0, channels = 0;
    std::vector<std::uint8_t> data;
    std::uint8_t at(int x, int y, int c) const {
        return data[(std::size_t(y) * width + x) * channels + c];
    }
};
Image8 read_image8(const std::filesystem::path& path);
/// A linear-RGB image as the 8-bit sRGB values write_png stores.
Image8 to_srgb8(const render::Image& linear_rgb);
/// Writes 8-bit sRGB data as a PNG, complete or absent (as write_png).
void write_png8(const std::filesystem::path& path, const Image8& image);

/// sRGB transfer function of a linear value in [0, 1].
double srgb_encode(double linear);

} // namespace chromasim::generators
