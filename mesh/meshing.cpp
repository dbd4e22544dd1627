// Scene objects -> OpenMesh meshes -> patches. Quads become grids of quads; triangles a regular
// grid of sub-triangles; spheres a projected cube (near-uniform triangle pairs); mesh files are triangulated
// and refined with OpenMesh's longest-edge splitting until no edge exceeds the target size.
#include <OpenMesh/Core/Mesh/PolyMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <cmath>
#include <map>
#include <queue>

#include "core/error.h"
#include "core/log.h"
#include "mesh/patches.h"
#include "mesh/refine.h"

namespace penumbra {
namespace {

struct Traits : public OpenMesh::DefaultTraits {
    typedef OpenMesh::Vec3d Point;
    typedef OpenMesh::Vec2d TexCoord2D;
};
using PolyMesh = OpenMesh::PolyMesh_ArrayKernelT<Traits>;
using TriMesh = OpenMesh::TriMesh_ArrayKernelT<Traits>;

OpenMesh::Vec3d om(const Vec3& v) { return OpenMesh::Vec3d(v.x(), v.y(), v.z()); }
Vec3 eig(const OpenMesh::Vec3d& v) { return Vec3(v[0], v[1], v[2]); }

// Copies the faces of an OpenMesh mesh into the patch set (its vertices become display vertices).
// With `uvs`, `uvOf(face, vertex)` gives each corner's texture coordinates.
template <typename Mesh, typename UvOf>
void appendMesh(const Mesh& mesh, int objectIndex, PatchSet& out, bool uvs, const UvOf& uvOf) {
    const int base = int(out.vertices.size());
    for (auto v : mesh.vertices()) out.vertices.push_back(eig(mesh.point(v)));
    for (auto f : mesh.faces()) {
        std::array<Vec3, 4> c;
        std::array<Vec2, 4> uv;
        std::array<int, 4> ids{};
        int n = 0;
        for (auto v : mesh.fv_range(f)) {
            PENUMBRA_CHECK_LT(n, 4);
            c[size_t(n)] = eig(mesh.point(v));
            uv[size_t(n)] = uvs ? uvOf(f, v) : Vec2::Zero();
            ids[size_t(n)] = base + v.idx();
            ++n;
        }
        PENUMBRA_CHECK(n == 3 || n == 4);
        if (n == 3) c[3] = c[2], ids[3] = ids[2], uv[3] = uv[2];
        out.add(c, n, objectIndex, ids, uvs ? &uv : nullptr);
    }
}

int divisions(double length, double h) { return std::max(1, int(std::ceil(length / h - 1e-9))); }

// Grids carry texture coordinates at their vertices, from the shape's corners' `uv` (zero without).
PolyMesh gridQuad(const std::vector<Vec3>& q, double h, const std::vector<Vec2>& uv = {}) {
    const int nu = divisions(std::max((q[1] - q[0]).norm(), (q[2] - q[3]).norm()), h);
    const int nv = divisions(std::max((q[3] - q[0]).norm(), (q[2] - q[1]).norm()), h);
    PolyMesh mesh;
    mesh.request_vertex_texcoords2D();
    std::vector<PolyMesh::VertexHandle> vh;
    for (int j = 0; j <= nv; ++j)
        for (int i = 0; i <= nu; ++i) {
            const double u = double(i) / nu, v = double(j) / nv;
            vh.push_back(
                mesh.add_vertex(om((1 - u) * (1 - v) * q[0] + u * (1 - v) * q[1] + u * v * q[2] + (1 - u) * v * q[3])));
            if (uv.size() == 4) {
                const Vec2 t = (1 - u) * (1 - v) * uv[0] + u * (1 - v) * uv[1] + u * v * uv[2] + (1 - u) * v * uv[3];
                mesh.set_texcoord2D(vh.back(), OpenMesh::Vec2d(t.x(), t.y()));
            }
        }
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) {
            const int a = j * (nu + 1) + i;
            mesh.add_face(vh[size_t(a)], vh[size_t(a + 1)], vh[size_t(a + nu + 2)], vh[size_t(a + nu + 1)]);
        }
    return mesh;
}

PolyMesh gridTriangle(const std::vector<Vec3>& t, double h, const std::vector<Vec2>& uv = {}) {
    const double longest = std::max({(t[1] - t[0]).norm(), (t[2] - t[1]).norm(), (t[0] - t[2]).norm()});
    const int k = divisions(longest, h);
    PolyMesh mesh;
    mesh.request_vertex_texcoords2D();
    // Vertex (i, j) at t0 + i/k (t1 - t0) + j/k (t2 - t0), i + j <= k.
    std::vector<std::vector<PolyMesh::VertexHandle>> vh(size_t(k + 1));
    for (int i = 0; i <= k; ++i)
        for (int j = 0; j <= k - i; ++j) {
            vh[size_t(i)].push_back(
                mesh.add_vertex(om(t[0] + (double(i) / k) * (t[1] - t[0]) + (double(j) / k) * (t[2] - t[0]))));
            if (uv.size() == 3) {
                const Vec2 c = uv[0] + (double(i) / k) * (uv[1] - uv[0]) + (double(j) / k) * (uv[2] - uv[0]);
                mesh.set_texcoord2D(vh[size_t(i)].back(), OpenMesh::Vec2d(c.x(), c.y()));
            }
        }
    for (int i = 0; i < k; ++i)
        for (int j = 0; j < k - i; ++j) {
            mesh.add_face(vh[size_t(i)][size_t(j)], vh[size_t(i + 1)][size_t(j)], vh[size_t(i)][size_t(j + 1)]);
            if (j + 1 < k - i)
                mesh.add_face(vh[size_t(i + 1)][size_t(j)], vh[size_t(i + 1)][size_t(j + 1)],
                              vh[size_t(i)][size_t(j + 1)]);
        }
    return mesh;
}

// For a cell a, b, c, d of points on a sphere about the origin: whether the diagonal a-c lies
// farther out than b-d, so that splitting along it keeps the surface convex.
bool ridgeAlongFirstDiagonal(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
    return (a.normalized() + c.normalized()).squaredNorm() >= (b.normalized() + d.normalized()).squaredNorm();
}

// Area of the triangulated k x k cube-sphere inscribed in the unit sphere.
double unitCubeSphereArea(int k) {
    double area = 0;
    auto p = [&](int ii, int jj) { return Vec3(1, 2.0 * ii / k - 1, 2.0 * jj / k - 1).normalized(); };
    for (int j = 0; j < k; ++j)
        for (int i = 0; i < k; ++i) {  // one face; the six are congruent
            const Vec3 a = p(i, j), b = p(i + 1, j), c = p(i + 1, j + 1), d = p(i, j + 1);
            const bool diagonalAC = ridgeAlongFirstDiagonal(a, b, c, d);
            area += diagonalAC ? 0.5 * ((b - a).cross(c - a).norm() + (c - a).cross(d - a).norm())
                               : 0.5 * ((b - a).cross(d - a).norm() + (c - b).cross(d - b).norm());
        }
    return 6 * area;
}

// A cube's six faces, each a k x k grid, projected onto the unit sphere, then mapped to the world.
// Cells are split into triangles, so every patch is planar.
PolyMesh cubeSphere(const SceneObject& o, double h) {
    const Vec3 c = o.toWorld * o.center;
    const double worldRadius = (o.toWorld.linear() * Vec3(o.radius, 0, 0)).norm();
    const double area = 4 * kPi * worldRadius * worldRadius;
    const int k = std::max(2, int(std::ceil(std::sqrt(area / (12 * h * h)))));
    // Facets inscribed in the sphere hold less area than it; lifting the vertices by this factor
    // gives the tessellation the sphere's area, so emitted and absorbed powers come out right.
    const double lift = std::sqrt(4 * kPi / unitCubeSphereArea(k));
    PolyMesh mesh;
    std::map<std::array<long, 3>, PolyMesh::VertexHandle> shared;  // cube-edge vertices shared by faces
    auto vertex = [&](const Vec3& cubePoint) {
        const std::array<long, 3> key{std::lround(cubePoint.x() * 2 * k), std::lround(cubePoint.y() * 2 * k),
                                      std::lround(cubePoint.z() * 2 * k)};
        auto it = shared.find(key);
        if (it != shared.end()) return it->second;
        const Vec3 p = o.toWorld * (o.center + lift * o.radius * cubePoint.normalized());
        return shared[key] = mesh.add_vertex(om(p));
    };
    // A mirroring transform (negative determinant) would turn the facets inside out.
    const bool mirrored = o.toWorld.linear().determinant() < 0;
    auto triangle = [&](PolyMesh::VertexHandle a, PolyMesh::VertexHandle b, PolyMesh::VertexHandle d) {
        if (mirrored)
            mesh.add_face(a, d, b);
        else
            mesh.add_face(a, b, d);
    };
    for (int axis = 0; axis < 3; ++axis)
        for (int sign = -1; sign <= 1; sign += 2) {
            Vec3 n = Vec3::Zero();
            n[axis] = sign;
            Vec3 a = Vec3::Zero(), b = Vec3::Zero();
            a[(axis + 1) % 3] = 1;
            b[(axis + 2) % 3] = 1;
            if (sign < 0) std::swap(a, b);  // keep a x b along the outward normal
            for (int j = 0; j < k; ++j)
                for (int i = 0; i < k; ++i) {
                    auto p = [&](int ii, int jj) { return n + (2.0 * ii / k - 1) * a + (2.0 * jj / k - 1) * b; };
                    // Two planar triangles per cell: a projected quad is not planar. The split
                    // follows the diagonal that lies farther out (a ridge, not a valley), so the
                    // tessellation stays convex and no two facets of a sphere see each other.
                    const auto v00 = vertex(p(i, j)), v10 = vertex(p(i + 1, j)), v11 = vertex(p(i + 1, j + 1)),
                               v01 = vertex(p(i, j + 1));
                    if (ridgeAlongFirstDiagonal(p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1))) {
                        triangle(v00, v10, v11);
                        triangle(v00, v11, v01);
                    } else {
                        triangle(v00, v10, v01);
                        triangle(v10, v11, v01);
                    }
                }
        }
    (void)c;
    return mesh;
}

