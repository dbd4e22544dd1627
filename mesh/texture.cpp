#include "mesh/texture.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "core/error.h"
#include "core/image_file.h"
#include "mesh/patches.h"

namespace penumbra {
namespace {

// Texel index along one axis under a wrap mode.
int wrapIndex(int i, int n, Wrap w) {
    switch (w) {
        case Wrap::Clamp:
            return std::clamp(i, 0, n - 1);
        case Wrap::Mirror: {
            const int period = 2 * n;
            int k = i % period;
            if (k < 0) k += period;
            return k < n ? k : period - 1 - k;
        }
        case Wrap::Repeat:
            break;
    }
    const int k = i % n;
    return k < 0 ? k + n : k;
}

// The mean of `texture` over patch i (its coordinates given).
Rgb patchMean(const Texture& texture, const PatchSet& p, size_t i) {
    Eigen::AlignedBox2d box;
    for (const Vec2& t : p.uv[i]) box.extend(t);
    const Vec2 extent = box.sizes();
    const int n =
        std::clamp(int(std::ceil(2 * std::max(extent.x() * texture.width(), extent.y() * texture.height()))), 1, 64);
    Rgb sum = Rgb::Zero();
    double weight = 0;
    for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b) {
            const double u = (a + 0.5) / n, v = (b + 0.5) / n, j = p.jacobian(i, u, v);
            sum += j * texture.at(p.uvAt(i, u, v));
            weight += j;
        }
    return weight > 0 ? Rgb(sum / weight) : texture.at(p.uv[i][0]);
}

}  // namespace

namespace {

// A diffuse material's factor (reflectance or emission) times its texture's mean over patch i.
Rgb meanOverPatch(const Scene& scene, const PatchSet& p, size_t i, Rgb Material::*factor,
                  std::shared_ptr<const Texture> Material::*texture) {
    const SceneObject& o = scene.objects[size_t(p.object[i])];
    const Material& m = scene.materialOf(o);
    if (m.type != MaterialType::Diffuse) return Rgb::Zero();
    const Texture* t = (m.*texture).get();
    if (!t) return m.*factor;
    return m.*factor * (p.hasUv() && o.hasUv() ? patchMean(*t, p, i) : t->mean());
}

}  // namespace

Rgb meanReflectance(const Scene& scene, const PatchSet& p, size_t i) {
    return meanOverPatch(scene, p, i, &Material::reflectance, &Material::reflectanceTexture);
}

Rgb meanEmission(const Scene& scene, const PatchSet& p, size_t i) {
    return meanOverPatch(scene, p, i, &Material::emission, &Material::emissionTexture);
}

Texture::Texture(std::string name, int width, int height, std::vector<float> rgb, Wrap wrapU, Wrap wrapV)
    : name_(std::move(name)), width_(width), height_(height), rgb_(std::move(rgb)), wrapU_(wrapU), wrapV_(wrapV) {
    PENUMBRA_CHECK(width_ > 0 && height_ > 0);
    PENUMBRA_CHECK_EQ(rgb_.size(), size_t(width_) * size_t(height_) * 3);
    Rgb sum = Rgb::Zero();
    for (size_t k = 0; k < rgb_.size(); k += 3) {
        sum += Rgb(rgb_[k], rgb_[k + 1], rgb_[k + 2]);
        maximum_ = std::max({maximum_, double(rgb_[k]), double(rgb_[k + 1]), double(rgb_[k + 2])});
    }
    mean_ = sum / double(size_t(width_) * size_t(height_));
}

Rgb Texture::texel(int x, int y) const {
    const size_t k =
        3 * (size_t(wrapIndex(y, height_, wrapV_)) * size_t(width_) + size_t(wrapIndex(x, width_, wrapU_)));
    return Rgb(rgb_[k], rgb_[k + 1], rgb_[k + 2]);
}

Rgb Texture::at(const Vec2& uv) const {
    // Texel centres at half-integers: the filter's footprint is the four around the point.
    const double x = uv.x() * width_ - 0.5, y = uv.y() * height_ - 0.5;
    if (!std::isfinite(x) || !std::isfinite(y)) return mean_;
    const double fx = std::floor(x), fy = std::floor(y);
    // Far coordinates (a repeat millions of times over) keep their place within one period.
    const auto place = [](double f, int n, Wrap w) {
        return w == Wrap::Clamp ? int(std::clamp(f, -1.0, double(n))) : int(std::fmod(f, 2.0 * n));
    };
    const int x0 = place(fx, width_, wrapU_), y0 = place(fy, height_, wrapV_);
    const double ax = x - fx, ay = y - fy;
    return (1 - ay) * ((1 - ax) * texel(x0, y0) + ax * texel(x0 + 1, y0)) +
           ay * ((1 - ax) * texel(x0, y0 + 1) + ax * texel(x0 + 1, y0 + 1));
}

double srgbToLinear(double encoded) {
    return encoded <= 0.04045 ? encoded / 12.92 : std::pow((encoded + 0.055) / 1.055, 2.4);
}

std::shared_ptr<const Texture> readTextureFile(const std::string& path, Wrap wrapU, Wrap wrapV) {
    // A folder, a device or a pipe (/dev/zero, a FIFO) would hang or exhaust the reader: refused first.
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        throw Error(cat(path, ": ", std::filesystem::exists(path, ec) ? "not a regular file" : "no such file",
                        " (a texture must be an image file)"));
    if (std::filesystem::file_size(path, ec) > (uintmax_t(1) << 30))
        throw Error(cat(path, ": texture file larger than 1 GiB"));
    ImagePixels image = readImagePixels(path);
    for (float& v : image.rgb) {
        if (!std::isfinite(v) || v < 0) throw Error(cat(path, ": texture holds a negative or non-finite value"));
        if (image.integer) v = float(srgbToLinear(std::min(double(v), 1.0)));
    }
    return std::make_shared<const Texture>(path, image.width, image.height, std::move(image.rgb), wrapU, wrapV);
}

}  // namespace penumbra
