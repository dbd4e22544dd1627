// Textures: an image of linear RGB values laid over a surface by texture coordinates. Diffuse
// reflectance and emission may each take one, multiplying the material's factor (as glTF's
// baseColorFactor x baseColorTexture). The ray tracers read the texel under each hit (bilinear, with
// the file's wrap modes); the radiosity solve takes each patch's mean over its area (PatchSet::uv).
//
// Coordinates as glTF has them: (0, 0) is the image's top-left corner, u to the right, v down; one
// unit spans the image. Texel centres lie at ((x + 0.5) / width, (y + 0.5) / height).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/math.h"

namespace penumbra {

using Vec2 = Eigen::Vector2d;

enum class Wrap { Repeat, Clamp, Mirror };

class Texture {
public:
    // `rgb`: width x height x 3 linear values, rows from the top.
    Texture(std::string name, int width, int height, std::vector<float> rgb, Wrap wrapU = Wrap::Repeat,
            Wrap wrapV = Wrap::Repeat);

    const std::string& name() const { return name_; }
    int width() const { return width_; }
    int height() const { return height_; }
    Wrap wrapU() const { return wrapU_; }
    Wrap wrapV() const { return wrapV_; }

    // The bilinearly filtered value at `uv`.
    Rgb at(const Vec2& uv) const;
    // The mean over one period of the image (what a surface without coordinates takes).
    const Rgb& mean() const { return mean_; }
    // The largest value of any channel of any texel.
    double maximum() const { return maximum_; }
    Rgb texel(int x, int y) const;

private:
    std::string name_;
    int width_, height_;
    std::vector<float> rgb_;
    Wrap wrapU_, wrapV_;
    Rgb mean_ = Rgb::Zero();
    double maximum_ = 0;
};

// An 8- or 16-bit value's sRGB encoding in [0, 1] to linear (IEC 61966-2-1).
double srgbToLinear(double encoded);

// Reads an image file as a texture (OpenImageIO, through io's module): integer formats (PNG, JPEG,
// 8- or 16-bit TIFF) are taken as sRGB-encoded and decoded to linear, floating-point ones (EXR, HDR)
// as linear already. Throws Error naming the file on failure.
std::shared_ptr<const Texture> readTextureFile(const std::string& path, Wrap wrapU = Wrap::Repeat,
                                               Wrap wrapV = Wrap::Repeat);

}  // namespace penumbra