// A soup's triangles, each with its corners' points and texture coordinates: what a refined face
// lies in.
struct SourceTriangle {
    std::array<Vec3, 3> p;
    std::array<Vec2, 3> uv;
    // Texture coordinates at a point of the triangle's plane (barycentric).
    Vec2 uvAt(const Vec3& x) const {
        const Vec3 e1 = p[1] - p[0], e2 = p[2] - p[0], d = x - p[0];
        const double a = e1.dot(e1), b = e1.dot(e2), c = e2.dot(e2), det = a * c - b * b;
        if (!(det > 0)) return uv[0];
        const double s = (c * d.dot(e1) - b * d.dot(e2)) / det, t = (a * d.dot(e2) - b * d.dot(e1)) / det;
        return uv[0] + s * (uv[1] - uv[0]) + t * (uv[2] - uv[0]);
    }
};

// The soup fan-triangulated and refined by longest-edge splitting until no edge exceeds h sqrt(2)
// (OpenMesh's LongestEdgeT, its queue kept here, splitting with split_copy so that each new face
// keeps the index of the soup triangle it lies in, `source`).
TriMesh refinedSoup(const PolygonSoup& soup, double h, const std::string& name, std::vector<SourceTriangle>& sources,
                    OpenMesh::FPropHandleT<int>& source) {
    TriMesh mesh;
    mesh.add_property(source);
    std::vector<TriMesh::VertexHandle> vh;
    for (const auto& v : soup.vertices) vh.push_back(mesh.add_vertex(om(v)));
    size_t skipped = 0;
    for (size_t fi = 0; fi < soup.faces.size(); ++fi) {
        const auto& f = soup.faces[fi];
        for (size_t k = 1; k + 1 < f.size(); ++k) {  // fan triangulation of convex polygons
            const Vec3& a = soup.vertices[size_t(f[0])];
            const Vec3& b = soup.vertices[size_t(f[k])];
            const Vec3& c = soup.vertices[size_t(f[k + 1])];
            const double edge = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
            TriMesh::FaceHandle added;
            if ((b - a).cross(c - a).norm() <= 1e-12 * edge * edge ||
                !(added = mesh.add_face(vh[size_t(f[0])], vh[size_t(f[k])], vh[size_t(f[k + 1])])).is_valid()) {
                ++skipped;
                continue;
            }
            SourceTriangle t{{a, b, c}, {Vec2::Zero(), Vec2::Zero(), Vec2::Zero()}};
            if (!soup.faceUv.empty()) t.uv = {soup.faceUv[fi][0], soup.faceUv[fi][k], soup.faceUv[fi][k + 1]};
            mesh.property(source, added) = int(sources.size());
            sources.push_back(t);
        }
    }
    if (skipped) logWarning("object '", name, "': skipped ", skipped, " degenerate or non-manifold mesh faces");
    if (mesh.n_faces() == 0) throw Error(cat("object '", name, "': its mesh has no usable faces"));
    const double longest = h * std::sqrt(2.0), longestSquared = longest * longest;
    using Queued = std::pair<TriMesh::EdgeHandle, double>;
    const auto shorter = [](const Queued& a, const Queued& b) { return a.second < b.second; };
    std::priority_queue<Queued, std::vector<Queued>, decltype(shorter)> queue(shorter);
    const auto lengthSquared = [&](TriMesh::HalfedgeHandle he) {
        return (mesh.point(mesh.to_vertex_handle(he)) - mesh.point(mesh.from_vertex_handle(he))).sqrnorm();
    };
    for (auto e : mesh.edges())
        if (const double l = lengthSquared(mesh.halfedge_handle(e, 0)); l > longestSquared) queue.push({e, l});
    while (!queue.empty()) {
        const Queued top = queue.top();
        queue.pop();
        if (top.second < longestSquared) break;
        const auto he = mesh.halfedge_handle(top.first, 0);
        const auto middle =
            mesh.add_vertex(0.5 * (mesh.point(mesh.to_vertex_handle(he)) + mesh.point(mesh.from_vertex_handle(he))));
        mesh.split_copy(top.first, middle);
        for (auto out : mesh.voh_range(middle))
            if (const double l = lengthSquared(out); l > longestSquared) queue.push({mesh.edge_handle(out), l});
    }
    mesh.garbage_collection();
    return mesh;
}

}  // namespace

