#include "io/image_io.h"

#include <OpenImageIO/imageio.h>

#include <cmath>
#include <filesystem>

#include "core/error.h"
#include "io/atomic_file.h"

namespace penumbra {
namespace {

void writeWith(const std::string& path, int w, int h, OIIO::TypeDesc type, const void* data) {
    const std::string tmp = temporarySibling(path);
    auto out = OIIO::ImageOutput::create(path);
    if (!out) throw Error(cat(path, ": cannot write images of this type (", OIIO::geterror(), ")"));
    OIIO::ImageSpec spec(w, h, 3, type);
    if (!out->open(tmp, spec) || !out->write_image(type, data) || !out->close()) {
        const std::string why = out->geterror();
        std::error_code ec;
        std::filesystem::remove(tmp, ec);
        throw Error(cat(path, ": cannot write image: ", why));
    }
    commitFile(tmp, path);
}

}  // namespace

void writeLinearImage(const Image& image, const std::string& path) {
    writeWith(path, image.width, image.height, OIIO::TypeDesc::FLOAT, image.rgb.data());
}

Image readLinearImage(const std::string& path) {
    auto in = OIIO::ImageInput::open(path);
    if (!in) throw Error(cat(path, ": cannot read image (", OIIO::geterror(), ")"));
    const OIIO::ImageSpec& spec = in->spec();
    Image image(spec.width, spec.height);
    std::vector<float> all(size_t(spec.width) * size_t(spec.height) * size_t(spec.nchannels));
    if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, all.data()))
        throw Error(cat(path, ": cannot read image: ", in->geterror()));
    for (size_t p = 0; p < size_t(spec.width) * size_t(spec.height); ++p)
        for (size_t c = 0; c < 3; ++c)
            image.rgb[3 * p + c] = all[p * size_t(spec.nchannels) + std::min<size_t>(c, size_t(spec.nchannels) - 1)];
    return image;
}

double exposureScale(const std::vector<double>& luminances, double stops) {
    double logSum = 0;
    size_t count = 0;
    for (double l : luminances)
        if (l > 0) logSum += std::log(l), ++count;
    const double key = count ? std::exp(logSum / double(count)) : 1;
    return 0.18 / key * std::pow(2.0, stops);
}

unsigned char srgb8(double linear) {
    const double v = std::clamp(linear, 0.0, 1.0);
    const double s = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
    return static_cast<unsigned char>(std::lround(255 * s));
}

void writePreviewPng(const Image& image, const std::string& path, double exposureStops) {
    std::vector<double> luminances;
    luminances.reserve(size_t(image.width) * size_t(image.height));
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x) luminances.push_back(luminance(image.at(x, y)));
    const double scale = exposureScale(luminances, exposureStops);
    std::vector<unsigned char> pixels(image.rgb.size());
    for (size_t k = 0; k < image.rgb.size(); ++k) pixels[k] = srgb8(double(image.rgb[k]) * scale);
    writeWith(path, image.width, image.height, OIIO::TypeDesc::UINT8, pixels.data());
}

void writeRgb8(const std::string& path, int width, int height, const std::vector<unsigned char>& rgb) {
    writeWith(path, width, height, OIIO::TypeDesc::UINT8, rgb.data());
}

std::string previewPathFor(const std::string& linearPath) {
    return std::filesystem::path(linearPath).replace_extension(".png").string();
}

}  // namespace penumbra
