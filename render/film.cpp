#include "render/film.h"

#include <cmath>
#include <cstring>
#include <functional>
#include <optional>

#include "core/cluster.h"
#include "core/counters.h"
#include "core/error.h"
#include "core/log.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "core/rng.h"
#include "render/camera.h"
#include "solver/visibility.h"

namespace penumbra {
namespace {
const Counter g_cameraSamples("render.camera_samples", "camera rays (samples of pixels), all integrators");
const Counter g_edgePixels("render.edge_pixels",
                           "edge pixels sampled again with four times their samples (at least 64 at a lamp's edge)");

// A lamp's edge is told by its pixel's samples' spread: over eight times their mean (a wall's edge, a
// penumbra or glass's refractions spread less). A lamp fifty times brighter than the ceiling beside
// it leaves an edge pixel's mean off by about 50 / n^(3/2) of the ceiling with n^2 stratified
// samples, so such pixels take many more.
constexpr float kLampContrast = 8;

// The sum of a pixel's samples and the spread of their brightness.
struct PixelSum {
    Rgb sum = Rgb::Zero();
    double low = HUGE_VAL, high = -HUGE_VAL;
    void add(const Rgb& L) {
        sum += L;
        low = std::min(low, L.sum()), high = std::max(high, L.sum());
    }
};

// The largest spread over mean (contrast) of pixel (x, y) and its eight neighbours: a pixel whose
// samples differ by more than their mean, or beside one, is sampled again (a lamp may cover a
// twentieth of a pixel that none of its few samples found).
// Calls f(u, v) for pixel (x, y) and its neighbours within a w x h image.
template <typename F>
void forNeighbourhood(int w, int h, int x, int64_t y, const F& f) {
    for (int64_t v = std::max<int64_t>(0, y - 1); v <= std::min<int64_t>(h - 1, y + 1); ++v)
        for (int u = std::max(0, x - 1); u <= std::min(w - 1, x + 1); ++u) f(u, v);
}

float edgeContrast(const std::vector<float>& contrast, int w, int h, int x, int64_t y) {
    float most = 0;
    forNeighbourhood(w, h, x, y,
                     [&](int u, int64_t v) { most = std::max(most, contrast[size_t(v) * size_t(w) + size_t(u)]); });
    return most;
}

// The image is rendered in bands of kBand rows, handed out to the threads of every rank by a work
// queue (cluster::WorkQueue: under mpirun a rank on a faster or less busy host takes more bands),
// then the ranks exchange them.
constexpr int64_t kBand = 4;

int64_t bandsOf(int height) { return (height + kBand - 1) / kBand; }

// Calls rows(y0, y1) for the rows [y0, y1) of every band this rank takes; returns those bands.
std::vector<int64_t> renderBands(int height, Progress& progress, const std::function<void(int64_t, int64_t)>& rows) {
    return cluster::forEachQueued(
        bandsOf(height), [&](int64_t band) { rows(band * kBand, std::min<int64_t>(height, (band + 1) * kBand)); },
        [&](int64_t bands) { progress.update(bands); }, prepareTracingThread);
}

// Every rank's bands of `image` (and of the per-pixel `extra`, if not empty) on every rank; `mine`
// are the bands this rank rendered.
void shareBands(Image& image, std::vector<float>& extra, const std::vector<int64_t>& mine) {
    if (!cluster::distributed()) return;
    const size_t w = size_t(image.width);
    const auto rowsOf = [&](int64_t band) {
        return std::pair<size_t, size_t>(size_t(band * kBand),
                                         size_t(std::min<int64_t>(image.height, (band + 1) * kBand)));
    };
    cluster::Packer packed;
    packed.put(mine);
    for (int64_t band : mine) {
        const auto [y0, y1] = rowsOf(band);
        packed.put(std::vector<float>(image.rgb.begin() + long(3 * w * y0), image.rgb.begin() + long(3 * w * y1)));
        if (!extra.empty()) packed.put(std::vector<float>(extra.begin() + long(w * y0), extra.begin() + long(w * y1)));
    }
    const std::vector<std::string> all = cluster::allGather(packed.bytes);
    std::string shares;
    for (int r = 0; r < cluster::size(); ++r) {
        cluster::Unpacker from(all[size_t(r)]);
        std::vector<int64_t> bands;
        from.get(bands);
        shares += cat(r > 0 ? ", " : "", bands.size());
        if (r == cluster::rank()) continue;
        std::vector<float> values;
        for (int64_t band : bands) {
            PENUMBRA_CHECK(band >= 0 && band < bandsOf(image.height));
            const auto [y0, y1] = rowsOf(band);
            from.get(values);
            PENUMBRA_CHECK(values.size() == 3 * w * (y1 - y0));
            std::copy(values.begin(), values.end(), image.rgb.begin() + long(3 * w * y0));
            if (!extra.empty()) {
                from.get(values);
                PENUMBRA_CHECK(values.size() == w * (y1 - y0));
                std::copy(values.begin(), values.end(), extra.begin() + long(w * y0));
            }
        }
        PENUMBRA_CHECK(from.done());
    }
    logDebug("bands of ", kBand, " rows rendered per rank: ", shares, " (", all[size_t(cluster::rank())].size(),
             " bytes from this rank)");
}

}  // namespace

Image renderPixels(const Camera& camera, int samplesPerPixel, uint64_t seed, const char* title,
                   const RadianceFn& radiance) {
    const PinholeCamera cam(camera);
    Image image(camera.width, camera.height);
    const int side = stratumSide(samplesPerPixel);
    Progress progress(title, bandsOf(camera.height));
    const std::vector<int64_t> mine = renderBands(camera.height, progress, [&](int64_t y0, int64_t y1) {
        for (int64_t y = y0; y < y1; ++y) {
            for (int x = 0; x < camera.width; ++x) {
                Rng rng = pairRng(seed, Stream::Pixels, uint64_t(y), uint64_t(x));
                Rgb sum = Rgb::Zero();
                for (int s = 0; s < side * side; ++s) {
                    const double px = x + ((s % side) + rng.uniform()) / side;
                    const double py = double(y) + ((s / side) + rng.uniform()) / side;
                    sum += radiance(cam.origin(), cam.direction(px, py), rng);
                }
                image.set(x, int(y), sum / (side * side));
            }
            g_cameraSamples.add(uint64_t(camera.width) * uint64_t(side * side));
        }
    });
    progress.done();
    std::vector<float> none;
    shareBands(image, none, mine);
    return image;
}

namespace {
// Pixels share their sets, tile by tile: the index of a pixel's first sample is its Morton rank in
// its 64 x 64 tile times the samples per pixel rounded up to a power of two, so any aligned 2^k x
// 2^k block of pixels takes an aligned run of each set's indices (the index scramble permutes such
// runs as wholes: Owen's scramble of the ranks' tree, Ahmed and Wonka 2020). A block's samples
// together are then as well stratified as one pixel's, and neighbours' errors cancel where the image
// is smooth: what is left is blue noise, which a 5x5 blur (or an eye) removes. Each pixel's own
// samples are still an aligned run, a net, and each number still uniform.
constexpr int kTileBits = 6;

uint32_t mortonRank(uint32_t x, uint32_t y) {
    uint32_t rank = 0;
    for (int b = 0; b < kTileBits; ++b) rank |= ((x >> b) & 1u) << (2 * b) | ((y >> b) & 1u) << (2 * b + 1);
    return rank;
}

// Where the first pass's samples come from: the seed of pixel (x, y)'s sets and the index of its first
// sample; and where a sample lies.
struct FirstPass {
    FirstPass(uint64_t seed, int samples) : spp(samples), pixels(mixSeed(seed, uint64_t(Stream::Pixels))) {
        while (stride < uint32_t(spp)) stride *= 2;
    }
    uint64_t seedOf(int x, int64_t y) const {
        return mixSeed(pixels, uint64_t(y >> kTileBits), uint64_t(x >> kTileBits));
    }
    uint32_t first(int x, int64_t y) const { return mortonRank(uint32_t(x), uint32_t(y)) * stride; }
    // Starts sample s of pixel (x, y) and returns its image position (dimensions 0-1).
    Vec2 start(PixelSampler& sampler, int x, int64_t y, uint32_t index) const {
        sampler.start(index);
        const double px = x + sampler.uniform(), py = double(y) + sampler.uniform();
        return Vec2(px, py);
    }
    int spp;
    uint64_t pixels;
    uint32_t stride = 1;  // 2^12 ranks x at most 2^20 samples fit the sets' 32-bit indices
};

// A pixel's samples in one pass: `count` of the sets seeded `seed`, from index `first`.
struct PixelJob {
    int x;
    int64_t y;
    uint64_t seed;
    uint32_t first;
    int count;
};
}  // namespace

Image renderPixelsSampled(const Camera& camera, int samplesPerPixel, uint64_t seed, const char* title,
                          const SampledRadianceFn& radiance, bool edges, const BatchRadianceFn& batch) {
    const PinholeCamera cam(camera);
    const int w = camera.width, h = camera.height;
    Image image(w, h);
    const FirstPass pass(seed, std::max(1, samplesPerPixel));
    const int spp = pass.spp;
    // Each job's samples and their spread: ray by ray through `radiance`, or all of them at once
    // through `batch`.
    const auto take = [&](const std::vector<PixelJob>& jobs) {
        std::vector<PixelSum> sums(jobs.size());
        if (!batch) {
            for (size_t j = 0; j < jobs.size(); ++j) {
                const PixelJob& job = jobs[j];
                PixelSampler sampler(job.seed);
                for (int s = 0; s < job.count; ++s) {
                    const Vec2 at = pass.start(sampler, job.x, job.y, job.first + uint32_t(s));
                    sampler.skipTo(4);
                    sums[j].add(radiance(cam.origin(), cam.direction(at.x(), at.y()), sampler));
                }
            }
            return sums;
        }
        // In runs of whole jobs of about kBatch samples, so that many samples a pixel stay in bounds.
        constexpr size_t kBatch = 65536;
        std::vector<CameraSample> samples;
        std::vector<Rgb> L;
        std::optional<PixelSampler> sampler;  // kept while the jobs share their sets (a tile's pixels)
        for (size_t j0 = 0, j1; j0 < jobs.size(); j0 = j1) {
            samples.clear();
            for (j1 = j0; j1 < jobs.size() && (j1 == j0 || samples.size() + size_t(jobs[j1].count) <= kBatch); ++j1) {
                const PixelJob& job = jobs[j1];
                if (!sampler || job.seed != jobs[j1 - 1].seed) sampler.emplace(job.seed);
                for (int s = 0; s < job.count; ++s)
                    samples.push_back({job.x, job.y, pass.start(*sampler, job.x, job.y, job.first + uint32_t(s))});
            }
            L.assign(samples.size(), Rgb::Zero());
            batch(samples, L);
            size_t k = 0;
            for (size_t j = j0; j < j1; ++j)
                for (int s = 0; s < jobs[j].count; ++s) sums[j].add(L[k++]);
        }
        return sums;
    };
    std::vector<float> contrast(edges ? size_t(w) * size_t(h) : 0, 0.0f);
    const int64_t bands = bandsOf(h);
    Progress progress(title, edges ? 2 * bands : bands);
    std::vector<int64_t> mine = renderBands(h, progress, [&](int64_t y0, int64_t y1) {
        std::vector<PixelJob> jobs;
        for (int64_t y = y0; y < y1; ++y)
            for (int x = 0; x < w; ++x) jobs.push_back({x, y, pass.seedOf(x, y), pass.first(x, y), spp});
        const std::vector<PixelSum> sums = take(jobs);
        for (size_t j = 0; j < jobs.size(); ++j) {
            const PixelSum& p = sums[j];
            const size_t at = size_t(jobs[j].y) * size_t(w) + size_t(jobs[j].x);
            if (edges) contrast[at] = float((p.high - p.low) * spp / p.sum.sum());
            image.set(jobs[j].x, int(jobs[j].y), p.sum / spp);
        }
        g_cameraSamples.add(uint64_t(jobs.size()) * uint64_t(spp));
    });
    // The edge pass reads the neighbours' values and spreads, which other ranks may have made.
    shareBands(image, contrast, mine);
    if (edges && spp == 1) {
        // One sample has no spread: a pixel's contrast is then that of its and its eight neighbours'
        // values (a lamp's edge against the ceiling beside it).
        parallelFor(h, [&](int64_t y0, int64_t y1) {
            for (int64_t y = y0; y < y1; ++y)
                for (int x = 0; x < w; ++x) {
                    double low = HUGE_VAL, high = -HUGE_VAL, sum = 0;
                    int n = 0;
                    forNeighbourhood(w, h, x, y, [&](int u, int64_t v) {
                        const double b = image.at(u, int(v)).sum();
                        low = std::min(low, b), high = std::max(high, b), sum += b, ++n;
                    });
                    contrast[size_t(y) * size_t(w) + size_t(x)] = float((high - low) * n / sum);
                }
        });
    }
    if (edges) {
        // Edge pixels take four times their samples again (a lamp's edge at least 64: 128 cost
        // cornell-glass's view at one sample per pixel 1.6x the camera rays of 64 for 0.93% against
        // 0.93%, the Cornell box 0.79% against 0.80%), from sets of their own.
        const int again = 4 * int(pass.stride), lamp = std::max(again, 64);
        const uint64_t edgeSeed = mixSeed(seed, uint64_t(Stream::EdgePixels));
        mine = renderBands(h, progress, [&](int64_t y0, int64_t y1) {
            std::vector<PixelJob> jobs;
            uint64_t samples = 0;
            for (int64_t y = y0; y < y1; ++y)
                for (int x = 0; x < w; ++x) {
                    // One sample a pixel: its contrast is already its neighbourhood's (above), and
                    // says whether it is an edge; whether a lamp's, its neighbours' say too.
                    const float most = edgeContrast(contrast, w, h, x, y);
                    if (!((spp == 1 ? contrast[size_t(y) * size_t(w) + size_t(x)] : most) > 1)) continue;
                    const int more = most > kLampContrast ? lamp : again;
                    jobs.push_back({x, y, mixSeed(edgeSeed, uint64_t(y), uint64_t(x)), 0, more});
                    samples += uint64_t(more);
                }
            const std::vector<PixelSum> sums = take(jobs);
            for (size_t j = 0; j < jobs.size(); ++j) {
                const int x = jobs[j].x, y = int(jobs[j].y);
                image.set(x, y, (image.at(x, y) * spp + sums[j].sum) / (spp + jobs[j].count));
            }
            g_cameraSamples.add(samples);
            g_edgePixels.add(jobs.size());
        });
        std::vector<float> none;
        shareBands(image, none, mine);
    }
    progress.done();
    return image;
}

}  // namespace penumbra
