#include "render/occlusion.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace penumbra {
namespace {

constexpr uint64_t kFull = ~uint64_t(0);

// A polygon of at most kMost corners after clipping (a quad gains one at each of two planes).
constexpr size_t kMost = 8;
struct Clipped {
    std::array<Eigen::Vector4d, kMost> p;
    size_t n = 0;
};

// A polygon (3 or 4 corners) clipped to OpenGL's near (w + z >= 0) and far (w - z >= 0) planes, in
// clip space; fewer than 3 corners if none of it is left.
Clipped clipped(const Eigen::Matrix4d& vp, const std::vector<Eigen::Vector3d>& polygon) {
    Clipped in, out;
    if (polygon.size() + 2 > kMost) return in;
    for (const Eigen::Vector3d& p : polygon) in.p[in.n++] = vp * p.homogeneous();
    for (const double side : {1.0, -1.0}) {
        out.n = 0;
        for (size_t k = 0; k < in.n; ++k) {
            const Eigen::Vector4d &p = in.p[k], &q = in.p[(k + 1) % in.n];
            const double dp = p.w() + side * p.z(), dq = q.w() + side * q.z();
            if (dp >= 0) out.p[out.n++] = p;
            if ((dp >= 0) != (dq >= 0)) out.p[out.n++] = p + (q - p) * (dp / (dp - dq));
        }
        in = out;
        if (in.n < 3) return Clipped{};
    }
    return in;
}

}  // namespace

OcclusionBuffer::OcclusionBuffer(const Eigen::Matrix4d& viewProjection, int width, int height)
    : vp_(viewProjection),
      width_(width),
      height_(height),
      columns_((width + kTile - 1) / kTile),
      rows_((height + kTile - 1) / kTile),
      mask_(size_t(columns_) * size_t(rows_), 0),
      depth_(mask_.size(), 0) {
    // Centres past the picture's edge are covered from the start: nothing is seen there (tiles of
    // the last column and row only).
    const auto outside = [&](int i, int j) {
        uint64_t m = 0;
        for (int y = 0; y < kTile; ++y)
            for (int x = 0; x < kTile; ++x)
                if (kTile * i + x >= width_ || kTile * j + y >= height_) m |= uint64_t(1) << (kTile * y + x);
        mask_[size_t(j) * size_t(columns_) + size_t(i)] = m;
    };
    for (int j = 0; j < rows_; ++j) outside(columns_ - 1, j);
    for (int i = 0; i < columns_; ++i) outside(i, rows_ - 1);
}

int OcclusionBuffer::tileOf(double v, int count) {
    return int(std::clamp(std::floor(v / kTile), 0.0, double(count - 1)));
}

