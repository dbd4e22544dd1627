#include "solver/shafts.h"

#include <algorithm>
#include <cmath>

namespace penumbra {
namespace {

constexpr int kLeafPieces = 4;

double planarity(const ShaftEnd& e, const Vec3& centre) {
    double most = 0;
    for (int k = 0; k < e.count; ++k) most = std::max(most, std::abs(e.normal.dot(e.corner[size_t(k)] - centre)));
    return most;
}

Vec3 centreOf(const ShaftEnd& e) {
    Vec3 c = Vec3::Zero();
    for (int k = 0; k < e.count; ++k) c += e.corner[size_t(k)];
    return c / double(e.count);
}

// Whether every corner of `e` lies more than `margin` in front of the plane through `centre` of
// unit normal `normal`.
bool whollyInFront(const ShaftEnd& e, const Vec3& centre, const Vec3& normal, double margin) {
    for (int k = 0; k < e.count; ++k)
        if (!(normal.dot(e.corner[size_t(k)] - centre) > margin)) return false;
    return true;
}

// The interval of the points' projections on `axis`.
std::pair<double, double> project(const Vec3* p, int count, const Vec3& axis) {
    double low = HUGE_VAL, high = -HUGE_VAL;
    for (int k = 0; k < count; ++k) {
        const double s = axis.dot(p[k]);
        low = std::min(low, s), high = std::max(high, s);
    }
    return {low, high};
}

}  // namespace

ShaftEnd patchEnd(const PatchSet& patches, size_t i, double lift) {
    ShaftEnd e;
    e.count = patches.cornerCount[i];
    for (int k = 0; k < e.count; ++k) e.corner[size_t(k)] = patches.corners[i][size_t(k)] + lift * patches.normal[i];
    e.normal = patches.normal[i];
    return e;
}

ClearShafts::ClearShafts(const PatchSet& patches, const std::vector<RaySphere>& spheres,
                         const std::vector<char>& replaced, double margin) {
    Vec3 low = Vec3::Constant(HUGE_VAL), high = Vec3::Constant(-HUGE_VAL);
    for (size_t i = 0; i < patches.size(); ++i) {
        if (i < replaced.size() && replaced[i]) continue;
        Piece p;
        p.count = patches.cornerCount[i];
        p.corner = patches.corners[i];
        p.object = patches.object[i];
        p.low = p.high = p.corner[0];
        for (int k = 1; k < p.count; ++k)
            p.low = p.low.cwiseMin(p.corner[size_t(k)]), p.high = p.high.cwiseMax(p.corner[size_t(k)]);
        low = low.cwiseMin(p.low), high = high.cwiseMax(p.high);
        pieces_.push_back(p);
    }
    for (const RaySphere& s : spheres) {
        Piece p;
        p.corner[0] = s.center;
        p.radius = s.radius;
        p.low = s.center - Vec3::Constant(s.radius), p.high = s.center + Vec3::Constant(s.radius);
        low = low.cwiseMin(p.low), high = high.cwiseMax(p.high);
        pieces_.push_back(p);
    }
    // Embree traces the corners as floats (a relative error of 6e-8): closer than a ten-millionth of
    // the scene's size counts as touching.
    tolerance_ = pieces_.empty() ? 0 : 1e-7 * std::max((high - low).norm(), 1e-300);
    margin_ = std::max(tolerance_, margin);
    if (pieces_.empty()) return;
    nodes_.reserve(2 * pieces_.size() / kLeafPieces + 2);
    nodes_.push_back({});
    build(0, 0, int(pieces_.size()));
}

void ClearShafts::build(int node, int first, int count) {
    Vec3 low = Vec3::Constant(HUGE_VAL), high = Vec3::Constant(-HUGE_VAL);
    Vec3 cLow = low, cHigh = high;
    for (int k = first; k < first + count; ++k) {
        const Piece& p = pieces_[size_t(k)];
        low = low.cwiseMin(p.low), high = high.cwiseMax(p.high);
        const Vec3 c = 0.5 * (p.low + p.high);
        cLow = cLow.cwiseMin(c), cHigh = cHigh.cwiseMax(c);
    }
    nodes_[size_t(node)].low = low, nodes_[size_t(node)].high = high;
    if (count <= kLeafPieces) {
        nodes_[size_t(node)].first = first, nodes_[size_t(node)].count = count;
        return;
    }
    int axis = 0;
    (cHigh - cLow).maxCoeff(&axis);
    const int half = count / 2;
    std::nth_element(
        pieces_.begin() + first, pieces_.begin() + first + half, pieces_.begin() + first + count,
        [axis](const Piece& a, const Piece& b) { return a.low[axis] + a.high[axis] < b.low[axis] + b.high[axis]; });
    const int children = int(nodes_.size());
    nodes_[size_t(node)].first = children, nodes_[size_t(node)].count = 0;
    nodes_.push_back({});
    nodes_.push_back({});
    build(children, first, half);
    build(children + 1, first + half, count - half);
}

bool ClearShafts::separated(const Piece& p, const Vec3* hull, int count,
                            const std::vector<std::array<double, 4>>& faces) const {
    const double tol = margin_;
    if (p.count == 0) {  // a sphere: outside one face of the shaft
        for (const auto& f : faces)
            if (Vec3(f[0], f[1], f[2]).dot(p.corner[0]) - f[3] > p.radius + tol) return true;
        return false;
    }
    const Vec3* q = p.corner.data();
    for (const auto& f : faces) {  // wholly outside a face of the shaft
        const Vec3 n(f[0], f[1], f[2]);
        double nearest = HUGE_VAL;
        for (int k = 0; k < p.count; ++k) nearest = std::min(nearest, n.dot(q[k]) - f[3]);
        if (nearest > tol) return true;
    }
    auto apart = [&](const Vec3& axis) {
        const double length = axis.norm();
        if (!(length > 1e-300)) return false;
        const Vec3 u = axis / length;
        const auto [hLow, hHigh] = project(hull, count, u);
        const auto [pLow, pHigh] = project(q, p.count, u);
        return hHigh < pLow - tol || pHigh < hLow - tol;
    };
    // The piece's own plane, then the edges of both two by two (the shaft's edges a superset:
    // every pair of its points).
    const Vec3 normal = p.count == 4 ? Vec3((q[2] - q[0]).cross(q[3] - q[1])) : Vec3((q[1] - q[0]).cross(q[2] - q[0]));
    if (apart(normal)) return true;
    Vec3 edges[6];
    int edgeCount = 0;
    for (int k = 0; k < p.count; ++k) edges[edgeCount++] = q[(k + 1) % p.count] - q[k];
    if (p.count == 4) edges[edgeCount++] = q[2] - q[0], edges[edgeCount++] = q[3] - q[1];
    for (int i = 0; i < count; ++i)
        for (int j = i + 1; j < count; ++j) {
            const Vec3 e = hull[j] - hull[i];
            for (int k = 0; k < edgeCount; ++k)
                if (apart(e.cross(edges[k]))) return true;
        }
    return false;
}

bool ClearShafts::clear(const ShaftEnd& a, const ShaftEnd& b) const {
    if (nodes_.empty()) return true;
    const double tol = tolerance_;
    const Vec3 ca = centreOf(a), cb = centreOf(b);
    const double flatA = planarity(a, ca), flatB = planarity(b, cb);
    // Each end wholly in front of the other: every segment leaves one front for the other.
    if (!whollyInFront(b, ca, a.normal, flatA + 2 * tol) || !whollyInFront(a, cb, b.normal, flatB + 2 * tol))
        return false;
    Vec3 hull[8];
    int count = 0;
    for (int k = 0; k < a.count; ++k) hull[count++] = a.corner[size_t(k)];
    for (int k = 0; k < b.count; ++k) hull[count++] = b.corner[size_t(k)];
    // The shaft's faces: the planes through three of its points with all the others on one side.
    thread_local std::vector<std::array<double, 4>> faces;
    faces.clear();
    for (int i = 0; i < count; ++i)
        for (int j = i + 1; j < count; ++j)
            for (int k = j + 1; k < count; ++k) {
                Vec3 n = (hull[j] - hull[i]).cross(hull[k] - hull[i]);
                const double length = n.norm();
                if (!(length > 1e-300)) continue;
                n /= length;
                const double d = n.dot(hull[i]);
                double low = HUGE_VAL, high = -HUGE_VAL;
                for (int m = 0; m < count; ++m) {
                    const double s = n.dot(hull[m]) - d;
                    low = std::min(low, s), high = std::max(high, s);
                }
                if (high <= tol)
                    faces.push_back({n.x(), n.y(), n.z(), d});
                else if (low >= -tol)
                    faces.push_back({-n.x(), -n.y(), -n.z(), -d});
            }
    Vec3 low = hull[0], high = hull[0];
    for (int k = 1; k < count; ++k) low = low.cwiseMin(hull[k]), high = high.cwiseMax(hull[k]);
    low -= Vec3::Constant(margin_), high += Vec3::Constant(margin_);
    // Behind (or in) a flat end's plane, nothing meets a segment that leaves its front.
    auto behind = [&](const Piece& p, const ShaftEnd& e, const Vec3& c, double flat) {
        if (flat > tol) return false;
        if (p.count == 0) return e.normal.dot(p.corner[0] - c) < -p.radius;
        for (int k = 0; k < p.count; ++k)
            if (e.normal.dot(p.corner[size_t(k)] - c) > tol) return false;
        return true;
    };
    thread_local std::vector<int> stack;
    stack.assign(1, 0);
    while (!stack.empty()) {
        const Node& node = nodes_[size_t(stack.back())];
        stack.pop_back();
        if ((node.low.array() > high.array()).any() || (node.high.array() < low.array()).any()) continue;
        if (node.count == 0) {
            stack.push_back(node.first), stack.push_back(node.first + 1);
            continue;
        }
        for (int k = node.first; k < node.first + node.count; ++k) {
            const Piece& p = pieces_[size_t(k)];
            if ((p.low.array() > high.array()).any() || (p.high.array() < low.array()).any()) continue;
            if (p.count > 0 && (p.object == a.object || p.object == b.object)) continue;
            if (behind(p, a, ca, flatA) || behind(p, b, cb, flatB)) continue;
            if (!separated(p, hull, count, faces)) return false;
        }
    }
    return true;
}

}  // namespace penumbra
