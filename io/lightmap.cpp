#include "io/lightmap.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "core/error.h"

namespace penumbra {
namespace {

constexpr double kCoplanarCosine = 0.99996;  // 0.5 degree

Vec3 triangleNormal(const std::vector<Vec3>& p, const std::array<int, 3>& t) {
    const Vec3 n = (p[size_t(t[1])] - p[size_t(t[0])]).cross(p[size_t(t[2])] - p[size_t(t[0])]);
    const double length = n.norm();
    return length > 0 ? Vec3(n / length) : Vec3(Vec3::UnitZ());
}

}  // namespace

bool packShelves(const std::vector<std::array<int, 2>>& sizes, int size, std::vector<std::array<int, 2>>& at) {
    std::vector<size_t> order(sizes.size());
    std::iota(order.begin(), order.end(), size_t(0));
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return sizes[a][1] > sizes[b][1]; });
    at.assign(sizes.size(), {0, 0});
    int x = 0, y = 0, shelf = 0;  // the shelf's left end so far, its bottom, its height
    for (size_t i : order) {
        const auto [w, h] = sizes[i];
        if (w > size || h > size) return false;
        if (x + w > size) x = 0, y += shelf, shelf = 0;
        if (y + h > size) return false;
        at[i] = {x, y};
        x += w;
        shelf = std::max(shelf, h);
    }
    return true;
}

LightmapLayout layoutLightmap(const std::vector<Vec3>& positions, const std::vector<std::array<int, 3>>& triangles,
                              int size, int padding) {
    PENUMBRA_CHECK(size > 0 && padding >= 0);
    LightmapLayout out;
    out.size = size;
    // Charts: triangles joined through shared vertices while coplanar with the chart's first.
    const size_t n = triangles.size();
    std::vector<Vec3> normal(n);
    for (size_t t = 0; t < n; ++t) normal[t] = triangleNormal(positions, triangles[t]);
    std::vector<std::vector<int>> trianglesAt(positions.size());
    for (size_t t = 0; t < n; ++t)
        for (int v : triangles[t]) trianglesAt[size_t(v)].push_back(int(t));
    out.chartOf.assign(n, -1);
    std::vector<int> first;  // per chart: its first triangle, whose plane it lies in
    for (size_t seed = 0; seed < n; ++seed) {
        if (out.chartOf[seed] >= 0) continue;
        const int chart = int(first.size());
        first.push_back(int(seed));
        std::vector<int> stack{int(seed)};
        out.chartOf[seed] = chart;
        while (!stack.empty()) {
            const int t = stack.back();
            stack.pop_back();
            for (int v : triangles[size_t(t)])
                for (int u : trianglesAt[size_t(v)])
                    if (out.chartOf[size_t(u)] < 0 && normal[size_t(u)].dot(normal[seed]) >= kCoplanarCosine) {
                        out.chartOf[size_t(u)] = chart;
                        stack.push_back(u);
                    }
        }
    }
    // Each chart flat in its plane's axes (metres), and its extent there.
    const size_t charts = first.size();
    std::vector<Vec3> axisU(charts), axisV(charts);
    std::vector<Eigen::AlignedBox2d> box(charts);
    for (size_t c = 0; c < charts; ++c) orthonormalBasis(normal[size_t(first[c])], axisU[c], axisV[c]);
    const auto flat = [&](size_t chart, const Vec3& p) { return Vec2(p.dot(axisU[chart]), p.dot(axisV[chart])); };
    for (size_t t = 0; t < n; ++t)
        for (int v : triangles[t])
            box[size_t(out.chartOf[t])].extend(flat(size_t(out.chartOf[t]), positions[size_t(v)]));
    // The largest texel density at which the charts fit, by bisection on texels a metre.
    double largest = 0;
    for (const auto& b : box) largest = std::max({largest, b.sizes().x(), b.sizes().y()});
    const auto rectangles = [&](double density) {
        std::vector<std::array<int, 2>> sizes;
        for (const auto& b : box)
            sizes.push_back({int(std::ceil(b.sizes().x() * density)) + 1 + 2 * padding,
                             int(std::ceil(b.sizes().y() * density)) + 1 + 2 * padding});
        return sizes;
    };
    std::vector<std::array<int, 2>> at;
    double low = 0, high = largest > 0 ? 2.0 * size / largest : 1.0;
    if (!packShelves(rectangles(0), size, at))
        throw Error(
            cat(charts, " charts do not fit a lightmap of ", size, " x ", size, " texels: give a larger --lightmap"));
    for (int k = 0; k < 40; ++k) {
        const double mid = 0.5 * (low + high);
        (packShelves(rectangles(mid), size, at) ? low : high) = mid;
    }
    out.texelsPerMetre = low;
    const std::vector<std::array<int, 2>> sizes = rectangles(low);
    PENUMBRA_CHECK(packShelves(sizes, size, at));
    for (size_t c = 0; c < charts; ++c) out.chartTexels.push_back({at[c][0], at[c][1], sizes[c][0], sizes[c][1]});
    // New vertices: one per (mesh vertex, chart) pair, at its place in the image.
    std::vector<std::vector<std::pair<int, int>>> copies(positions.size());  // per vertex: (chart, new vertex)
    out.triangles.resize(n);
    for (size_t t = 0; t < n; ++t) {
        const int chart = out.chartOf[t];
        for (int k = 0; k < 3; ++k) {
            const int v = triangles[t][size_t(k)];
            auto& list = copies[size_t(v)];
            auto it = std::find_if(list.begin(), list.end(), [&](const auto& e) { return e.first == chart; });
            if (it == list.end()) {
                const Vec2 f = (flat(size_t(chart), positions[size_t(v)]) - box[size_t(chart)].min()) * low;
                const auto& r = out.chartTexels[size_t(chart)];
                // Texel units from the chart's corner, past its padding and half a texel in.
                out.uv.push_back(Vec2((r[0] + padding + 0.5 + f.x()) / size, (r[1] + padding + 0.5 + f.y()) / size));
                out.vertexOf.push_back(v);
                list.push_back({chart, int(out.uv.size()) - 1});
                it = list.end() - 1;
            }
            out.triangles[t][size_t(k)] = it->second;
        }
    }
    return out;
}