Vec3 PatchSet::pointAt(size_t i, double u, double v) const {
    const auto& c = corners[i];
    if (isTriangle(i)) return c[0] + u * ((1 - v) * (c[1] - c[0]) + v * (c[2] - c[0]));
    return (1 - u) * (1 - v) * c[0] + u * (1 - v) * c[1] + u * v * c[2] + (1 - u) * v * c[3];
}

double PatchSet::jacobian(size_t i, double u, double v) const {
    const auto& c = corners[i];
    if (isTriangle(i)) return u * (c[1] - c[0]).cross(c[2] - c[0]).norm();
    const Vec3 du = (1 - v) * (c[1] - c[0]) + v * (c[2] - c[3]);
    const Vec3 dv = (1 - u) * (c[3] - c[0]) + u * (c[2] - c[1]);
    return du.cross(dv).norm();
}

std::vector<std::vector<size_t>> PatchSet::byObject(size_t objects) const {
    std::vector<std::vector<size_t>> members(objects);
    for (size_t i = 0; i < size(); ++i) {
        const size_t o = size_t(object[i]);
        if (o >= members.size()) members.resize(o + 1);
        members[o].push_back(i);
    }
    return members;
}

Vec2 PatchSet::uvAt(size_t i, double u, double v) const {
    const auto& t = uv[i];
    if (isTriangle(i)) return t[0] + u * ((1 - v) * (t[1] - t[0]) + v * (t[2] - t[0]));
    return (1 - u) * (1 - v) * t[0] + u * (1 - v) * t[1] + u * v * t[2] + (1 - u) * v * t[3];
}