void OcclusionBuffer::occlude(const std::vector<Eigen::Vector3d>& polygon, bool frontOnly) {
    const Clipped clip = clipped(vp_, polygon);
    if (clip.n < 3) return;
    // Picture coordinates (x right, y up, pixel (x, y) the square [x, x + 1] x [y, y + 1], its centre
    // at + 0.5) and 1/w, which is affine over them on a plane.
    const size_t n = clip.n;
    const auto& c = clip.p;
    std::array<Eigen::Vector3d, kMost> s;
    for (size_t k = 0; k < n; ++k) {
        const double w = c[k].w();
        if (!(w > 0)) return;
        s[k] = Eigen::Vector3d((c[k].x() / w * 0.5 + 0.5) * width_, (c[k].y() / w * 0.5 + 0.5) * height_, 1 / w);
    }
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    for (size_t k = 1; k + 1 < n; ++k) normal += (s[k] - s[0]).cross(s[k + 1] - s[0]);
    double x0 = HUGE_VAL, x1 = -HUGE_VAL, y0 = HUGE_VAL, y1 = -HUGE_VAL;
    for (size_t k = 0; k < n; ++k)
        x0 = std::min(x0, s[k].x()), x1 = std::max(x1, s[k].x()), y0 = std::min(y0, s[k].y()),
        y1 = std::max(y1, s[k].y());
    // Edge-on (its area a negligible part of its box's): its plane of 1/w cannot be trusted.
    if (!(std::abs(normal.z()) > 1e-9 * (x1 - x0) * (y1 - y0))) return;
    if (frontOnly && normal.z() < 0) return;
    const double turn = normal.z() > 0 ? 1 : -1;
    const auto invW = [&](double x, double y) {
        return s[0].z() - (normal.x() * (x - s[0].x()) + normal.y() * (y - s[0].y())) / normal.z();
    };
    if (x1 < 0 || y1 < 0 || x0 > width_ || y0 > height_) return;
    const int i0 = tileOf(x0, columns_), i1 = tileOf(x1, columns_), j0 = tileOf(y0, rows_), j1 = tileOf(y1, rows_);
    double smallest = HUGE_VAL, nearW = HUGE_VAL;  // the least 1/w of the polygon, its nearest w
    for (size_t k = 0; k < n; ++k) smallest = std::min(smallest, s[k].z()), nearW = std::min(nearW, c[k].w());
    // Bit k: (x, y) is inside edge k (on the polygon's side of its line).
    const auto insideEdges = [&](double x, double y) {
        unsigned bits = 0;
        for (size_t k = 0; k < n; ++k) {
            const Eigen::Vector3d &a = s[k], &b = s[(k + 1) % n];
            if (turn * ((b.x() - a.x()) * (y - a.y()) - (b.y() - a.y()) * (x - a.x())) >= 0) bits |= 1u << k;
        }
        return bits;
    };
    const unsigned all = (1u << n) - 1;
    // The tiles' corners, a row of them at a time (each corner shared by four tiles): inside or
    // not, and 1/w there.
    const size_t corners = size_t(i1 - i0 + 2);
    std::vector<unsigned> insideBelow(corners), insideAbove(corners);
    std::vector<double> invBelow(corners), invAbove(corners);
    const auto cornerRow = [&](int j, std::vector<unsigned>& in, std::vector<double>& inv) {
        for (size_t k = 0; k < corners; ++k) {
            const double x = kTile * (i0 + int(k)), y = kTile * j;
            in[k] = insideEdges(x, y), inv[k] = invW(x, y);
        }
    };
    cornerRow(j0, insideBelow, invBelow);
    for (int j = j0; j <= j1; ++j) {
        cornerRow(j + 1, insideAbove, invAbove);
        for (int i = i0; i <= i1; ++i) {
            const size_t t = size_t(j) * size_t(columns_) + size_t(i), c0 = size_t(i - i0);
            // A tile covered whole nearer than any point of the polygon: nothing to add.
            if (mask_[t] == kFull && depth_[t] <= nearW) continue;
            // Centres covered: none if the tile's four corners are outside one edge, every one if
            // they are inside all (the polygon is convex), else in each row of the tile the run of x
            // that every edge keeps.
            const unsigned q0 = insideBelow[c0], q1 = insideBelow[c0 + 1], q2 = insideAbove[c0],
                           q3 = insideAbove[c0 + 1];
            if ((q0 | q1 | q2 | q3) != all) continue;
            uint64_t m = (q0 & q1 & q2 & q3) == all ? kFull : 0;
            for (int y = 0; y < kTile && m != kFull; ++y) {
                const double py = kTile * j + y + 0.5;
                double lo = kTile * i + 0.5, hi = kTile * i + kTile - 0.5;
                for (size_t k = 0; k < n && lo <= hi; ++k) {
                    // Inside: turn * ((b - a) x (p - a)) >= 0, i.e. A x + B >= 0 along the row.
                    const Eigen::Vector3d &a = s[k], &b = s[(k + 1) % n];
                    const double A = -turn * (b.y() - a.y()), B = turn * ((b.x() - a.x()) * (py - a.y())) - A * a.x();
                    if (A > 0) {
                        lo = std::max(lo, -B / A);
                    } else if (A < 0) {
                        hi = std::min(hi, -B / A);
                    } else if (B < 0) {
                        hi = lo - 1;
                    }
                }
                if (lo > hi) continue;
                const int first = std::max(0, int(std::ceil(lo - 0.5 - kTile * i)));
                const int last = std::min(kTile - 1, int(std::floor(hi - 0.5 - kTile * i)));
                if (first > last) continue;
                const uint64_t row = ((uint64_t(1) << (last + 1)) - 1) & ~((uint64_t(1) << first) - 1);
                m |= row << (kTile * y);
            }
            if (m == 0) continue;
            // The farthest point of the polygon over the tile: at a corner of the tile, the least 1/w
            // (clamped into the polygon's own range: the plane beyond the polygon does not count).
            double least = std::min({invBelow[c0], invBelow[c0 + 1], invAbove[c0], invAbove[c0 + 1]});
            least = std::max(least, smallest);
            if (!(least > 0)) continue;
            const double far = 1 / least;
            uint64_t& have = mask_[t];
            double& depth = depth_[t];
            if (m == kFull && (have != kFull || far < depth)) {
                have = kFull, depth = far;  // a whole tile nearer than what was there
            } else if (have != kFull) {
                // Merged: the union of the centres, behind the farther of the two.
                depth = have == 0 ? far : std::max(depth, far);
                have |= m;
            }
        }
        std::swap(insideBelow, insideAbove);
        std::swap(invBelow, invAbove);
    }
}

bool OcclusionBuffer::hidden(const Eigen::AlignedBox3d& box) const {
    if (box.isEmpty()) return true;
    double nearest = HUGE_VAL, x0 = HUGE_VAL, x1 = -HUGE_VAL, y0 = HUGE_VAL, y1 = -HUGE_VAL;
    for (int c = 0; c < 8; ++c) {
        const Eigen::Vector4d p = vp_ * box.corner(Eigen::AlignedBox3d::CornerType(c)).homogeneous();
        if (!(p.w() + p.z() > 0)) return false;  // reaches in front of the near plane
        const double x = (p.x() / p.w() * 0.5 + 0.5) * width_, y = (p.y() / p.w() * 0.5 + 0.5) * height_;
        nearest = std::min(nearest, p.w());
        x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
    }
    if (x1 < 0 || y1 < 0 || x0 > width_ || y0 > height_) return true;  // out of the picture
    // A margin above the depth buffer's resolution where the viewer draws (24 bits from a near plane
    // at a thousandth of the scene's size: 6e-5 of the depth at the scene's size away) and above the
    // polygon offset's: surfaces nearer together than that may show through each other in OpenGL.
    const double behind = nearest * (1 - 1e-3);
    for (int j = tileOf(y0, rows_); j <= tileOf(y1, rows_); ++j)
        for (int i = tileOf(x0, columns_); i <= tileOf(x1, columns_); ++i) {
            const size_t t = size_t(j) * size_t(columns_) + size_t(i);
            if (mask_[t] != kFull || !(depth_[t] < behind)) return false;
        }
    return true;
}

}  // namespace penumbra
