#include "generators/io/image_io.hpp"

#include "generators/io/file_io.hpp"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace chromasim::generators {

namespace {

/// The PNGs' zlib level (0 to 9).
constexpr int kPngCompressionLevel = 1;

/// "name.tmp.ext" beside `path`: OpenImageIO picks the format from the extension.
std::filesystem::path temporary_name(const std::filesystem::path& path) {
    return path.parent_path() / (path.stem().string() + ".tmp" + path.extension().string());
}

/// Calls write(tmp) and renames tmp to `path`: an image is complete or absent.
template <class Write> void write_then_rename(const std::filesystem::path& path, Write write) {
    const std::filesystem::path tmp = temporary_name(path);
    try {
        write(tmp);
    } catch (...) {
        std::error_code ec;
        std::filesystem::remove(tmp, ec);
        throw;
    }
    rename_path(tmp, path);
}

} // namespace

double srgb_encode(double x) {
    x = std::clamp(x, 0.0, 1.0);
    return x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1.0 / 2.4) - 0.055;
}

Image8 to_srgb8(const render::Image& image) {
    Image8 png{image.width, image.height, 3, std::vector<std::uint8_t>(image.rgb.size())};
    for (std::size_t i = 0; i < png.data.size(); ++i)
        png.data[i] = std::uint8_t(std::lround(255.0 * srgb_encode(image.rgb[i])));
    return png;
}

void write_png(const std::filesystem::path& final_path, const render::Image& image) {
    write_png8(final_path, to_srgb8(image));
}

void write_png8(const std::filesystem::path& final_path, const Image8& image) {
    write_then_rename(final_path, [&](const std::filesystem::path& path) {
        auto out = OIIO::ImageOutput::create(path.string());
        if (!out)
            throw std::runtime_error("cannot create image writer for " + path.string() + ": " +
                                     OIIO::geterror());
        OIIO::ImageSpec spec(image.width, image.height, image.channels, OIIO::TypeDesc::UINT8);
        spec.attribute("oiio:ColorSpace", "sRGB");
        spec.attribute("Software", "chromasim " CHROMASIM_VERSION);
        // zlib's fastest level: a 224 px image writes about 4 times faster than at the
        // default level 6, for files about a tenth larger (the same pixels).
        spec.attribute("png:compressionLevel", kPngCompressionLevel);
        if (!out->open(path.string(), spec) ||
            !out->write_image(OIIO::TypeDesc::UINT8, image.data.data()) || !out->close())
            throw std::runtime_error("cannot write " + path.string() + ": " + out->geterror());
    });
}

void write_exr(const std::filesystem::path& final_path, const render::Image& image) {
    write_then_rename(final_path, [&](const std::filesystem::path& path) {
        const std::size_t pixels = std::size_t(image.width) * image.height;
        std::vector<std::string> names{"R", "G", "B"};
        const bool variance = !image.variance.empty(), ids = !image.inner_marker_id.empty();
        if (variance) names.insert(names.end(), {"variance.R", "variance.G", "variance.B"});
        if (ids) names.insert(names.end(), {"inner_marker_id", "outer_marker_id"});
        const std::size_t nc = names.size();
        std::vector<float> data(pixels * nc);
        for (std::size_t p = 0; p < pixels; ++p) {
            float* out = data.data() + p * nc;
            std::size_t c = 0;
            for (int k = 0; k < 3; ++k)
                out[c++] = image.rgb[3 * p + std::size_t(k)];
            if (variance)
                for (int k = 0; k < 3; ++k)
                    out[c++] = image.variance[3 * p + std::size_t(k)];
            if (ids) {
                out[c++] = float(image.inner_marker_id[p]);
                out[c++] = float(image.outer_marker_id[p]);
            }
        }
        auto out = OIIO::ImageOutput::create(path.string());
        if (!out)
            throw std::runtime_error("cannot create image writer for " + path.string() + ": " +
                                     OIIO::geterror());
        OIIO::ImageSpec spec(image.width, image.height, int(nc), OIIO::TypeDesc::FLOAT);
        spec.channelnames = names;
        spec.attribute("oiio:ColorSpace", "Linear");
        spec.attribute("compression", "zip");
        spec.attribute("Software", "chromasim " CHROMASIM_VERSION);
        // OpenImageIO stamps EXRs with the wall clock unless DateTime is set; empty leaves it
        // out, so that the same spec gives the same bytes (manifest.json's checksums).
        spec.attribute("DateTime", "");
        if (image.image_per_radiance > 0.0)
            spec.attribute("chromasim:image_per_radiance", float(image.image_per_radiance));
        if (!out->open(path.string(), spec) ||
            !out->write_image(OIIO::TypeDesc::FLOAT, data.data()) || !out->close())
            throw std::runtime_error("cannot write " + path.string() + ": " + out->geterror());
    });
}

float ImageF::at(int x, int y, const std::string& channel) const {
    for (std::size_t c = 0; c < channels.size(); ++c)
        if (channels[c] == channel)
            return data[(std::size_t(y) * std::size_t(width) + std::size_t(x)) * channels.size() +
                        c];
    throw std::out_of_range("no channel " + channel);
}

ImageF read_image_float(const std::filesystem::path& path) {
    auto in = OIIO::ImageInput::open(path.string());
    if (!in)
        throw std::runtime_error("cannot open image " + path.string() + ": " + OIIO::geterror());
    const OIIO::ImageSpec& spec = in->spec();
    ImageF img{spec.width, spec.height, {}, {}};
    img.image_per_radiance = spec.get_float_attribute("chromasim:image_per_radiance", 0.0f);
    for (const auto& name : spec.channelnames)
        img.channels.push_back(name);
    img.data.resize(std::size_t(img.width) * img.height * img.channels.size());
    if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, img.data.data()))
        throw std::runtime_error("cannot read " + path.string() + ": " + in->geterror());
    in->close();
    return img;
}

Image8 read_image8(const std::filesystem::path& path) {
    auto in = OIIO::ImageInput::open(path.string());
    if (!in)
        throw std::runtime_error("cannot open image " + path.string() + ": " + OIIO::geterror());
    const OIIO::ImageSpec& spec = in->spec();
    Image8 img{spec.width, spec.height, spec.nchannels, {}};
    img.data.resize(std::size_t(img.width) * img.height * img.channels);
    if (!in->read_image(0, 0, 0, img.channels, OIIO::TypeDesc::UINT8, img.data.data()))
        throw std::runtime_error("cannot read " + path.string() + ": " + in->geterror());
    in->close();
    return img;
}

} // namespace chromasim::generators