Vec2 PatchSet::uvAtHit(size_t i, double u, double v) const {
    const auto& t = uv[i];
    // Embree's quad: (0, 0) at corner 0, u towards corner 1, v towards corner 3; a triangle (corner
    // 3 = corner 2) is its first half, with barycentric u and v.
    if (isTriangle(i)) return t[0] + u * (t[1] - t[0]) + v * (t[2] - t[0]);
    return (1 - u) * (1 - v) * t[0] + u * (1 - v) * t[1] + u * v * t[2] + (1 - u) * v * t[3];
}

Vec2 PatchSet::uvAtPoint(size_t i, const Vec3& x) const {
    // Barycentric (s, t) of x in the triangle a, b, d: x = a + s (b - a) + t (d - a).
    const auto barycentric = [&x](const Vec3& a, const Vec3& b, const Vec3& d) {
        const Vec3 e1 = b - a, e2 = d - a, r = x - a;
        const double p = e1.dot(e1), q = e1.dot(e2), w = e2.dot(e2), det = p * w - q * q;
        if (!(det > 0)) return Vec2(Vec2::Zero());
        return Vec2((w * r.dot(e1) - q * r.dot(e2)) / det, (p * r.dot(e2) - q * r.dot(e1)) / det);
    };
    const auto& c = corners[i];
    if (isTriangle(i)) {
        const Vec2 b = barycentric(c[0], c[1], c[2]);
        return uvAtHit(i, b.x(), b.y());
    }
    const Vec2 first = barycentric(c[0], c[1], c[3]);
    if (first.sum() <= 1) return uvAtHit(i, first.x(), first.y());
    const Vec2 second = barycentric(c[2], c[3], c[1]);
    return uvAtHit(i, 1 - second.x(), 1 - second.y());
}

