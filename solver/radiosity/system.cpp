#include "solver/radiosity/system.h"

#include "core/parallel.h"

namespace penumbra {

RadiositySystem buildSystem(const Scene& scene, const PatchSet& patches) {
    RadiositySystem s;
    s.area = patches.area;
    s.reflectance.resize(patches.size());
    s.emission.resize(patches.size());
    s.object = patches.object;
    s.specular.assign(patches.size(), 0);
    for (size_t i = 0; i < patches.size(); ++i) {
        const Material& m = scene.materialOf(scene.objects[size_t(patches.object[i])]);
        const bool diffuse = m.type == MaterialType::Diffuse;
        s.specular[i] = !diffuse;
        s.reflectance[i] = diffuse ? m.reflectance : Rgb::Zero();
        s.emission[i] = diffuse ? Rgb(kPi * m.emission) : Rgb::Zero();
    }
    return s;
}

std::vector<Rgb> gatherIrradiance(const RadiositySystem& s, const FormFactorMatrix& F, const std::vector<Rgb>& B) {
    const size_t n = F.size();
    std::vector<Rgb> H(n);
    parallelFor(int64_t(n), [&](int64_t begin, int64_t end) {
        for (int64_t i = begin; i < end; ++i) H[size_t(i)] = irradianceAt(s, F, size_t(i), B);
    }, 16);
    return H;
}

double relativeResidual(const RadiositySystem& s, const std::vector<Rgb>& B, const std::vector<Rgb>& H) {
    double r = 0, e = 0;
    for (size_t i = 0; i < s.size(); ++i) {
        r += s.area[i] * (s.emission[i] + s.reflectance[i] * H[i] - B[i]).abs().sum();
        e += s.area[i] * s.emission[i].sum();
    }
    return e > 0 ? r / e : 0;
}

PowerBalance powerBalance(const RadiositySystem& s, const FormFactorMatrix& F, const std::vector<Rgb>& B) {
    const size_t n = s.size();
    const std::vector<Rgb> H = gatherIrradiance(s, F, B);
    const bool transport = !s.transport.empty();
    PowerBalance p;
    p.emitted.resize(n);
    p.absorbed.assign(n, Rgb::Zero());
    Rgb leaving = Rgb::Zero(), arriving = Rgb::Zero();
    std::vector<int> firstPatch;   // of each object, to book what an object absorbs as a whole
    for (size_t i = 0; i < n; ++i) {
        p.emitted[i] = s.area[i] * s.emission[i];
        leaving += s.area[i] * B[i];
        if (size_t(s.object[i]) >= firstPatch.size()) firstPatch.resize(size_t(s.object[i]) + 1, -1);
        if (firstPatch[size_t(s.object[i])] < 0) firstPatch[size_t(s.object[i])] = int(i);
        // With specular transport, light reaching a mirror or glass patch is passed on (or lost) by
        // the transport's shares below, not absorbed here.
        if (transport && s.specular[i]) continue;
        p.absorbed[i] = s.area[i] * (1 - s.reflectance[i]) * H[i];
        arriving += s.area[i] * H[i];
    }
    if (transport)
        for (size_t i = 0; i < n; ++i)
            for (size_t k = s.transport.lossStart[i]; k < s.transport.lossStart[i + 1]; ++k) {
                const Rgb power = s.area[i] * s.transport.lossShare[k] * B[i];
                p.absorbed[size_t(firstPatch[size_t(s.transport.lossObject[k])])] += power;
                arriving += power;
            }
    for (const BackTransfer& t : F.backTransfers) {
        const Rgb power = t.areaFactor * B[size_t(t.from)];
        p.absorbed[size_t(t.to)] += power;
        arriving += power;
    }
    for (size_t i = 0; i < n; ++i) {
        p.totalEmitted += p.emitted[i];
        p.totalAbsorbed += p.absorbed[i];
    }
    // What leaves the surfaces and arrives at none of them has left the scene.
    p.escaped = leaving - arriving;
    return p;
}

}  // namespace penumbra
