// Images: linear radiance as EXR by OpenEXR, 8-bit previews as PNG by libpng, and every other
// format (.hdr, .tif, ...) through OpenImageIO, loaded as a module when first needed (oiio_module.h).
#pragma once

#include <string>
#include <vector>

#include "render/image.h"

namespace penumbra {

// Writes linear radiance to `path` (format from its extension: .exr or .hdr), atomically.
void writeLinearImage(const Image& image, const std::string& path);
// Reads a linear image (tests, and comparing renders).
Image readLinearImage(const std::string& path);

// Writes an 8-bit sRGB preview. exposureStops shifts the automatic exposure (which puts the
// log-average luminance at middle grey) by that many stops.
void writePreviewPng(const Image& image, const std::string& path, double exposureStops = 0);

// 8-bit RGB pixels (rows from the top) as the bytes of a PNG file (libpng), e.g. to embed in a glTF.
std::string pngBytes(int width, int height, const std::vector<unsigned char>& rgb);

// Writes 8-bit RGB pixels (rows from the top) as they are, e.g. a window's contents.
void writeRgb8(const std::string& path, int width, int height, const std::vector<unsigned char>& rgb);

// The preview's exposure: the factor that puts the log-average of the positive luminances at middle
// grey (0.18), shifted by `stops`.
double exposureScale(const std::vector<double>& luminances, double stops);
// A linear value in [0, 1] (clamped) encoded as 8-bit sRGB.
unsigned char srgb8(double linear);

// `IMAGE.exr` -> `IMAGE.png`.
std::string previewPathFor(const std::string& linearPath);

}  // namespace penumbra