void PatchSet::add(const std::array<Vec3, 4>& c, int count, int objectIndex, const std::array<int, 4>& vertexIds,
                   const std::array<Vec2, 4>* cornerUv) {
    const Vec3 vectorArea =
        count == 3 ? 0.5 * (c[1] - c[0]).cross(c[2] - c[0]) : 0.5 * (c[2] - c[0]).cross(c[3] - c[1]);
    const double a = vectorArea.norm();
    if (!(a > 0)) return;  // a degenerate sub-face (only from mesh refinement) carries no light
    PENUMBRA_CHECK(cornerUv ? uv.size() == area.size() : uv.empty());
    if (cornerUv) uv.push_back(*cornerUv);
    corners.push_back(c);
    cornerCount.push_back(uint8_t(count));
    normal.push_back(vectorArea / a);
    area.push_back(a);
    object.push_back(objectIndex);
    cornerVertex.push_back(vertexIds);
    // Area centroid: for a quad, the area-weighted mean of its two triangles' centroids.
    if (count == 3) {
        centroid.push_back((c[0] + c[1] + c[2]) / 3);
    } else {
        const double a1 = (c[1] - c[0]).cross(c[2] - c[0]).norm(), a2 = (c[2] - c[0]).cross(c[3] - c[0]).norm();
        const Vec3 g1 = (c[0] + c[1] + c[2]) / 3, g2 = (c[0] + c[2] + c[3]) / 3;
        centroid.push_back(a1 + a2 > 0 ? Vec3((a1 * g1 + a2 * g2) / (a1 + a2)) : Vec3((c[0] + c[1] + c[2] + c[3]) / 4));
    }
    double r = 0;
    for (const Vec3& corner : c) r = std::max(r, (corner - centroid.back()).norm());
    radius.push_back(r);
}

Eigen::AlignedBox3d patchBounds(const PatchSet& patches) {
    Eigen::AlignedBox3d box;
    for (const auto& corners : patches.corners)
        for (const Vec3& p : corners) box.extend(p);
    return box;
}

double objectArea(const SceneObject& o) {
    switch (o.type) {
        case ShapeType::Quad:
            return 0.5 * (o.vertices[2] - o.vertices[0]).cross(o.vertices[3] - o.vertices[1]).norm();
        case ShapeType::Triangle:
            return 0.5 * (o.vertices[1] - o.vertices[0]).cross(o.vertices[2] - o.vertices[0]).norm();
        case ShapeType::Sphere: {
            const double r = (o.toWorld.linear() * Vec3(o.radius, 0, 0)).norm();
            return 4 * kPi * r * r;
        }
        case ShapeType::Mesh: {
            double total = 0;
            for (const auto& f : o.mesh.faces)
                for (size_t k = 1; k + 1 < f.size(); ++k)
                    total += 0.5 * (o.mesh.vertices[size_t(f[k])] - o.mesh.vertices[size_t(f[0])])
                                       .cross(o.mesh.vertices[size_t(f[k + 1])] - o.mesh.vertices[size_t(f[0])])
                                       .norm();
            return total;
        }
    }
    return 0;
}

double sceneArea(const Scene& scene) {
    double total = 0;
    for (const auto& o : scene.objects) total += objectArea(o);
    return total;
}

int patchTarget(const Scene& scene, const MeshingOptions& options) {
    const double perObject = double(std::max(options.patchesPerObject, 0)) * double(scene.objects.size());
    return int(std::min(std::max(double(options.targetPatches), perObject), 1e8));
}

