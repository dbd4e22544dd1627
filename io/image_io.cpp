#include "io/image_io.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <png.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>

#include "core/error.h"
#include "core/image_file.h"
#include "core/oiio_module.h"
#include "core/parallel.h"
#include "io/atomic_file.h"
#include "io/output_set.h"

namespace penumbra {
namespace {

// Writes through `write(temporary)`, then renames into place; a failed write leaves nothing.
template <typename Write>
void writeAtomically(const std::string& path, Write&& write) {
    faultPoint(path);
    const std::string tmp = temporarySibling(path);
    try {
        write(tmp);
    } catch (const std::exception& e) {
        std::error_code ec;
        std::filesystem::remove(tmp, ec);
        throw Error(cat(path, ": cannot write image: ", e.what()));
    }
    commitFile(tmp, path);
}

void writeWithOiio(const std::string& path, int w, int h, bool isFloat, const void* data) {
    const OiioModule& m = oiioModule();
    writeAtomically(path, [&](const std::string& tmp) {
        char why[512] = "";
        if (m.write(tmp.c_str(), w, h, isFloat ? 1 : 0, data, why, sizeof why) != 0) throw Error(why);
    });
}

// OpenEXR's output through stdio, every write checked, and the close too: its own std::ofstream
// stream drops the error of the last buffer's flush, which it makes when it closes (a full disk left a
// 0-byte EXR and a zero exit).
class CheckedFile : public Imf::OStream {
public:
    explicit CheckedFile(const std::string& path) : Imf::OStream(path.c_str()), file_(std::fopen(path.c_str(), "wb")) {
        if (!file_) throw Error(cat("cannot create ", path, ": ", std::strerror(errno)));
    }
    ~CheckedFile() override {
        if (file_) std::fclose(file_);
    }
    void write(const char c[], int n) override {
        if (std::fwrite(c, 1, size_t(n), file_) != size_t(n)) fail();
    }
    uint64_t tellp() override { return uint64_t(std::ftell(file_)); }
    void seekp(uint64_t pos) override {
        if (std::fseek(file_, long(pos), SEEK_SET) != 0) fail();
    }
    // Flushes and closes the file; throws if the data did not all reach it.
    void close() {
        FILE* f = file_;
        file_ = nullptr;
        const bool flushed = std::fflush(f) == 0 && !std::ferror(f);
        const int error = errno;
        if (std::fclose(f) != 0 || !flushed) throw Error(cat(fileName(), ": ", std::strerror(flushed ? errno : error)));
    }

private:
    [[noreturn]] void fail() { throw Error(cat(fileName(), ": ", std::strerror(errno))); }
    FILE* file_;
};

// Linear RGB as 32-bit float EXR, uncompressed: ZIP (what OpenImageIO wrote) took 0.07-0.08 s of
// OpenEXR's two threads for a 512 x 512 picture, at any zlib level, to save 10% of its 3.1 MB (the
// low bits of float radiance are noise to zlib); OpenEXR writes it plain in 0.004 s.
void writeExr(const std::string& path, const Image& image) {
    writeAtomically(path, [&](const std::string& tmp) {
        Imf::Header header(image.width, image.height);
        header.compression() = Imf::NO_COMPRESSION;
        Imf::FrameBuffer frame;
        const char* names[3] = {"R", "G", "B"};
        const size_t pixel = 3 * sizeof(float), row = pixel * size_t(image.width);
        for (int c = 0; c < 3; ++c) {
            header.channels().insert(names[c], Imf::Channel(Imf::FLOAT));
            frame.insert(
                names[c],
                Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(const_cast<float*>(image.rgb.data() + c)), pixel, row));
        }
        CheckedFile file(tmp);
        {
            Imf::OutputFile out(file, header, std::max(1, threadCount()));
            out.setFrameBuffer(frame);
            out.writePixels(image.height);
        }  // the line offsets written
        file.close();
    });
}

// An EXR's R, G and B (or its Y, as grey); false if it has neither, for OpenImageIO to read.

// 8-bit RGB as PNG by libpng, at its fast setting (the previews are for looking at).
void writePng(const std::string& path, int w, int h, const unsigned char* rgb) {
    writeAtomically(path, [&](const std::string& tmp) {
        std::unique_ptr<FILE, int (*)(FILE*)> file(std::fopen(tmp.c_str(), "wb"), std::fclose);
        if (!file) throw Error(cat("cannot create ", tmp));
        png_image png{};
        png.version = PNG_IMAGE_VERSION;
        png.width = png_uint_32(w), png.height = png_uint_32(h);
        png.format = PNG_FORMAT_RGB;
        png.flags = PNG_IMAGE_FLAG_FAST;
        if (!png_image_write_to_stdio(&png, file.get(), 0, rgb, 0, nullptr)) {
            const std::string why = png.message;
            png_image_free(&png);
            throw Error(why);
        }
        if (std::fflush(file.get()) != 0 || std::ferror(file.get())) throw Error("write failed");
        if (std::fclose(file.release()) != 0) throw Error("write failed");
    });
}

}  // namespace

void writeLinearImage(const Image& image, const std::string& path) {
    if (lowerExtension(path) == ".exr")
        writeExr(path, image);
    else
        writeWithOiio(path, image.width, image.height, true, image.rgb.data());
}

Image readLinearImage(const std::string& path) {
    ImagePixels pixels = readImagePixels(path);
    Image image;
    image.width = pixels.width, image.height = pixels.height;
    image.rgb = std::move(pixels.rgb);
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
    writeRgb8(path, image.width, image.height, pixels);
}

std::string pngBytes(int width, int height, const std::vector<unsigned char>& rgb) {
    PENUMBRA_CHECK_EQ(rgb.size(), size_t(width) * size_t(height) * 3);
    png_image png{};
    png.version = PNG_IMAGE_VERSION;
    png.width = png_uint_32(width), png.height = png_uint_32(height);
    png.format = PNG_FORMAT_RGB;
    png_alloc_size_t size = 0;
    if (!png_image_write_to_memory(&png, nullptr, &size, 0, rgb.data(), 0, nullptr))
        throw Error(cat("PNG encoding: ", png.message));
    std::string bytes(size, '\0');
    if (!png_image_write_to_memory(&png, bytes.data(), &size, 0, rgb.data(), 0, nullptr))
        throw Error(cat("PNG encoding: ", png.message));
    bytes.resize(size);
    return bytes;
}

void writeRgb8(const std::string& path, int width, int height, const std::vector<unsigned char>& rgb) {
    if (lowerExtension(path) == ".png")
        writePng(path, width, height, rgb.data());
    else
        writeWithOiio(path, width, height, false, rgb.data());
}

std::string previewPathFor(const std::string& linearPath) {
    return std::filesystem::path(linearPath).replace_extension(".png").string();
}

}  // namespace penumbra