std::vector<Rgb> bakeLightmap(const LightmapLayout& layout, const std::vector<Vec3>& positions,
                              const std::function<Rgb(const Vec3& point, const Vec3& normal)>& light) {
    const int size = layout.size;
    std::vector<Rgb> texels(size_t(size) * size_t(size), Rgb::Zero());
    std::vector<int> covered(texels.size(), -1);  // the chart whose surface lies under the texel centre
    for (size_t t = 0; t < layout.triangles.size(); ++t) {
        const auto& tri = layout.triangles[t];
        std::array<Vec2, 3> q;
        std::array<Vec3, 3> p;
        for (int k = 0; k < 3; ++k) {
            q[size_t(k)] = layout.uv[size_t(tri[size_t(k)])] * size;  // texel units
            p[size_t(k)] = positions[size_t(layout.vertexOf[size_t(tri[size_t(k)])])];
        }
        const double area = (q[1] - q[0]).x() * (q[2] - q[0]).y() - (q[1] - q[0]).y() * (q[2] - q[0]).x();
        if (!(std::abs(area) > 0)) continue;
        const Vec3 n = (p[1] - p[0]).cross(p[2] - p[0]).normalized();
        Eigen::AlignedBox2d box;
        for (const Vec2& x : q) box.extend(x);
        const int x0 = std::max(0, int(std::floor(box.min().x()))), x1 = std::min(size - 1, int(box.max().x()));
        const int y0 = std::max(0, int(std::floor(box.min().y()))), y1 = std::min(size - 1, int(box.max().y()));
        for (int y = y0; y <= y1; ++y)
            for (int x = x0; x <= x1; ++x) {
                const Vec2 c(x + 0.5, y + 0.5);
                const double b1 = ((c - q[0]).x() * (q[2] - q[0]).y() - (c - q[0]).y() * (q[2] - q[0]).x()) / area;
                const double b2 = ((q[1] - q[0]).x() * (c - q[0]).y() - (q[1] - q[0]).y() * (c - q[0]).x()) / area;
                const double b0 = 1 - b1 - b2, slack = -1e-9;
                if (b0 < slack || b1 < slack || b2 < slack) continue;
                const size_t k = size_t(y) * size_t(size) + size_t(x);
                if (covered[k] >= 0) continue;  // on an edge two triangles share: taken once
                // A texel centre on the triangle's edge is read a hair inside it, where rays meet it.
                const double e = 1e-4, a0 = (b0 + e) / (1 + 3 * e), a1 = (b1 + e) / (1 + 3 * e);
                texels[k] = light(a0 * p[0] + a1 * p[1] + (1 - a0 - a1) * p[2], n);
                covered[k] = layout.chartOf[t];
            }
    }
    // Padding: each pass gives the uncovered texels of a chart's rectangle the mean of their covered
    // neighbours of that chart.
    for (int pass = 0; pass < 4; ++pass) {
        std::vector<int> next = covered;
        std::vector<Rgb> values = texels;
        for (size_t chart = 0; chart < layout.chartTexels.size(); ++chart) {
            const auto& r = layout.chartTexels[chart];
            for (int y = r[1]; y < std::min(size, r[1] + r[3]); ++y)
                for (int x = r[0]; x < std::min(size, r[0] + r[2]); ++x) {
                    const size_t k = size_t(y) * size_t(size) + size_t(x);
                    if (covered[k] >= 0) continue;
                    Rgb sum = Rgb::Zero();
                    int count = 0;
                    for (int dy = -1; dy <= 1; ++dy)
                        for (int dx = -1; dx <= 1; ++dx) {
                            const int xx = x + dx, yy = y + dy;
                            if (xx < 0 || yy < 0 || xx >= size || yy >= size) continue;
                            const size_t j = size_t(yy) * size_t(size) + size_t(xx);
                            if (covered[j] == int(chart)) sum += texels[j], ++count;
                        }
                    if (count) values[k] = sum / count, next[k] = int(chart);
                }
        }
        covered.swap(next);
        texels.swap(values);
    }
    return texels;
}

}  // namespace penumbra
