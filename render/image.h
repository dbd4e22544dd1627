// A linear-radiance RGB image in memory, W sr^-1 m^-2 per channel, row-major from the top left.
#pragma once

#include <vector>

#include "core/math.h"

namespace penumbra {

struct Image {
    int width = 0, height = 0;
    std::vector<float> rgb;  // 3 floats per pixel
    Image() = default;
    Image(int w, int h) : width(w), height(h), rgb(size_t(w) * size_t(h) * 3, 0.0f) {}
    Rgb at(int x, int y) const {
        const size_t k = 3 * (size_t(y) * size_t(width) + size_t(x));
        return Rgb(rgb[k], rgb[k + 1], rgb[k + 2]);
    }
    void set(int x, int y, const Rgb& c) {
        const size_t k = 3 * (size_t(y) * size_t(width) + size_t(x));
        rgb[k] = float(c[0]), rgb[k + 1] = float(c[1]), rgb[k + 2] = float(c[2]);
    }
};

}  // namespace penumbra
