// The C interface of penumbra_oiio, the module that holds OpenImageIO. OpenImageIO as Debian builds
// it loads 261 shared libraries (OpenCV, FFmpeg, GDAL, DCMTK, ...) whose relocation took 0.35-0.40 s
// at every start of the program, more than the Cornell box's whole solve; so it is loaded only when
// an image neither OpenEXR nor libpng handles is read or written (io/image_io.cpp), or a texture
// (mesh/texture.cpp). The module is built from io/oiio_module.cpp; the loader is here, in core, so
// that both layers reach it.
#pragma once

#include <cstddef>

extern "C" {
// Writes `channels` (3) interleaved channels of `float` (isFloat) or 8-bit values. Returns 0, or -1
// with the reason in `error`.
int penumbra_oiio_write(const char* path, int width, int height, int isFloat, const void* pixels, char* error,
                        size_t errorSize);
// Reads an image's size (then call again with `rgb` of width * height * 3 floats to read its first
// three channels, a grey one repeated), and whether its values are stored as floating point (linear)
// rather than integers (an encoding such as sRGB). Returns 0, or -1 with the reason in `error`.
int penumbra_oiio_read(const char* path, int* width, int* height, int* isFloat, float* rgb, char* error,
                       size_t errorSize);
}

namespace penumbra {

// The module's entry points, loaded at the first call: from $PENUMBRA_OIIO_MODULE, else where the
// build put it, else beside the executable. Throws Error if it cannot be loaded.
struct OiioModule {
    decltype(&penumbra_oiio_write) write = nullptr;
    decltype(&penumbra_oiio_read) read = nullptr;
};
const OiioModule& oiioModule();

}  // namespace penumbra
