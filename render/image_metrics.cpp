#include "render/image_metrics.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace penumbra {

Image boxBlur(const Image& image, int radius) {
    Image out(image.width, image.height);
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x) {
            Rgb sum = Rgb::Zero();
            int count = 0;
            for (int dy = -radius; dy <= radius; ++dy)
                for (int dx = -radius; dx <= radius; ++dx) {
                    const int xx = x + dx, yy = y + dy;
                    if (xx < 0 || yy < 0 || xx >= image.width || yy >= image.height) continue;
                    sum += image.at(xx, yy);
                    ++count;
                }
            out.set(x, y, sum / count);
        }
    return out;
}

ImageError compareImages(const Image& a, const Image& ref) {
    if (a.width != ref.width || a.height != ref.height)
        throw Error(cat("cannot compare images of ", a.width, "x", a.height, " and ", ref.width, "x", ref.height));
    ImageError e;
    const size_t n = ref.rgb.size();
    if (n == 0) return e;
    double refSum = 0, aSum = 0;
    for (size_t k = 0; k < n; ++k) {
        refSum += ref.rgb[k];
        aSum += a.rgb[k];
    }
    const double floor = 0.01 * refSum / double(n) + 1e-30;
    double rel = 0, sq = 0, l1 = 0;
    for (size_t k = 0; k < n; ++k) {
        const double d = double(a.rgb[k]) - double(ref.rgb[k]);
        rel += std::abs(d) / (std::max(0.0, double(ref.rgb[k])) + floor);
        l1 += std::abs(d);
        sq += d * d;
    }
    e.pooledL1 = refSum > 0 ? l1 / refSum : (l1 > 0 ? HUGE_VAL : 0);
    e.meanRelative = rel / double(n);
    e.rmse = std::sqrt(sq / double(n));
    e.meanRatio = refSum > 0 ? aSum / refSum : 0;
    return e;
}

ImageError compareBlurred(const Image& a, const Image& ref, int radius) {
    return compareImages(boxBlur(a, radius), boxBlur(ref, radius));
}

Rgb meanOver(const Image& image, int x0, int y0, int x1, int y1) {
    Rgb sum = Rgb::Zero();
    int count = 0;
    for (int y = std::max(0, y0); y < std::min(image.height, y1); ++y)
        for (int x = std::max(0, x0); x < std::min(image.width, x1); ++x) {
            sum += image.at(x, y);
            ++count;
        }
    return count ? Rgb(sum / count) : Rgb(Rgb::Zero());
}

}  // namespace penumbra
