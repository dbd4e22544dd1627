#include "solver/radiosity/system.h"

#include "core/cluster.h"
#include "core/error.h"
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
        s.reflectance[i] = diffuse ? meanReflectance(scene, patches, i) : Rgb::Zero();
        s.emission[i] = diffuse ? Rgb(kPi * meanEmission(scene, patches, i)) : Rgb::Zero();
    }
    return s;
}

std::vector<char> smallSources(const RadiositySystem& s) {
    std::vector<char> emits(s.size(), 0);
    double emitting = 0, total = 0;
    for (size_t i = 0; i < s.size(); ++i) {
        emits[i] = !s.specular[i] && (s.emission[i] > 0).any();
        emitting += emits[i] ? s.area[i] : 0;
        total += s.area[i];
    }
    if (!(emitting < kSmallSourceShare * total)) return {};
    return emits;
}

ChannelPlanes::ChannelPlanes(const std::vector<Rgb>& B) {
    for (int k = 0; k < 3; ++k) {
        c[k].resize(B.size());
        for (size_t i = 0; i < B.size(); ++i) c[k][i] = B[i][k];
    }
}

// The sweeps are bound by reading the matrix. `omp simd` (compiled with -fopenmp-simd, no OpenMP
// runtime) lets the compiler vectorise the three double sums, whose order it may then change, and
// target_clones builds the loop for AVX2 with FMA as well as for the baseline, chosen when the
// program loads. The sums stay in double: summing in float (twice the vector width) was measured
// 1.3x faster but loses a 1e-6 lamp beside a 1e6 one (the twelve-orders test).
namespace {
Rgb sparseIrradiance(const FormFactorMatrix::SparseRow& r, const ChannelPlanes& B) {
    const double *b0 = B.c[0].data(), *b1 = B.c[1].data(), *b2 = B.c[2].data();
    double h0 = 0, h1 = 0, h2 = 0;
    for (size_t k = 0; k < r.count; ++k) {
        const double f = r.value[k];
        const size_t j = size_t(r.column[k]);
        h0 += f * b0[j];
        h1 += f * b1[j];
        h2 += f * b2[j];
    }
    return Rgb(h0, h1, h2);
}
}  // namespace

__attribute__((target_clones("arch=haswell", "default"))) Rgb rowIrradiance(const FormFactorMatrix& F, size_t i,
                                                                            const ChannelPlanes& B) {
    if (F.isSparse()) return sparseIrradiance(F.sparseRow(i), B);
    const double *b0 = B.c[0].data(), *b1 = B.c[1].data(), *b2 = B.c[2].data();
    double h0 = 0, h1 = 0, h2 = 0;
    const float* row = F.row(i);
    const size_t n = F.size();
#pragma omp simd reduction(+ : h0, h1, h2)
    for (size_t j = 0; j < n; ++j) {
        const double f = row[j];
        h0 += f * b0[j];
        h1 += f * b1[j];
        h2 += f * b2[j];
    }
    return Rgb(h0, h1, h2);
}

std::vector<Rgb> gatherIrradiance(const RadiositySystem& s, const FormFactorMatrix& F, const std::vector<Rgb>& B,
                                  bool mean) {
    const size_t n = F.size();
    const ChannelPlanes planes(B);
    std::vector<Rgb> H(n);
    const int64_t first = int64_t(F.firstRow());  // in row blocks, this rank's rows; then shared
    parallelFor(
        int64_t(F.endRow()) - first,
        [&](int64_t begin, int64_t end) {
            for (int64_t ii = first + begin; ii < first + end; ++ii) {
                const size_t i = size_t(ii);
                H[i] = mean && F.hasMeanRow(i) ? sparseIrradiance(F.meanRow(i), planes) + s.transport.incoming(i, B)
                                               : irradianceAt(s, F, i, B, planes);
            }
        },
        16);
    shareRowValues(F, H);
    return H;
}

