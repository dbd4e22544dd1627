// Reading image files' pixels: EXR by OpenEXR, PNG by libpng, every other format (.hdr, .tif,
// .jpg, ...) by OpenImageIO's module (core/oiio_module.h), loaded only then. Shared by the images the
// program compares (io/image_io.h) and the textures scenes name (mesh/texture.h).
#pragma once

#include <string>
#include <vector>

namespace penumbra {

struct ImagePixels {
    int width = 0, height = 0;
    std::vector<float> rgb;  // 3 values a pixel, rows from the top; a grey image's value repeated
    // Stored as integers (8 or 16 bits: PNG, JPEG, TIFF), their values scaled to [0, 1] as stored
    // (an encoding such as sRGB); else floating point (EXR, HDR), linear.
    bool integer = false;
};

// Throws Error naming the file and why it cannot be read.
ImagePixels readImagePixels(const std::string& path);

// A path's extension in lower case, with its dot (".exr"), or "".
std::string lowerExtension(const std::string& path);

}  // namespace penumbra