PatchSet meshScene(const Scene& scene, const MeshingOptions& options) {
    const double area = sceneArea(scene);
    double h = options.patchSize / scene.metresPerUnit;  // --patch-size is in metres
    if (!(h > 0)) {
        if (options.targetPatches < 1) throw Error("--patches must be at least 1");
        h = std::sqrt(area / patchTarget(scene, options));
    }
    // Small flat lamps (emitters covering under a tenth of the surface, the solve's small sources)
    // have their light taken in closed form by every receiver (solver/radiosity/system.h), at a cost
    // of rows times lamp patches. Past 64 lamp patches in all each lamp is meshed into patches about
    // as wide as its square root (one patch for a square lamp): finer lamps add nothing a receiver
    // can see, and the building's 44 lamps, in 176 patches at 48,712 patches in all, took 3.0 s of
    // its 4.8 s of first-pass form factors (0.5 m patches).
    double emitting = 0;
    size_t lampPatches = 0;
    std::vector<char> lamp(scene.objects.size(), 0);
    for (size_t i = 0; i < scene.objects.size(); ++i) {
        const SceneObject& o = scene.objects[i];
        const Material& m = scene.materialOf(o);
        if (m.type != MaterialType::Diffuse || !m.emits()) continue;
        emitting += objectArea(o);
        lamp[i] = o.type == ShapeType::Quad || o.type == ShapeType::Triangle;
        if (lamp[i])
            lampPatches +=
                (o.type == ShapeType::Quad ? gridQuad(o.vertices, h) : gridTriangle(o.vertices, h)).n_faces();
    }
    const bool coarseLamps = emitting < kSmallSourceShare * area && lampPatches > 64;
    PatchSet patches;
    // Texture coordinates at the patches' corners where the scene has textures.
    const bool uvs = scene.hasTextures();
    for (size_t i = 0; i < scene.objects.size(); ++i) {
        const SceneObject& o = scene.objects[i];
        const double size = coarseLamps && lamp[i] ? std::max(h, std::sqrt(objectArea(o))) : h;
        const auto atVertex = [](const PolyMesh& mesh) {
            return [&mesh](PolyMesh::FaceHandle, PolyMesh::VertexHandle v) {
                const OpenMesh::Vec2d t = mesh.texcoord2D(v);
                return Vec2(t[0], t[1]);
            };
        };
        switch (o.type) {
            case ShapeType::Quad: {
                const PolyMesh mesh = gridQuad(o.vertices, size, o.uv);
                appendMesh(mesh, int(i), patches, uvs, atVertex(mesh));
                break;
            }
            case ShapeType::Triangle: {
                const PolyMesh mesh = gridTriangle(o.vertices, size, o.uv);
                appendMesh(mesh, int(i), patches, uvs, atVertex(mesh));
                break;
            }
            case ShapeType::Sphere:
                appendMesh(cubeSphere(o, h), int(i), patches, uvs,
                           [](PolyMesh::FaceHandle, PolyMesh::VertexHandle) { return Vec2(Vec2::Zero()); });
                break;
            case ShapeType::Mesh: {
                std::vector<SourceTriangle> sources;
                OpenMesh::FPropHandleT<int> source;
                const TriMesh mesh = refinedSoup(o.mesh, h, o.name, sources, source);
                appendMesh(mesh, int(i), patches, uvs, [&](TriMesh::FaceHandle f, TriMesh::VertexHandle v) {
                    return sources[size_t(mesh.property(source, f))].uvAt(eig(mesh.point(v)));
                });
                break;
            }
        }
    }
    const int asked = options.patchSize > 0 ? 0 : patchTarget(scene, options);
    logInfo("meshed ", scene.objects.size(), " objects into ", patches.size(), " patches (target size ", h, " m",
            asked > options.targetPatches ? cat("; ", asked, " asked: ", options.patchesPerObject, " per object") : "",
            ")");
    return patches;
}

CornerValues interpolateCorners(const PatchSet& p, const std::vector<Rgb>& value, double creaseDeg) {
    // Patches around each vertex (vertices are per object, so nothing crosses objects).
    const auto around = patchesAround(p);
    const double cosCrease = std::cos(creaseDeg * kPi / 180);
    std::vector<std::array<Rgb, 4>> out(p.size());
    for (size_t i = 0; i < p.size(); ++i) {
        for (int k = 0; k < 4; ++k) {
            Rgb sum = Rgb::Zero();
            double weight = 0;
            for (int j : around[size_t(p.cornerVertex[i][size_t(k)])])
                if (p.normal[size_t(j)].dot(p.normal[i]) >= cosCrease) {
                    sum += p.area[size_t(j)] * value[size_t(j)];
                    weight += p.area[size_t(j)];
                }
            out[i][size_t(k)] = weight > 0 ? Rgb(sum / weight) : value[i];
        }
    }
    joinHangingVertices(p, around, out, creaseDeg);
    return out;
}

}  // namespace penumbra
