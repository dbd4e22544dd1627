// Image comparisons used by the tests, `penumbra compare` and the bench. The project's measure is
// the pooled L1 after a 5x5 box blur, sum |blur(a) - blur(ref)| / sum blur(ref) over all pixels and
// channels; beside it the mean per-pixel relative error (labelled as such) and the RMSE.
#pragma once

#include "render/image.h"

namespace penumbra {

// Box blur of (2 radius + 1)^2 pixels, clamped at the borders (the window shrinks there).
Image boxBlur(const Image& image, int radius);

struct ImageError {
    double pooledL1 = 0;      // sum over pixels and channels of |a - ref|, over the sum of ref
    double meanRelative = 0;  // per-pixel relative error: mean over pixels and channels of |a - ref| / (ref + floor)
    double rmse = 0;          // root mean square of a - ref, W sr^-1 m^-2
    double meanRatio = 0;     // sum(a) / sum(ref): the overall brightness ratio
};

// Compares `image` with `reference` (same size; Error otherwise). `floor` keeps black pixels from
// dominating the relative error: 1% of the reference's mean value.
ImageError compareImages(const Image& image, const Image& reference);

// The same after a box blur of both, radius 2 (5 x 5): the measure the issues state.
ImageError compareBlurred(const Image& image, const Image& reference, int radius = 2);

// Mean radiance per channel over the rectangle [x0, x1) x [y0, y1).
Rgb meanOver(const Image& image, int x0, int y0, int x1, int y1);

}  // namespace penumbra
