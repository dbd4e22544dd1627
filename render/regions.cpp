#include "render/regions.h"

#include <map>

#include "core/error.h"
#include "core/parallel.h"
#include "render/camera.h"
#include "render/image_metrics.h"

namespace penumbra {

void ImageRegions::add(const std::string& name, std::vector<char> mask) {
    PENUMBRA_CHECK(mask.size() == size_t(width) * size_t(height));
    names.push_back(name);
    masks.push_back(std::move(mask));
}

const std::vector<char>* ImageRegions::find(const std::string& name) const {
    for (size_t k = 0; k < names.size(); ++k)
        if (names[k] == name) return &masks[k];
    return nullptr;
}

ImageRegions objectRegions(const SceneTracer& tracer, const Camera& camera) {
    ImageRegions r;
    r.width = camera.width;
    r.height = camera.height;
    const PinholeCamera cam(camera);
    r.hits.resize(size_t(r.width) * size_t(r.height));
    parallelFor(r.height, [&](int64_t y0, int64_t y1) {
        prepareTracingThread();
        for (int64_t y = y0; y < y1; ++y)
            for (int x = 0; x < r.width; ++x)
                r.hits[size_t(y) * size_t(r.width) + size_t(x)] =
                    tracer.trace(cam.origin(), cam.direction(x + 0.5, double(y) + 0.5));
    });
    const Scene& scene = tracer.scene();
    const size_t objects = scene.objects.size();
    std::vector<std::vector<char>> own(objects);
    std::vector<int> count(objects, 0);
    for (int y = 1; y + 1 < r.height; ++y)
        for (int x = 1; x + 1 < r.width; ++x) {
            const int o = r.hits[size_t(y * r.width + x)].object;
            bool interior = o >= 0;
            for (int dy = -1; dy <= 1 && interior; ++dy)
                for (int dx = -1; dx <= 1; ++dx)
                    interior = interior && r.hits[size_t((y + dy) * r.width + x + dx)].object == o;
            if (!interior) continue;
            if (own[size_t(o)].empty()) own[size_t(o)].assign(r.hits.size(), 0);
            own[size_t(o)][size_t(y * r.width + x)] = 1;
            ++count[size_t(o)];
        }
    // Groups: the name less its last "_part", when two or more objects seen share it; and "blocks".
    std::map<std::string, std::vector<size_t>> stems;
    std::vector<size_t> blocks;
    for (size_t o = 0; o < objects; ++o) {
        if (count[o] == 0) continue;
        r.add(scene.objects[o].name, own[o]);
        const std::string& name = scene.objects[o].name;
        const size_t cut = name.rfind('_');
        if (cut != std::string::npos && cut > 0) stems[name.substr(0, cut)].push_back(o);
        if (name.find("block") != std::string::npos) blocks.push_back(o);
    }
    auto merged = [&](const std::vector<size_t>& members) {
        std::vector<char> mask(r.hits.size(), 0);
        for (size_t o : members)
            for (size_t k = 0; k < mask.size(); ++k) mask[k] |= own[o][k];
        return mask;
    };
    for (const auto& [stem, members] : stems)
        if (members.size() >= 2 && !r.find(stem)) r.add(stem, merged(members));
    if (blocks.size() >= 2 && !r.find("blocks")) r.add("blocks", merged(blocks));
    return r;
}

std::vector<char> causticMask(const SceneTracer& tracer, const PhotonMap& caustics, const ImageRegions& regions,
                              double share, int grow, int lightSamples) {
    const size_t n = regions.hits.size();
    std::vector<char> mask(n, 0);
    if (!tracer.hasEmitters()) return mask;
    std::vector<double> caustic(n, -1), direct(n, 0);
    parallelFor(
        int64_t(n),
        [&](int64_t begin, int64_t end) {
            prepareTracingThread();
            for (int64_t k = begin; k < end; ++k) {
                const SurfaceHit& x = regions.hits[size_t(k)];
                if (!x.found || x.material->type != MaterialType::Diffuse || x.patch < 0 || x.material->emits())
                    continue;
                caustic[size_t(k)] = caustics.irradiance(x.point, x.normal).sum();
                Rng rng = streamRng(0, Stream::CausticRegion, uint64_t(k));
                double sum = 0;
                for (int s = 0; s < lightSamples; ++s) {
                    const LightSample l = tracer.sampleLight(x.point, x.normal, rng);
                    if (l.found()) sum += l.radiance.sum() * l.cosine / l.pdf;
                }
                direct[size_t(k)] = sum / lightSamples;
            }
        },
        64);
    // Against the view's mean direct irradiance too, so that a shadow (no direct light at all) is
    // not a caustic for the little light the mirrors put there.
    double meanDirect = 0;
    size_t diffuse = 0;
    for (size_t k = 0; k < n; ++k)
        if (caustic[k] >= 0) {
            meanDirect += direct[k];
            ++diffuse;
        }
    meanDirect /= double(std::max<size_t>(diffuse, 1));
    for (size_t k = 0; k < n; ++k) mask[k] = caustic[k] > 0 && caustic[k] >= share * std::max(direct[k], meanDirect);
    // Grown by `grow` pixels over the same object: a region chosen where the estimate is high would
    // otherwise keep the pixels it overestimates (the spot's blurred rim) and lose those it misses.
    for (int pass = 0; pass < grow; ++pass) {
        std::vector<char> next = mask;
        for (int y = 0; y < regions.height; ++y)
            for (int x = 0; x < regions.width; ++x) {
                const size_t k = size_t(y * regions.width + x);
                if (mask[k] || caustic[k] < 0) continue;
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) {
                        const int xx = x + dx, yy = y + dy;
                        if (xx < 0 || yy < 0 || xx >= regions.width || yy >= regions.height) continue;
                        const size_t q = size_t(yy * regions.width + xx);
                        if (mask[q] && regions.hits[q].object == regions.hits[k].object) next[k] = 1;
                    }
            }
        mask.swap(next);
    }
    return mask;
}

std::vector<RegionError> compareRegions(const Image& image, const Image& reference, const ImageRegions& regions,
                                        int blurRadius) {
    if (image.width != regions.width || image.height != regions.height || reference.width != regions.width ||
        reference.height != regions.height)
        throw Error(cat("cannot compare regions of a ", regions.width, "x", regions.height, " view on images of ",
                        image.width, "x", image.height, " and ", reference.width, "x", reference.height));
    const Image a = boxBlur(image, blurRadius), b = boxBlur(reference, blurRadius);
    std::vector<RegionError> out;
    for (size_t r = 0; r < regions.names.size(); ++r) {
        RegionError e;
        e.name = regions.names[r];
        Rgb sa = Rgb::Zero(), sb = Rgb::Zero();
        double l1 = 0, ref = 0;
        for (size_t k = 0; k < regions.masks[r].size(); ++k) {
            if (!regions.masks[r][k]) continue;
            const int x = int(k % size_t(regions.width)), y = int(k / size_t(regions.width));
            sa += image.at(x, y);
            sb += reference.at(x, y);
            l1 += (a.at(x, y) - b.at(x, y)).abs().sum();
            ref += b.at(x, y).sum();
            ++e.pixels;
        }
        if (e.pixels == 0) continue;
        e.mean = sa / e.pixels;
        e.referenceMean = sb / e.pixels;
        e.ratio = sb.sum() > 0 ? sa.sum() / sb.sum() : 0;
        e.pooledL1 = ref > 0 ? l1 / ref : 0;
        out.push_back(e);
    }
    return out;
}

}  // namespace penumbra
