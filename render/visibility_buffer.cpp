#include "render/visibility_buffer.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "core/parallel.h"

namespace penumbra {
namespace {

// One triangle as the buffer tests it: the planes through the eye and its edges, each as a linear
// function of the image position, e_k(x, y) = c_k + y b_k + x a_k, positive inside. e_k is the
// weight of vertex k (its barycentric coordinate times their sum), the sum is D . N for the point's
// direction D and the plane's normal N, and det / sum the distance along D.
struct Triangle {
    double a[3], b[3], c[3];
    double invA[3];  // 1 / a (0 where a is 0)
    double det;
    int patch;
    int shape;           // 0: a quad's first triangle (v0, v1, v3) or a triangle patch; 1: a quad's second (v2, v3, v1)
    int x0, x1, y0, y1;  // the pixels its image may cover, inclusive
};

// The box of pixels that the image of the points `p` (relative to the eye) in front of the
// eye may cover, in a w x h image; false if none lies in front.
bool imageBox(const Vec3* p, size_t count, const PinholeCamera::ImagePlane& plane, int w, int h, int& x0, int& x1,
              int& y0, int& y1) {
    const double sx = 1 / plane.perX.squaredNorm(), sy = 1 / plane.perY.squaredNorm();
    double lo[2] = {HUGE_VAL, HUGE_VAL}, hi[2] = {-HUGE_VAL, -HUGE_VAL};
    for (size_t i = 0; i < count; ++i) {
        const Vec3& q = p[i];
        const Vec3 onPlane = q / q.dot(plane.forward) - plane.corner;
        const double xy[2] = {onPlane.dot(plane.perX) * sx, onPlane.dot(plane.perY) * sy};
        for (int k = 0; k < 2; ++k) lo[k] = std::min(lo[k], xy[k]), hi[k] = std::max(hi[k], xy[k]);
    }
    const auto clampTo = [](double v, int n) { return int(std::clamp(v, -1.0, double(n))); };
    // A point at image position x lies in pixel floor(x); a thousandth of a pixel's margin for rounding.
    x0 = std::max(0, clampTo(std::floor(lo[0] - 1e-3), w)), x1 = std::min(w - 1, clampTo(std::floor(hi[0] + 1e-3), w));
    y0 = std::max(0, clampTo(std::floor(lo[1] - 1e-3), h)), y1 = std::min(h - 1, clampTo(std::floor(hi[1] + 1e-3), h));
    return x0 <= x1 && y0 <= y1;
}

// The normal of the plane through the eye and corners p and q (relative to the eye), p x q, computed
// with its corners in a fixed order so that the triangle across the edge gets exactly its negative
// whatever the compiler fuses (a x b and -(b x a) may round apart under fused multiply-adds).
Vec3 edgePlane(const Vec3& p, const Vec3& q) {
    const bool inOrder = std::lexicographical_compare(p.data(), p.data() + 3, q.data(), q.data() + 3);
    return inOrder ? Vec3(p.cross(q)) : Vec3(-q.cross(p));
}

// Triangle `p` (relative to the eye) cut to the half space in front of the eye (Sutherland-Hodgman),
// a hair in front so that the projection stays finite: at most four corners.
struct Clipped {
    Vec3 v[4];
    size_t n = 0;
};
Clipped inFront(const Vec3 (&p)[3], const Vec3& forward) {
    const double near = 1e-9 * std::max({p[0].norm(), p[1].norm(), p[2].norm()});
    Clipped out;
    for (size_t k = 0; k < 3; ++k) {
        const Vec3& a = p[k];
        const Vec3& b = p[(k + 1) % 3];
        const double za = a.dot(forward) - near, zb = b.dot(forward) - near;
        if (za > 0) out.v[out.n++] = a;
        if ((za > 0) != (zb > 0)) out.v[out.n++] = a + (za / (za - zb)) * (b - a);
    }
    return out;
}

}  // namespace

bool VisibilityBuffer::eyeInsideSphere(const RayScene& rays, const Camera& camera) {
    for (const RaySphere& s : rays.spheres())
        if ((camera.position - s.center).norm() <= s.radius) return true;
    return false;
}

// The exact spheres' images, found per point by the quadratic.
struct Disc {
    Vec3 centre;  // relative to the eye
    double radius;
    int x0, x1, y0, y1;
};

struct VisibilityBuffer::Shapes {
    int width, height;
    PinholeCamera::ImagePlane plane;
    std::vector<Triangle> triangles;
    // Per row of pixels y, the triangles whose box reaches it: rowTriangles[rowStart[y], rowStart[y + 1]).
    std::vector<uint32_t> rowStart, rowTriangles;
    std::vector<Disc> discs;  // by sphere
};

VisibilityBuffer::~VisibilityBuffer() = default;

VisibilityBuffer::VisibilityBuffer(const PatchSet& patches, const RayScene& rays, const Camera& camera) {
    auto shapes = std::make_unique<Shapes>();
    const int width = shapes->width = camera.width, height = shapes->height = camera.height;
    const PinholeCamera::ImagePlane plane = shapes->plane = PinholeCamera(camera).imagePlane();
    const Vec3& forward = plane.forward;
    const Vec3& eye = camera.position;

    // Every patch's triangles, as Embree splits a quad, that the image may show.
    std::vector<Triangle>& triangles = shapes->triangles;
    triangles.reserve(2 * patches.size());
    for (size_t i = 0; i < patches.size(); ++i) {
        if (rays.onExactSphere(i)) continue;
        const std::array<Vec3, 4>& q = patches.corners[i];
        // Embree is given all four corners, a triangle's fourth its third: (q0, q1, q3) is it whole.
        for (int shape = 0; shape < (patches.isTriangle(i) ? 1 : 2); ++shape) {
            const Vec3 v[3] = {shape == 0 ? q[0] - eye : q[2] - eye, shape == 0 ? q[1] - eye : q[3] - eye,
                               shape == 0 ? q[3] - eye : q[1] - eye};
            Vec3 n[3] = {edgePlane(v[1], v[2]), edgePlane(v[2], v[0]), edgePlane(v[0], v[1])};
            const double det = v[0].dot(n[0]);
            if (!(std::abs(det) > 0)) continue;  // edge-on to the eye (or degenerate): no area in the image
            Triangle t;
            const Clipped front = inFront(v, forward);
            if (!imageBox(front.v, front.n, plane, width, height, t.x0, t.x1, t.y0, t.y1)) continue;
            for (int k = 0; k < 3; ++k) {
                if (det < 0) n[k] = -n[k];
                t.a[k] = n[k].dot(plane.perX), t.b[k] = n[k].dot(plane.perY), t.c[k] = n[k].dot(plane.corner);
                t.invA[k] = t.a[k] != 0 ? 1 / t.a[k] : 0;
            }
            t.det = std::abs(det);
            t.patch = int(i);
            t.shape = shape;
            triangles.push_back(t);
        }
    }
    std::vector<uint32_t>& rowStart = shapes->rowStart;
    rowStart.assign(size_t(height) + 1, 0);
    for (const Triangle& t : shapes->triangles)
        for (int y = t.y0; y <= t.y1; ++y) ++rowStart[size_t(y) + 1];
    for (size_t y = 1; y < rowStart.size(); ++y) rowStart[y] += rowStart[y - 1];
    shapes->rowTriangles.resize(rowStart.back());
    std::vector<uint32_t> next(rowStart.begin(), rowStart.end() - 1);
    for (size_t k = 0; k < shapes->triangles.size(); ++k)
        for (int y = shapes->triangles[k].y0; y <= shapes->triangles[k].y1; ++y)
            shapes->rowTriangles[next[size_t(y)]++] = uint32_t(k);

    // The exact spheres, by the box of their bounding cube's image.
    for (const RaySphere& s : rays.spheres()) {
        Disc d{s.center - eye, s.radius, 1, 0, 1, 0};  // an empty box unless seen
        Vec3 cube[8];
        for (int k = 0; k < 8; ++k)
            cube[k] = d.centre + s.radius * Vec3(k & 1 ? 1 : -1, k & 2 ? 1 : -1, k & 4 ? 1 : -1);
        bool behind = false;
        for (const Vec3& c : cube) behind = behind || !(c.dot(forward) > 1e-9 * c.norm());
        if (!behind)
            imageBox(cube, 8, plane, width, height, d.x0, d.x1, d.y0, d.y1);
        else if (d.centre.dot(forward) + s.radius > 0)
            d.x0 = 0, d.x1 = width - 1, d.y0 = 0, d.y1 = height - 1;
        shapes->discs.push_back(d);
    }
    shapes_ = std::move(shapes);
}

std::vector<BufferHit> VisibilityBuffer::firstHits(const std::vector<CameraSample>& samples) const {
    const Shapes& sh = *shapes_;
    std::vector<BufferHit> hits(samples.size());
    if (samples.empty()) return hits;
    // The samples by pixel (they come in row order): pixel (x, y)'s are [start[i], start[i + 1]) for
    // i = (y - y0) w + x, over the rows they span.
    const int64_t y0 = samples.front().y, y1 = samples.back().y;
    const size_t w = size_t(sh.width);
    std::vector<uint32_t> start(w * size_t(y1 - y0 + 1) + 1, 0);
    for (size_t k = 0; k < samples.size(); ++k) {
        PENUMBRA_CHECK(samples[k].x >= 0 && samples[k].x < sh.width && samples[k].y >= 0 && samples[k].y < sh.height);
        PENUMBRA_CHECK(k == 0 ||
                       std::pair(samples[k - 1].y, samples[k - 1].x) <= std::pair(samples[k].y, samples[k].x));
        ++start[size_t(samples[k].y - y0) * w + size_t(samples[k].x) + 1];
    }
    for (size_t k = 1; k < start.size(); ++k) start[k] += start[k - 1];
    // Calls f(k) for every sample k in pixels [x0, x1] of row y.
    const auto forSamples = [&](int x0, int x1, int64_t y, const auto& f) {
        const size_t row = size_t(y - y0) * w;
        for (uint32_t k = start[row + size_t(x0)], end = start[row + size_t(x1) + 1]; k < end; ++k) f(k);
    };
    for (int64_t y = y0; y <= y1; ++y)
        for (uint32_t i = sh.rowStart[size_t(y)]; i < sh.rowStart[size_t(y) + 1]; ++i) {
            const Triangle& t = sh.triangles[sh.rowTriangles[i]];
            // The pixels of the row where every edge function may be positive (its samples lie in
            // [y, y + 1)), within the box.
            double lo = t.x0, hi = t.x1 + 1;
            for (int e = 0; e < 3; ++e) {
                const double a = t.a[e], r0 = t.c[e] + double(y) * t.b[e], r1 = r0 + t.b[e];
                if (a > 0)
                    lo = std::max(lo, -std::max(r0, r1) * t.invA[e]);
                else if (a < 0)
                    hi = std::min(hi, -std::max(r0, r1) * t.invA[e]);
                else if (std::max(r0, r1) < 0)
                    hi = lo - 1;
            }
            if (!(hi >= lo)) continue;
            // A thousandth of a pixel's margin for rounding.
            const int xa = std::max(t.x0, int(std::floor(lo - 1e-3))), xb = std::min(t.x1, int(std::floor(hi + 1e-3)));
            if (xa > xb) continue;
            forSamples(xa, xb, y, [&](uint32_t k) {
                const Vec2& p = samples[k].at;
                const double e0 = t.c[0] + p.y() * t.b[0] + p.x() * t.a[0];
                const double e1 = t.c[1] + p.y() * t.b[1] + p.x() * t.a[1];
                const double e2 = t.c[2] + p.y() * t.b[2] + p.x() * t.a[2];
                if (!(e0 >= 0 && e1 >= 0 && e2 >= 0)) return;
                const double sum = e0 + e1 + e2;
                if (!(sum > 0)) return;
                const double dist = t.det / sum;
                BufferHit& h = hits[k];
                if (!(dist < h.t)) return;
                h.t = dist;
                h.patch = t.patch;
                h.u = t.shape == 0 ? e1 / sum : 1 - e1 / sum;
                h.v = t.shape == 0 ? e2 / sum : 1 - e2 / sum;
            });
        }
    for (size_t s = 0; s < sh.discs.size(); ++s) {
        const Disc& d = sh.discs[s];
        const double cc = d.centre.squaredNorm() - d.radius * d.radius;
        if (d.x0 > d.x1) continue;
        for (int64_t y = std::max<int64_t>(d.y0, y0); y <= std::min<int64_t>(d.y1, y1); ++y)
            forSamples(d.x0, d.x1, y, [&](uint32_t k) {
                const Vec2& p = samples[k].at;
                const Vec3 D = sh.plane.corner + p.x() * sh.plane.perX + p.y() * sh.plane.perY;
                const double a = D.squaredNorm(), b = D.dot(d.centre), disc = b * b - a * cc;
                if (!(disc >= 0)) return;
                const double dist = (b - std::sqrt(disc)) / a;
                BufferHit& h = hits[k];
                if (!(dist > 0 && dist < h.t)) return;
                h = BufferHit{-1, int(s), dist, 0, 0};
            });
    }
    return hits;
}

}  // namespace penumbra
