// Images through OpenImageIO: linear radiance as EXR (or HDR), and tone-mapped sRGB PNG previews.
#pragma once

#include <string>

#include "render/image.h"

namespace penumbra {

// Writes linear radiance to `path` (format from its extension: .exr or .hdr), atomically.
void writeLinearImage(const Image& image, const std::string& path);
// Reads a linear image (tests, and comparing renders).
Image readLinearImage(const std::string& path);

// Writes an 8-bit sRGB preview. exposureStops shifts the automatic exposure (which puts the
// log-average luminance at middle grey) by that many stops.
void writePreviewPng(const Image& image, const std::string& path, double exposureStops = 0);

// `IMAGE.exr` -> `IMAGE.png`.
std::string previewPathFor(const std::string& linearPath);

}  // namespace penumbra
