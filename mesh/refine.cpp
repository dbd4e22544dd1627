#include "mesh/refine.h"

#include <unordered_map>

#include "core/error.h"

namespace penumbra {
namespace {

// A vertex position of one object, quantised to 1e-9 m: midpoints are computed in one way from the
// same two corners (0.5 (a + b)), so both neighbours of an edge find the same key.
struct PointKey {
    int object;
    int64_t x, y, z;
    bool operator==(const PointKey& o) const { return object == o.object && x == o.x && y == o.y && z == o.z; }
};
struct PointKeyHash {
    size_t operator()(const PointKey& k) const {
        uint64_t h = uint64_t(k.object) * 0x9E3779B97F4A7C15ull;
        for (int64_t v : {k.x, k.y, k.z}) h = (h ^ uint64_t(v)) * 0x100000001B3ull + (h >> 29);
        return size_t(h);
    }
};
PointKey keyOf(int object, const Vec3& p) {
    return {object, std::llround(p.x() * 1e9), std::llround(p.y() * 1e9), std::llround(p.z() * 1e9)};
}
Vec3 midpoint(const Vec3& a, const Vec3& b) { return 0.5 * (a + b); }

using VertexIndex = std::unordered_map<PointKey, int, PointKeyHash>;

VertexIndex indexVertices(const PatchSet& p) {
    VertexIndex index;
    index.reserve(p.vertices.size());
    for (size_t i = 0; i < p.size(); ++i)
        for (int k = 0; k < p.cornerCount[i]; ++k)
            index.emplace(keyOf(p.object[i], p.corners[i][size_t(k)]), p.cornerVertex[i][size_t(k)]);
    return index;
}

bool hasCorner(const PatchSet& p, size_t i, int vertex) {
    for (int k = 0; k < p.cornerCount[i]; ++k)
        if (p.cornerVertex[i][size_t(k)] == vertex) return true;
    return false;
}

}  // namespace

std::vector<std::vector<int>> patchesAround(const PatchSet& p) {
    std::vector<std::vector<int>> around(p.vertices.size());
    for (size_t i = 0; i < p.size(); ++i)
        for (int k = 0; k < p.cornerCount[i]; ++k) around[size_t(p.cornerVertex[i][size_t(k)])].push_back(int(i));
    return around;
}

std::vector<HangingVertex> hangingVertices(const PatchSet& p) {
    const VertexIndex index = indexVertices(p);
    std::vector<HangingVertex> out;
    for (size_t i = 0; i < p.size(); ++i) {
        const int n = p.cornerCount[i];
        for (int k = 0; k < n; ++k) {
            const Vec3& a = p.corners[i][size_t(k)];
            const Vec3& b = p.corners[i][size_t((k + 1) % n)];
            const auto it = index.find(keyOf(p.object[i], midpoint(a, b)));
            if (it != index.end()) out.push_back({it->second, int(i), k, (k + 1) % n, (b - a).norm()});
        }
    }
    std::sort(out.begin(), out.end(), [](const HangingVertex& x, const HangingVertex& y) {
        return x.edgeLength != y.edgeLength ? x.edgeLength > y.edgeLength : x.vertex < y.vertex;
    });
    return out;
}

void joinHangingVertices(const PatchSet& p, const std::vector<std::vector<int>>& around, CornerValues& out,
                         double creaseDeg) {
    const double cosCrease = std::cos(creaseDeg * kPi / 180);
    for (const HangingVertex& h : hangingVertices(p)) {
        const size_t coarse = size_t(h.patch);
        const Rgb mean = 0.5 * (out[coarse][size_t(h.cornerA)] + out[coarse][size_t(h.cornerB)]);
        for (int j : around[size_t(h.vertex)])
            if (p.normal[size_t(j)].dot(p.normal[coarse]) >= cosCrease)
                for (int k = 0; k < 4; ++k)
                    if (p.cornerVertex[size_t(j)][size_t(k)] == h.vertex) out[size_t(j)][size_t(k)] = mean;
    }
}

PatchSet shareVertices(const PatchSet& p) {
    PatchSet out;
    VertexIndex index;
    index.reserve(4 * p.size());
    for (size_t i = 0; i < p.size(); ++i) {
        std::array<int, 4> ids;
        for (int k = 0; k < 4; ++k) {
            const Vec3& x = p.corners[i][size_t(k)];
            const auto [it, added] = index.emplace(keyOf(p.object[i], x), int(out.vertices.size()));
            if (added) out.vertices.push_back(x);
            ids[size_t(k)] = it->second;
        }
        out.add(p.corners[i], p.cornerCount[i], p.object[i], ids, p.hasUv() ? &p.uv[i] : nullptr);
    }
    return out;
}

void childPolygons(const PatchSet& p, size_t i, std::array<std::array<Vec3, 4>, 4>& out) {
    const auto& c = p.corners[i];
    if (p.isTriangle(i)) {
        const Vec3 ab = midpoint(c[0], c[1]), bc = midpoint(c[1], c[2]), ca = midpoint(c[2], c[0]);
        out = {{{c[0], ab, ca, ca}, {ab, c[1], bc, bc}, {ca, bc, c[2], c[2]}, {ab, bc, ca, ca}}};
    } else {
        const Vec3 ab = midpoint(c[0], c[1]), bc = midpoint(c[1], c[2]), cd = midpoint(c[2], c[3]),
                   da = midpoint(c[3], c[0]), e = p.pointAt(i, 0.5, 0.5);
        out = {{{c[0], ab, e, da}, {ab, c[1], bc, e}, {e, bc, c[2], cd}, {da, e, cd, c[3]}}};
    }
}

void childUvs(const PatchSet& p, size_t i, std::array<std::array<Vec2, 4>, 4>& out) {
    const auto& c = p.uv[i];
    const auto mid = [](const Vec2& a, const Vec2& b) { return Vec2(0.5 * (a + b)); };
    if (p.isTriangle(i)) {
        const Vec2 ab = mid(c[0], c[1]), bc = mid(c[1], c[2]), ca = mid(c[2], c[0]);
        out = {{{c[0], ab, ca, ca}, {ab, c[1], bc, bc}, {ca, bc, c[2], c[2]}, {ab, bc, ca, ca}}};
    } else {
        const Vec2 ab = mid(c[0], c[1]), bc = mid(c[1], c[2]), cd = mid(c[2], c[3]), da = mid(c[3], c[0]),
                   e = p.uvAt(i, 0.5, 0.5);
        out = {{{c[0], ab, e, da}, {ab, c[1], bc, e}, {e, bc, c[2], cd}, {da, e, cd, c[3]}}};
    }
}

PatchSet splitPatches(const PatchSet& p, std::vector<char>& split) {
    PENUMBRA_CHECK_EQ(split.size(), p.size());
    VertexIndex index = indexVertices(p);
    const auto around = patchesAround(p);
    // The 2:1 rule: an unsplit patch with a vertex hanging on its edge, next to a neighbour that
    // splits, would get a second level of hanging vertices; split it too, until nothing changes.
    for (bool changed = true; changed;) {
        changed = false;
        for (size_t i = 0; i < p.size(); ++i) {
            if (split[i]) continue;
            const int n = p.cornerCount[i];
            for (int k = 0; k < n && !split[i]; ++k) {
                const int a = p.cornerVertex[i][size_t(k)], b = p.cornerVertex[i][size_t((k + 1) % n)];
                const auto it = index.find(
                    keyOf(p.object[i], midpoint(p.corners[i][size_t(k)], p.corners[i][size_t((k + 1) % n)])));
                if (it == index.end()) continue;
                for (int j : around[size_t(it->second)])
                    if (split[size_t(j)] && (hasCorner(p, size_t(j), a) || hasCorner(p, size_t(j), b))) {
                        split[i] = 1;
                        changed = true;
                        break;
                    }
            }
        }
    }
    PatchSet out;
    out.vertices = p.vertices;
    auto vertexAt = [&](int object, const Vec3& position) {
        const auto [it, added] = index.emplace(keyOf(object, position), int(out.vertices.size()));
        if (added) out.vertices.push_back(position);
        return it->second;
    };
    for (size_t i = 0; i < p.size(); ++i) {
        if (!split[i]) {
            out.add(p.corners[i], p.cornerCount[i], p.object[i], p.cornerVertex[i], p.hasUv() ? &p.uv[i] : nullptr);
            continue;
        }
        std::array<std::array<Vec3, 4>, 4> children;
        std::array<std::array<Vec2, 4>, 4> uvs;
        childPolygons(p, i, children);
        if (p.hasUv()) childUvs(p, i, uvs);
        for (size_t k = 0; k < 4; ++k) {
            std::array<int, 4> ids;
            for (size_t c = 0; c < 4; ++c) ids[c] = vertexAt(p.object[i], children[k][c]);
            out.add(children[k], p.cornerCount[i], p.object[i], ids, p.hasUv() ? &uvs[k] : nullptr);
        }
    }
    return out;
}

}  // namespace penumbra
