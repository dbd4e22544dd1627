#include "core/image_file.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <png.h>

#include <algorithm>
#include <cctype>
#include <filesystem>

#include "core/error.h"
#include "core/oiio_module.h"
#include "core/parallel.h"

namespace penumbra {
namespace {

// Past this many pixels an image is refused before it is allocated (a header may claim anything).
constexpr double kMostPixels = double(1 << 28);

// False if the file has neither R, G and B nor Y channels (then OpenImageIO tries it).
bool readExr(const std::string& path, ImagePixels& image) {
    try {
        Imf::InputFile in(path.c_str(), std::max(1, threadCount()));
        const Imf::ChannelList& channels = in.header().channels();
        const bool rgb = channels.findChannel("R") && channels.findChannel("G") && channels.findChannel("B");
        if (!rgb && !channels.findChannel("Y")) return false;
        const Imath::Box2i window = in.header().dataWindow();
        const int w = window.max.x - window.min.x + 1, h = window.max.y - window.min.y + 1;
        if (w <= 0 || h <= 0 || double(w) * double(h) > kMostPixels)
            throw Error(cat(path, ": image of ", w, " x ", h, " pixels: at most 2^28 are read"));
        image.width = w, image.height = h;
        image.rgb.assign(size_t(w) * size_t(h) * 3, 0.0f);
        const size_t pixel = 3 * sizeof(float), row = pixel * size_t(w);
        // The slices' base is where pixel (0, 0) of the data window's origin would be.
        char* base = reinterpret_cast<char*>(image.rgb.data()) - ptrdiff_t(window.min.x) * ptrdiff_t(pixel) -
                     ptrdiff_t(window.min.y) * ptrdiff_t(row);
        Imf::FrameBuffer frame;  // one slice a channel name: a grey image's Y into R, then copied
        const char* names[3] = {"R", "G", "B"};
        for (int c = 0; c < (rgb ? 3 : 1); ++c)
            frame.insert(rgb ? names[c] : "Y", Imf::Slice(Imf::FLOAT, base + c * sizeof(float), pixel, row));
        in.setFrameBuffer(frame);
        in.readPixels(window.min.y, window.max.y);
        if (!rgb)
            for (size_t k = 0; k < image.rgb.size(); k += 3) image.rgb[k + 1] = image.rgb[k + 2] = image.rgb[k];
        return true;
    } catch (const std::exception& e) {
        throw Error(cat(path, ": cannot read image: ", e.what()));
    }
}

// 8-bit RGB by libpng's simplified reader (16-bit files reduced to 8 bits).
void readPng(const std::string& path, ImagePixels& image) {
    png_image png{};
    png.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&png, path.c_str()))
        throw Error(cat(path, ": cannot read image: ", png.message));
    png.format = PNG_FORMAT_RGB;
    if (double(png.width) * double(png.height) > kMostPixels) {
        png_image_free(&png);
        throw Error(cat(path, ": image of ", png.width, " x ", png.height, " pixels: at most 2^28 are read"));
    }
    std::vector<unsigned char> bytes(PNG_IMAGE_SIZE(png));
    if (!png_image_finish_read(&png, nullptr, bytes.data(), 0, nullptr)) {
        const std::string why = png.message;
        png_image_free(&png);
        throw Error(cat(path, ": cannot read image: ", why));
    }
    image.width = int(png.width), image.height = int(png.height);
    image.integer = true;
    image.rgb.resize(bytes.size());
    for (size_t k = 0; k < bytes.size(); ++k) image.rgb[k] = float(bytes[k]) / 255.0f;
}

}  // namespace

std::string lowerExtension(const std::string& path) {
    std::string e = std::filesystem::path(path).extension().string();
    std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return e;
}

ImagePixels readImagePixels(const std::string& path) {
    ImagePixels image;
    const std::string ext = lowerExtension(path);
    if (ext == ".exr" && readExr(path, image)) return image;
    if (ext == ".png") {
        readPng(path, image);
        return image;
    }
    const OiioModule& m = oiioModule();
    char why[512] = "";
    int w = 0, h = 0, isFloat = 0;
    if (m.read(path.c_str(), &w, &h, &isFloat, nullptr, why, sizeof why) != 0)
        throw Error(cat(path, ": cannot read image (", why, ")"));
    if (w <= 0 || h <= 0 || double(w) * double(h) > kMostPixels)
        throw Error(cat(path, ": image of ", w, " x ", h, " pixels: at most 2^28 are read"));
    image.width = w, image.height = h, image.integer = !isFloat;
    image.rgb.resize(size_t(w) * size_t(h) * 3);
    if (m.read(path.c_str(), &w, &h, &isFloat, image.rgb.data(), why, sizeof why) != 0)
        throw Error(cat(path, ": cannot read image: ", why));
    return image;
}

}  // namespace penumbra
