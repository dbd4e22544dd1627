#include "io/solution.h"

#include <cmath>
#include <cstring>
#include <fstream>

#include "core/error.h"
#include "io/atomic_file.h"

namespace penumbra {
namespace {

// Version 02 adds the corner values; version 01 files (without them) are still read, their corners
// interpolated from the display values as they were shown when written. Version 03 adds the indirect
// irradiance per corner (SolveResult::indirect) after the patches, a flag and then the values; files
// of 01 and 02 are read without it (their final gather gathers). Version 04 ends with the scene's
// inside unit in metres (SolveResult::metresPerUnit, 1 in older files), for export in metres. Version
// 05 ends with the patches' texture coordinates (PatchSet::uv): a flag, then four (u, v) per patch.
constexpr char kMagic[8] = {'P', 'N', 'B', 'S', 'O', 'L', '0', '5'};
constexpr char kMagic04[8] = {'P', 'N', 'B', 'S', 'O', 'L', '0', '4'};
constexpr char kMagic03[8] = {'P', 'N', 'B', 'S', 'O', 'L', '0', '3'};
constexpr char kMagic02[8] = {'P', 'N', 'B', 'S', 'O', 'L', '0', '2'};
constexpr char kMagic01[8] = {'P', 'N', 'B', 'S', 'O', 'L', '0', '1'};

struct Writer {
    std::string bytes;
    template <typename T>
    void put(const T& v) {
        bytes.append(reinterpret_cast<const char*>(&v), sizeof(T));
    }
    void put(const Vec3& v) { put(v.x()), put(v.y()), put(v.z()); }
    void put(const Rgb& v) { put(v[0]), put(v[1]), put(v[2]); }
};

struct Reader {
    const std::string& bytes;
    const std::string& path;
    size_t at = 0;
    template <typename T>
    T get() {
        if (at + sizeof(T) > bytes.size()) throw Error(cat(path, ": solution file is truncated"));
        T v;
        std::memcpy(&v, bytes.data() + at, sizeof(T));
        at += sizeof(T);
        return v;
    }
    Vec3 vec() {
        const double x = get<double>(), y = get<double>(), z = get<double>();
        return Vec3(x, y, z);
    }
    Rgb rgb() {
        const double x = get<double>(), y = get<double>(), z = get<double>();
        return Rgb(x, y, z);
    }
};

}  // namespace

std::string solutionBytes(const SolveResult& s) {
    PENUMBRA_CHECK_EQ(s.corners.size(), s.patches.size());
    Writer w;
    w.bytes.append(kMagic, 8);
    w.put(s.sceneFingerprint);
    w.put(uint64_t(s.patches.size()));
    w.put(uint64_t(s.patches.vertices.size()));
    for (const Vec3& v : s.patches.vertices) w.put(v);
    for (size_t i = 0; i < s.patches.size(); ++i) {
        w.put(s.patches.cornerCount[i]);
        w.put(int32_t(s.patches.object[i]));
        for (int k = 0; k < 4; ++k) w.put(s.patches.corners[i][size_t(k)]);
        for (int k = 0; k < 4; ++k) w.put(int32_t(s.patches.cornerVertex[i][size_t(k)]));
        w.put(s.solution.B[i]);
        w.put(s.solution.display[i]);
        for (int k = 0; k < 4; ++k) w.put(s.corners[i][size_t(k)]);
    }
    const bool indirect = s.indirect.size() == s.patches.size();
    w.put(uint8_t(indirect));
    if (indirect)
        for (const auto& corners : s.indirect)
            for (const Rgb& c : corners) w.put(c);
    w.put(s.metresPerUnit);
    w.put(uint8_t(s.patches.hasUv()));
    for (const auto& corners : s.patches.uv)
        for (const Vec2& t : corners) w.put(t.x()), w.put(t.y());
    return std::move(w.bytes);
}

void writeSolution(const std::string& path, const SolveResult& s) { writeFileAtomic(path, solutionBytes(s)); }

SolveResult readSolution(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(cat(path, ": no solution here (solve the scene first with `penumbra solve SCENE --out DIR`)"));
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return solutionFromBytes(bytes, path);
}

SolveResult solutionFromBytes(const std::string& bytes, const std::string& path) {
    const bool v01 = bytes.size() >= 8 && std::memcmp(bytes.data(), kMagic01, 8) == 0;
    const bool v02 = bytes.size() >= 8 && std::memcmp(bytes.data(), kMagic02, 8) == 0;
    const bool v03 = bytes.size() >= 8 && std::memcmp(bytes.data(), kMagic03, 8) == 0;
    const bool v04 = bytes.size() >= 8 && std::memcmp(bytes.data(), kMagic04, 8) == 0;
    if (bytes.size() < 8 || (!v01 && !v02 && !v03 && !v04 && std::memcmp(bytes.data(), kMagic, 8) != 0))
        throw Error(cat(path, ": not a Penumbra solution file (or from an incompatible version)"));
    Reader r{bytes, path, 8};
    SolveResult s;
    s.sceneFingerprint = r.get<uint64_t>();
    const uint64_t n = r.get<uint64_t>(), nv = r.get<uint64_t>();
    if (n > bytes.size() || nv > bytes.size()) throw Error(cat(path, ": solution file is damaged"));
    for (uint64_t k = 0; k < nv; ++k) s.patches.vertices.push_back(r.vec());
    for (uint64_t i = 0; i < n; ++i) {
        const uint8_t count = r.get<uint8_t>();
        const int object = r.get<int32_t>();
        std::array<Vec3, 4> c;
        for (auto& p : c) p = r.vec();
        std::array<int, 4> ids;
        for (auto& id : ids) {
            id = r.get<int32_t>();
            if (id < 0 || uint64_t(id) >= nv) throw Error(cat(path, ": solution file is damaged"));
        }
        if (count != 3 && count != 4) throw Error(cat(path, ": solution file is damaged"));
        s.patches.add(c, count, object, ids);
        s.solution.B.push_back(r.rgb());
        s.solution.display.push_back(r.rgb());
        if (!v01) {
            std::array<Rgb, 4> uniform;
            for (auto& value : uniform) value = r.rgb();
            s.corners.push_back(uniform);
        }
    }
    if (s.patches.size() != n) throw Error(cat(path, ": solution file is damaged (degenerate patch)"));
    if (v01) s.corners = interpolateCorners(s.patches, s.solution.display);
    if (!v01 && !v02 && r.get<uint8_t>() != 0) {
        s.indirect.resize(n);
        for (auto& corners : s.indirect)
            for (Rgb& c : corners) c = r.rgb();
    }
    if (!v01 && !v02 && !v03) {
        s.metresPerUnit = r.get<double>();
        if (!(s.metresPerUnit > 0) || !std::isfinite(s.metresPerUnit))
            throw Error(cat(path, ": solution file is damaged (its unit)"));
    }
    if (!v01 && !v02 && !v03 && !v04 && r.get<uint8_t>() != 0) {
        s.patches.uv.resize(s.patches.size());
        for (auto& corners : s.patches.uv)
            for (Vec2& t : corners) {
                const double u = r.get<double>(), v = r.get<double>();
                t = Vec2(u, v);
            }
    }
    if (r.at != bytes.size())
        throw Error(cat(path, ": solution file is damaged (", bytes.size() - r.at, " bytes too many)"));
    return s;
}

}  // namespace penumbra