std::vector<Rgb> meanRadiosity(const RadiositySystem& s, const FormFactorMatrix& F, const std::vector<Rgb>& B) {
    if (F.seen.empty()) return B;
    const std::vector<Rgb> H = gatherIrradiance(s, F, B, true);
    std::vector<Rgb> mean = B;
    for (size_t i = 0; i < s.size(); ++i)
        if (F.hasMeanRow(i)) mean[i] = s.emission[i] + s.reflectance[i] * H[i];
    return mean;
}

double gaussSeidelPass(const RadiositySystem& s, const FormFactorMatrix& F, std::vector<Rgb>& B) {
    ChannelPlanes planes(B);
    double change = 0, emitted = 0;
    const auto sweep = [&](size_t begin, size_t end) {
        for (size_t i = begin; i < end; ++i) {
            const Rgb next = s.emission[i] + s.reflectance[i] * irradianceAt(s, F, i, B, planes);
            change += s.area[i] * (next - B[i]).abs().sum();
            emitted += s.area[i] * s.emission[i].sum();
            B[i] = next;
            planes.set(i, B[i]);
        }
    };
    if (!F.inRowBlocks() || !cluster::distributed()) {
        sweep(0, s.size());
    } else {
        // Row blocks: a chain in rank order. Each rank sweeps its rows with the newest values of the
        // rows before them and passes them on with the running sums: the same operations in the same
        // order as one process, so the same bits (and no speed-up: the point is the memory).
        const std::vector<size_t>& start = F.rowBlocks();
        for (int r = 0; r + 1 < int(start.size()); ++r) {
            const size_t begin = start[size_t(r)], end = start[size_t(r) + 1];
            cluster::Packer mine;
            if (r == cluster::rank()) {
                sweep(begin, end);
                mine.put(change), mine.put(emitted);
                mine.put(B.data() + begin, end - begin);
            }
            const std::string bytes = cluster::broadcast(mine.bytes, r);
            cluster::Unpacker in(bytes);
            std::vector<Rgb> theirs;
            in.get(change), in.get(emitted), in.get(theirs);
            PENUMBRA_CHECK(theirs.size() == end - begin);
            for (size_t i = begin; i < end; ++i) B[i] = theirs[i - begin], planes.set(i, B[i]);
        }
    }
    return emitted > 0 ? change / emitted : 0;
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
    // Per patch what it absorbs and sends out is its mean over its area; what the rest of the scene
    // gathers from it is B.
    const std::vector<Rgb> H = gatherIrradiance(s, F, B, true);
    std::vector<Rgb> mean = B;
    for (size_t i = 0; i < n; ++i)
        if (F.hasMeanRow(i)) mean[i] = s.emission[i] + s.reflectance[i] * H[i];
    const bool transport = !s.transport.empty();
    PowerBalance p;
    p.emitted.resize(n);
    p.absorbed.assign(n, Rgb::Zero());
    Rgb leaving = Rgb::Zero(), arriving = Rgb::Zero();
    std::vector<int> firstPatch;  // of each object, to book what an object absorbs as a whole
    for (size_t i = 0; i < n; ++i) {
        p.emitted[i] = s.area[i] * s.emission[i];
        leaving += s.area[i] * mean[i];
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
    // A patch with a hidden part sends to back faces what leaves it and is not seen, A_i (mean_i -
    // seen_i B_i), which is the light of its origins whose second ray met a back face (never below
    // zero: ray_form_factors.cpp), shared among its back-face transfers as its first rays met them.
    std::vector<double> backShare(F.seen.empty() ? 0 : n, 0.0);
    for (const BackTransfer& t : F.backTransfers)
        if (F.hasMeanRow(size_t(t.from))) backShare[size_t(t.from)] += t.areaFactor;
    for (const BackTransfer& t : F.backTransfers) {
        const size_t i = size_t(t.from);
        const Rgb power = F.hasMeanRow(i)
                              ? Rgb(t.areaFactor / backShare[i] * s.area[i] * (mean[i] - double(F.seen[i]) * B[i]))
                              : Rgb(t.areaFactor * B[i]);
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
