#include "generators/image_io.hpp"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace chromasim::generators {

double srgb_encode(double x) {
    x = std::clamp(x, 0.0, 1.0);
    return x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1.0 / 2.4) - 0.055;
}

void write_png(const std::filesystem::path& path, const render::Image& image) {
    std::vector<std::uint8_t> bytes(image.rgb.size());
    for (std::size_t i = 0; i < bytes.size(); ++i)
        bytes[i] = std::uint8_t(std::lround(255.0 * srgb_encode(image.rgb[i])));
    auto out = OIIO::ImageOutput::create(path.string());
    if (!out)
        throw std::runtime_error("cannot create image writer for " + path.string() + ": " +
                                 OIIO::geterror());
    OIIO::ImageSpec spec(image.width, image.height, 3, OIIO::TypeDesc::UINT8);
    spec.attribute("oiio:ColorSpace", "sRGB");
    spec.attribute("Software", "chromasim " CHROMASIM_VERSION);
    if (!out->open(path.string(), spec) || !out->write_image(OIIO::TypeDesc::UINT8, bytes.data()) ||
        !out->close())
        throw std::runtime_error("cannot write " + path.string() + ": " + out->geterror());
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
