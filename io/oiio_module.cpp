#include "core/oiio_module.h"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

namespace {
int fail(char* error, size_t size, const std::string& why) {
    if (size > 0) std::snprintf(error, size, "%s", why.c_str());
    return -1;
}
}  // namespace

extern "C" int penumbra_oiio_write(const char* path, int width, int height, int isFloat, const void* pixels,
                                   char* error, size_t errorSize) {
    const OIIO::TypeDesc type = isFloat ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8;
    auto out = OIIO::ImageOutput::create(path);
    if (!out) return fail(error, errorSize, "no writer for this type (" + OIIO::geterror() + ")");
    const OIIO::ImageSpec spec(width, height, 3, type);
    if (!out->open(path, spec) || !out->write_image(type, pixels) || !out->close())
        return fail(error, errorSize, out->geterror());
    return 0;
}

extern "C" int penumbra_oiio_read(const char* path, int* width, int* height, int* isFloat, float* rgb, char* error,
                                  size_t errorSize) {
    auto in = OIIO::ImageInput::open(path);
    if (!in) return fail(error, errorSize, OIIO::geterror());
    const OIIO::ImageSpec& spec = in->spec();
    *width = spec.width, *height = spec.height;
    if (isFloat) *isFloat = spec.format.is_floating_point() ? 1 : 0;
    if (!rgb) return 0;
    const size_t pixels = size_t(spec.width) * size_t(spec.height), channels = size_t(spec.nchannels);
    std::vector<float> all(pixels * channels);
    if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, all.data()))
        return fail(error, errorSize, in->geterror());
    for (size_t p = 0; p < pixels; ++p)
        for (size_t c = 0; c < 3; ++c) rgb[3 * p + c] = all[p * channels + std::min(c, channels - 1)];
    return 0;
}
