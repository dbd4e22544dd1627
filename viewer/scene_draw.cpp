#include "viewer/scene_draw.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <type_traits>

#include "core/error.h"
#include "core/log.h"
#include "render/occlusion.h"
#include "solver/tracer.h"

namespace penumbra {
namespace {

const char* kVertex = R"(#version 330 core
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 radiance;
layout(location = 2) in vec3 normal;
layout(location = 3) in vec2 uv;
uniform mat4 viewProjection;
out vec3 vRadiance;
out vec3 vWorld;
out vec3 vNormal;
out vec2 vUv;
void main() {
    vRadiance = radiance;
    vWorld = position;
    vNormal = normal;
    vUv = uv;
    gl_Position = viewProjection * vec4(position, 1.0);
})";

// Diffuse patches: their radiance into a float target, alpha the distance from the eye (what a
// probe stores); back faces black (the contract's rule); edges flat black.
const char* kDiffuseFragment = R"(#version 330 core
in vec3 vRadiance;
in vec3 vWorld;
uniform int edges;
uniform vec3 eye;
out vec4 colour;
void main() {
    float distance = length(vWorld - eye);
    if (edges == 1) { colour = vec4(0.0, 0.0, 0.0, distance); return; }
    colour = vec4(gl_FrontFacing ? vRadiance : vec3(0.0), distance);
})";

// A textured diffuse object: the light at its corners (E / pi, interpolated) times the reflectance
// texel, plus the emission texel: the texture's detail on however coarse a mesh, as the headless
// radiosity view shows it (render/radiosity_view.cpp TextureDetail).
const char* kTexturedFragment = R"(#version 330 core
in vec3 vRadiance;
in vec3 vWorld;
in vec2 vUv;
uniform vec3 eye;
uniform sampler2D reflectanceTexture;
uniform sampler2D emissionTexture;
uniform int textures;  // 1: a reflectance texture, 2: an emission texture, 3: both
uniform vec3 reflectance;
uniform vec3 emission;
out vec4 colour;
void main() {
    vec3 rho = reflectance * ((textures % 2) == 1 ? texture(reflectanceTexture, vUv).rgb : vec3(1.0));
    vec3 e = emission * (textures >= 2 ? texture(emissionTexture, vUv).rgb : vec3(1.0));
    colour = vec4(gl_FrontFacing ? e + rho * vRadiance : vec3(0.0), length(vWorld - eye));
})";

// A mirror or glass object through its probe (see scene_draw.h).
const char* kSpecularFragment = R"(#version 330 core
in vec3 vWorld;
in vec3 vNormal;
uniform vec3 eye;
uniform mat4 viewProjection;
uniform samplerCube probe;  // rgb: radiance; a: distance from probeCentre
uniform samplerCube probeNearest;  // the same, read without filtering (the search's many reads)
uniform vec3 probeCentre;
uniform float reach;        // the farthest a ray is followed: the scene's diagonal
uniform int glass;          // 0: mirror
uniform vec3 tint;          // the mirror's reflectance, the glass's transmittance
uniform float ior;
uniform int sphere;         // 1: an exact sphere of `centre` and `radius`
uniform vec3 centre;
uniform float radius;
out vec4 colour;

// How far x lies behind the surface the probe sees in its direction (negative: in front).
float behind(vec3 x) {
    vec3 v = x - probeCentre;
    return length(v) - texture(probeNearest, v).a;
}

// The radiance arriving at p from direction d: the first point of the ray behind the probe's
// surface, by steps growing along the ray, then secants.
vec3 follow(vec3 p, vec3 d) {
    float t0 = 0.0, f0 = behind(p + 1e-4 * reach * d);
    const int steps = 8;
    for (int k = 1; k <= steps; ++k) {
        float s = float(k) / float(steps);
        float t1 = reach * s * s;
        float f1 = behind(p + t1 * d);
        if (f1 >= 0.0) {
            for (int j = 0; j < 4; ++j) {
                float t = t0 + (t1 - t0) * f0 / (f0 - f1);
                float f = behind(p + t * d);
                if (f < 0.0) { t0 = t; f0 = f; } else { t1 = t; f1 = f; }
            }
            return texture(probe, p + t1 * d - probeCentre).rgb;
        }
        t0 = t1;
        f0 = f1;
    }
    return texture(probe, d).rgb;
}

// The light a branch of weight w carries from p along d: a weak branch (Fresnel's reflections on
// glass, mostly) by its direction alone, as if what it meets were far (a single lookup: the walk
// along the ray up to 13).
vec3 carried(vec3 w, vec3 p, vec3 d) {
    if (max(w.r, max(w.g, w.b)) < 0.15) return w * texture(probe, d).rgb;
    return w * follow(p, d);
}

float fresnel(float cosIncident, float etaFrom, float etaTo) {
    cosIncident = min(1.0, abs(cosIncident));
    float sinT = etaFrom / etaTo * sqrt(max(0.0, 1.0 - cosIncident * cosIncident));
    if (sinT >= 1.0) return 1.0;
    float cosT = sqrt(max(0.0, 1.0 - sinT * sinT));
    float rs = (etaFrom * cosIncident - etaTo * cosT) / (etaFrom * cosIncident + etaTo * cosT);
    float rp = (etaTo * cosIncident - etaFrom * cosT) / (etaTo * cosIncident + etaFrom * cosT);
    return 0.5 * (rs * rs + rp * rp);
}

void main() {
    vec3 d = normalize(vWorld - eye);
    vec3 p = vWorld, n = normalize(vNormal);
    if (sphere == 1) {
        // The exact sphere along the eye's ray (its facets are drawn about it: its outline is
        // the sphere's), at its own depth.
        vec3 o = eye - centre;
        float b = dot(o, d), h = b * b - (dot(o, o) - radius * radius);
        if (h < 0.0 || -b - sqrt(h) <= 0.0) discard;
        p = eye + (-b - sqrt(h)) * d;
        n = normalize(p - centre);
        vec4 clip = viewProjection * vec4(p, 1.0);
        gl_FragDepth = clamp(0.5 * clip.z / clip.w + 0.5, 0.0, 1.0);
    } else {
        gl_FragDepth = gl_FragCoord.z;
    }
    bool front = dot(n, d) < 0.0;
    vec3 L = vec3(0.0);
    if (glass == 0) {
        if (front) L = carried(tint, p, reflect(d, n));
    } else {
        vec3 m = front ? n : -n;
        float etaFrom = front ? 1.0 : ior, etaTo = front ? ior : 1.0;
        float F = fresnel(dot(d, m), etaFrom, etaTo);
        L = carried(vec3(F), p, reflect(d, m));
        if (F < 1.0) {
            vec3 w = (1.0 - F) * (front ? tint : vec3(1.0));
            vec3 t = refract(d, m, etaFrom / etaTo);
            if (sphere == 1 && front) {
                // Inside the ball: out where the chord ends, refracted again; what reflects there
                // goes on along the next chord (twice).
                vec3 q = p;
                for (int k = 0; k < 3; ++k) {
                    q = q - 2.0 * dot(q - centre, t) * t;
                    vec3 outward = normalize(q - centre);
                    float G = fresnel(dot(t, outward), ior, 1.0);
                    if (G < 1.0) L += carried(w * (1.0 - G), q, refract(t, -outward, ior));
                    w *= G;
                    t = reflect(t, -outward);
                }
            } else {
                // A slab: out on the far face parallel to the near one, along the eye's ray again.
                float G = fresnel(dot(t, m), etaTo, etaFrom);
                L += carried(w * (1.0 - G), p, d);
            }
        }
    }
    colour = vec4(L, length(p - eye));
})";

// The six faces of a cube map as cameras (the directions and up vectors of OpenGL's cube map
// lookup, so that a face's image lands where texture(probe, v) reads it).
constexpr std::array<std::array<double, 6>, 6> kFaces = {{
    {1, 0, 0, 0, -1, 0},
    {-1, 0, 0, 0, -1, 0},
    {0, 1, 0, 0, 0, 1},
    {0, -1, 0, 0, 0, -1},
    {0, 0, 1, 0, -1, 0},
    {0, 0, -1, 0, -1, 0},
}};
constexpr int kProbeSize = 128;

struct Specular {
    int object = 0;
    GLsizei first = 0, count = 0;  // its indices in the triangle buffer
    Vec3 probeCentre = Vec3::Zero();
    bool sphere = false;
    Vec3 centre = Vec3::Zero();
    double radius = 0;
    bool glass = false;
    Rgb tint = Rgb::Ones();
    double ior = 1.5;
    std::array<GLuint, 2> probe{0, 0};  // generations: mirrors and glass black, then through the first
};

// A textured diffuse object's triangles and its material's textures.
struct Textured {
    GLsizei first = 0, count = 0;
    GLuint reflectance = 0, emission = 0;  // 0: none
    Rgb reflectanceFactor = Rgb::Ones(), emissionFactor = Rgb::Zero();
};

GLint glWrap(Wrap w) {
    return w == Wrap::Clamp ? GL_CLAMP_TO_EDGE : w == Wrap::Mirror ? GL_MIRRORED_REPEAT : GL_REPEAT;
}

}  // namespace

struct SceneDraw::State {
    GLuint vertexBuffer = 0, triangleBuffer = 0, edgeBuffer = 0;
    GLuint vao = 0, edgeVao = 0;
    GLuint diffuse = 0, specular = 0;  // programs
    GLuint nearest = 0;                // a sampler object: cube maps read without filtering
    GLsizei edgeCount = 0;
    // The plain diffuse triangles in cells of a grid over the scene, each cell's contiguous: cells
    // out of the view are not drawn (looking into one of the building's rooms, most of it), the
    // others nearest first (hidden fragments then fail the depth test before shading).
    struct Cell {
        GLsizei first = 0, count = 0;
        Eigen::AlignedBox3f box;
    };
    std::vector<Cell> cells;
    // The opaque diffuse polygons of the scene (its quads and triangles), which hide the cells
    // behind them from the view; with their boxes, to draw the nearest first.
    std::vector<std::vector<Eigen::Vector3d>> occluders;
    std::vector<Eigen::AlignedBox3d> occluderBoxes;
    bool occlusionCulling = true;
    mutable size_t cellsInView = 0, cellsDrawn = 0;
    std::vector<Specular> objects;
    std::vector<Textured> textured;
    GLuint texturedProgram = 0;
    std::map<const Texture*, GLuint> textures;  // each image once
    double sceneSize = 1;
    bool cullBackFaces = false;
};

bool SceneDraw::showsTextures(const Scene& scene, const SceneObject& o) {
    const Material& m = scene.materialOf(o);
    return m.type == MaterialType::Diffuse && m.textured() && o.hasUv();
}

SceneDraw::SceneDraw(const Scene& scene, const std::vector<float>& vertices, const std::vector<unsigned>& triangles,
                     const std::vector<int>& triangleObject, const std::vector<unsigned>& edges, bool textures,
                     double sceneSize, bool cullBackFaces)
    : s_(std::make_unique<State>()) {
    State& s = *s_;
    s.sceneSize = sceneSize;
    s.cullBackFaces = cullBackFaces;
    // The plain diffuse triangles first (in cells), then each textured object's, then each mirror
    // or glass object's.
    std::vector<unsigned> ordered;
    std::vector<std::vector<unsigned>> ofObject(scene.objects.size());
    for (size_t t = 0; t < triangleObject.size(); ++t) {
        const SceneObject& o = scene.objects[size_t(triangleObject[t])];
        const bool plain = scene.materialOf(o).type == MaterialType::Diffuse && !(textures && showsTextures(scene, o));
        std::vector<unsigned>& to = plain ? ordered : ofObject[size_t(triangleObject[t])];
        to.insert(to.end(), &triangles[3 * t], &triangles[3 * t] + 3);
    }
    {
        const auto at = [&](unsigned v) {
            return Eigen::Vector3f(vertices[kStride * v], vertices[kStride * v + 1], vertices[kStride * v + 2]);
        };
        Eigen::AlignedBox3f bounds;
        for (unsigned v : ordered) bounds.extend(at(v));
        // About eight triangles a cell of the grid (most cells are empty, the others hold a surface):
        // the Cornell box's 6,000 in 9^3 cells (327 not empty), the building's 172,000 in 28^3 (one
        // draw each: finer cells cost llvmpipe more calls than they save in a small scene, and hide
        // more in a large one: 26.3 frames/s at 24^3, 25.2 at 16^3, 15.9 at 8^3, measured).
        const int grid = std::clamp(int(std::lround(std::cbrt(double(ordered.size() / 3) / 8))), 4, 32);
        const Eigen::Vector3f size = bounds.sizes().cwiseMax(1e-30f);
        std::vector<std::vector<unsigned>> inCell(size_t(grid * grid * grid));
        for (size_t k = 0; k + 2 < ordered.size(); k += 3) {
            const Eigen::Vector3f centre = (at(ordered[k]) + at(ordered[k + 1]) + at(ordered[k + 2])) / 3;
            int cell = 0;
            for (int c = 0; c < 3; ++c)
                cell = cell * grid + std::clamp(int((centre[c] - bounds.min()[c]) / size[c] * grid), 0, grid - 1);
            inCell[size_t(cell)].insert(inCell[size_t(cell)].end(), &ordered[k], &ordered[k] + 3);
        }
        ordered.clear();
        for (const std::vector<unsigned>& cell : inCell) {
            if (cell.empty()) continue;
            State::Cell c;
            c.first = GLsizei(ordered.size());
            c.count = GLsizei(cell.size());
            for (unsigned v : cell) c.box.extend(at(v));
            ordered.insert(ordered.end(), cell.begin(), cell.end());
            s.cells.push_back(c);
        }
    }
    for (const SceneObject& o : scene.objects) {
        if (scene.materialOf(o).type != MaterialType::Diffuse) continue;
        if (o.type != ShapeType::Quad && o.type != ShapeType::Triangle) continue;
        // A quad a little off its plane (the scene file allows 1%) is drawn bent, not as the plane
        // the buffer would take: only one flat to a millionth of its size hides anything.
        if (o.type == ShapeType::Quad) {
            const std::vector<Vec3>& v = o.vertices;
            const Vec3 n = (v[2] - v[0]).cross(v[3] - v[1]).normalized();
            const double twist = std::abs(n.dot(v[1] - v[0])) + std::abs(n.dot(v[3] - v[0]));
            if (!(twist <= 1e-6 * std::max((v[2] - v[0]).norm(), (v[3] - v[1]).norm()))) continue;
        }
        s.occluders.push_back(o.vertices);
        s.occluderBoxes.emplace_back();
        for (const Vec3& v : o.vertices) s.occluderBoxes.back().extend(v);
    }
    // Each image once, as the ray tracers read it (bilinear between texel centres, the file's wraps),
    // mipmapped for the distance.
    const auto upload = [&](const std::shared_ptr<const Texture>& t) -> GLuint {
        if (!t) return 0;
        if (const auto it = s.textures.find(t.get()); it != s.textures.end()) return it->second;
        std::vector<float> rgb;
        rgb.reserve(size_t(t->width()) * size_t(t->height()) * 3);
        for (int y = 0; y < t->height(); ++y)  // rows from the top: v runs down the image, as t does up the rows
            for (int x = 0; x < t->width(); ++x) {
                const Rgb c = t->texel(x, y);
                rgb.insert(rgb.end(), {float(c[0]), float(c[1]), float(c[2])});
            }
        GLuint name = 0;
        glGenTextures(1, &name);
        glBindTexture(GL_TEXTURE_2D, name);
        glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
        glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, t->width(), t->height(), 0, GL_RGB, GL_FLOAT, rgb.data());
        glGenerateMipmap(GL_TEXTURE_2D);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, glWrap(t->wrapU()));
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, glWrap(t->wrapV()));
        return s.textures[t.get()] = name;
    };
    for (size_t o = 0; o < scene.objects.size(); ++o) {
        if (ofObject[o].empty() || scene.materialOf(scene.objects[o]).type != MaterialType::Diffuse) continue;
        const Material& m = scene.materialOf(scene.objects[o]);
        Textured t;
        t.first = GLsizei(ordered.size());
        t.count = GLsizei(ofObject[o].size());
        t.reflectance = upload(m.reflectanceTexture);
        t.emission = upload(m.emissionTexture);
        t.reflectanceFactor = m.reflectance;
        t.emissionFactor = m.emission;
        ordered.insert(ordered.end(), ofObject[o].begin(), ofObject[o].end());
        s.textured.push_back(t);
    }
    for (size_t o = 0; o < scene.objects.size(); ++o) {
        if (ofObject[o].empty() || scene.materialOf(scene.objects[o]).type == MaterialType::Diffuse) continue;
        Specular sp;
        sp.object = int(o);
        sp.first = GLsizei(ordered.size());
        sp.count = GLsizei(ofObject[o].size());
        Eigen::AlignedBox3d box;
        for (unsigned v : ofObject[o])
            box.extend(Vec3(vertices[kStride * v], vertices[kStride * v + 1], vertices[kStride * v + 2]));
        sp.probeCentre = box.center();
        if (const std::optional<RaySphere> ball = exactSphereOf(scene, scene.objects[o])) {
            sp.sphere = true;
            sp.centre = sp.probeCentre = ball->center;
            sp.radius = ball->radius;
        }
        const Material& m = scene.materialOf(scene.objects[o]);
        sp.glass = m.type == MaterialType::Dielectric;
        sp.tint = sp.glass ? m.transmittance : m.reflectance;
        sp.ior = m.ior;
        ordered.insert(ordered.end(), ofObject[o].begin(), ofObject[o].end());
        s.objects.push_back(sp);
    }

    // A sphere's facets lie inside it: moved out to enclose it (by 1/cos of the widest facet's
    // angular radius), so that the fragments cover the sphere's outline, each finding its point
    // of the sphere (or none: discarded).
    std::vector<float> placed = vertices;
    for (const Specular& sp : s.objects) {
        if (!sp.sphere) continue;
        const auto at = [&](unsigned v) {
            return Vec3(vertices[kStride * v], vertices[kStride * v + 1], vertices[kStride * v + 2]);
        };
        double widest = 0;  // sine of the widest angular radius
        for (GLsizei k = sp.first; k + 2 < sp.first + sp.count; k += 3) {
            const Vec3 a = at(ordered[size_t(k)]), b = at(ordered[size_t(k) + 1]), c = at(ordered[size_t(k) + 2]);
            // The circumradius: |ab| |bc| |ca| / (4 area).
            const double area = 0.5 * (b - a).cross(c - a).norm();
            if (area > 0)
                widest = std::max(widest, (b - a).norm() * (c - b).norm() * (a - c).norm() / (4 * area) / sp.radius);
        }
        const double out = 1 / std::sqrt(std::max(1e-4, 1 - std::min(widest, 1.0) * std::min(widest, 1.0)));
        for (GLsizei k = sp.first; k < sp.first + sp.count; ++k) {
            const unsigned v = ordered[size_t(k)];
            const Vec3 x = sp.centre + out * (at(v) - sp.centre);
            for (int c = 0; c < 3; ++c) placed[kStride * v + unsigned(c)] = float(x[c]);
        }
    }
    glGenBuffers(1, &s.vertexBuffer);
    glBindBuffer(GL_ARRAY_BUFFER, s.vertexBuffer);
    glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(placed.size() * sizeof(float)), placed.data(), GL_STATIC_DRAW);
    const auto vertexArray = [&](const std::vector<unsigned>& indices, GLuint& buffer) {
        GLuint array = 0;
        glGenVertexArrays(1, &array);
        glBindVertexArray(array);
        glBindBuffer(GL_ARRAY_BUFFER, s.vertexBuffer);
        for (GLuint a = 0; a < 4; ++a) {
            glVertexAttribPointer(a, a < 3 ? 3 : 2, GL_FLOAT, GL_FALSE, kStride * sizeof(float),
                                  reinterpret_cast<void*>(3 * a * sizeof(float)));
            glEnableVertexAttribArray(a);
        }
        glGenBuffers(1, &buffer);
        glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, buffer);
        glBufferData(GL_ELEMENT_ARRAY_BUFFER, GLsizeiptr(indices.size() * sizeof(unsigned)), indices.data(),
                     GL_STATIC_DRAW);
        return array;
    };
    s.vao = vertexArray(ordered, s.triangleBuffer);
    s.edgeVao = vertexArray(edges, s.edgeBuffer);
    s.edgeCount = GLsizei(edges.size());
    s.diffuse = gl::program(kVertex, kDiffuseFragment);
    if (!s.textured.empty()) s.texturedProgram = gl::program(kVertex, kTexturedFragment);
    if (!s.objects.empty()) {
        s.specular = gl::program(kVertex, kSpecularFragment);
        glGenSamplers(1, &s.nearest);
        glSamplerParameteri(s.nearest, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        glSamplerParameteri(s.nearest, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    }
}

SceneDraw::~SceneDraw() {
    State& s = *s_;
    for (Specular& sp : s.objects) glDeleteTextures(2, sp.probe.data());
    glDeleteVertexArrays(1, &s.vao);
    glDeleteVertexArrays(1, &s.edgeVao);
    for (GLuint b : {s.vertexBuffer, s.triangleBuffer, s.edgeBuffer}) glDeleteBuffers(1, &b);
    glDeleteProgram(s.diffuse);
    if (s.texturedProgram) glDeleteProgram(s.texturedProgram);
    for (const auto& [texture, name] : s.textures) glDeleteTextures(1, &name);
    if (s.specular) glDeleteProgram(s.specular);
    if (s.nearest) glDeleteSamplers(1, &s.nearest);
}

size_t SceneDraw::probes() const { return s_->objects.size(); }

void SceneDraw::renderProbes() {
    State& s = *s_;
    if (s.objects.empty()) return;
    GLint previous = 0;
    glGetIntegerv(GL_FRAMEBUFFER_BINDING, &previous);
    GLuint fbo = 0, depth = 0;
    glGenFramebuffers(1, &fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glGenRenderbuffers(1, &depth);
    glBindRenderbuffer(GL_RENDERBUFFER, depth);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, kProbeSize, kProbeSize);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth);
    glEnable(GL_TEXTURE_CUBE_MAP_SEAMLESS);
    glViewport(0, 0, kProbeSize, kProbeSize);
    glEnable(GL_DEPTH_TEST);
    // Nothing seen: no light, and farther than any ray is followed.
    const float nothing = float(1e6 * s.sceneSize);
    for (int generation = 0; generation < 2; ++generation)
        for (Specular& sp : s.objects) {
            GLuint& cube = sp.probe[size_t(generation)];
            glGenTextures(1, &cube);
            glBindTexture(GL_TEXTURE_CUBE_MAP, cube);
            for (int f = 0; f < 6; ++f)
                glTexImage2D(GLenum(GL_TEXTURE_CUBE_MAP_POSITIVE_X + f), 0, GL_RGBA32F, kProbeSize, kProbeSize, 0,
                             GL_RGBA, GL_FLOAT, nullptr);
            glTexParameteri(GL_TEXTURE_CUBE_MAP, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
            glTexParameteri(GL_TEXTURE_CUBE_MAP, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
            for (GLenum wrap : {GL_TEXTURE_WRAP_S, GL_TEXTURE_WRAP_T, GL_TEXTURE_WRAP_R})
                glTexParameteri(GL_TEXTURE_CUBE_MAP, wrap, GL_CLAMP_TO_EDGE);
            for (int f = 0; f < 6; ++f) {
                glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GLenum(GL_TEXTURE_CUBE_MAP_POSITIVE_X + f),
                                       cube, 0);
                if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
                    throw Error("view: the OpenGL driver cannot render into a float cube map");
                glClearColor(0, 0, 0, nothing);
                glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
                Camera face;
                face.position = sp.probeCentre;
                const auto& a = kFaces[size_t(f)];
                face.lookAt = sp.probeCentre + Vec3(a[0], a[1], a[2]);
                face.up = Vec3(a[3], a[4], a[5]);
                face.fovYDeg = 90;
                drawAll(gl::viewProjection(face, kProbeSize, kProbeSize, s.sceneSize), sp.probeCentre, sp.object,
                        generation);
            }
        }
    glClearColor(0, 0, 0, 1);
    glBindFramebuffer(GL_FRAMEBUFFER, GLuint(previous));
    glDeleteFramebuffers(1, &fbo);
    glDeleteRenderbuffers(1, &depth);
}

void SceneDraw::draw(const Eigen::Matrix4f& viewProjection, const Vec3& eye) const {
    drawAll(viewProjection, eye, -1, s_->objects.empty() ? 0 : 2);
}

void SceneDraw::drawAll(const Eigen::Matrix4f& viewProjection, const Vec3& eye, int exclude, int probes) const {
    const State& s = *s_;
    glEnable(GL_POLYGON_OFFSET_FILL);
    glPolygonOffset(1, 1);
    if (s.cullBackFaces) glEnable(GL_CULL_FACE);
    glBindVertexArray(s.vao);
    glUseProgram(s.diffuse);
    glUniformMatrix4fv(glGetUniformLocation(s.diffuse, "viewProjection"), 1, GL_FALSE, viewProjection.data());
    glUniform1i(glGetUniformLocation(s.diffuse, "edges"), 0);
    glUniform3f(glGetUniformLocation(s.diffuse, "eye"), float(eye.x()), float(eye.y()), float(eye.z()));
    // The view's planes (Gribb and Hartmann): a cell wholly outside one is out of the view.
    std::array<Eigen::Vector4f, 6> planes;
    for (int r = 0; r < 3; ++r) {
        planes[size_t(2 * r)] = viewProjection.row(3).transpose() + viewProjection.row(r).transpose();
        planes[size_t(2 * r + 1)] = viewProjection.row(3).transpose() - viewProjection.row(r).transpose();
    }
    // Whether a box (a cell's, in floats, or an occluder's, in doubles) is inside all six planes.
    const auto inView = [&](const auto& box) {
        using S = typename std::decay_t<decltype(box)>::Scalar;
        for (const Eigen::Vector4f& p : planes) {
            Eigen::Matrix<S, 3, 1> far;
            for (int k = 0; k < 3; ++k) far[k] = p[k] > 0 ? box.max()[k] : box.min()[k];
            if (!(p.head<3>().template cast<S>().dot(far) + S(p[3]) >= 0)) return false;
        }
        return true;
    };
    std::vector<std::pair<float, const State::Cell*>> shown;
    const Eigen::Vector3f from = eye.cast<float>();
    for (const State::Cell& c : s.cells)
        if (inView(c.box)) shown.emplace_back(c.box.squaredExteriorDistance(from), &c);
    std::sort(shown.begin(), shown.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    std::unique_ptr<OcclusionBuffer> occlusion;
    if (s.occlusionCulling && !s.occluders.empty()) {
        GLint viewport[4];
        glGetIntegerv(GL_VIEWPORT, viewport);
        occlusion = std::make_unique<OcclusionBuffer>(viewProjection.cast<double>(), viewport[2], viewport[3]);
        std::vector<std::pair<double, size_t>> order;
        for (size_t k = 0; k < s.occluders.size(); ++k)
            if (inView(s.occluderBoxes[k])) order.emplace_back(s.occluderBoxes[k].squaredExteriorDistance(eye), k);
        std::sort(order.begin(), order.end());
        for (const auto& [distance, k] : order)  // nearest first: one hidden behind those before adds nothing
            if (!occlusion->hidden(s.occluderBoxes[k])) occlusion->occlude(s.occluders[k], s.cullBackFaces);
    }
    // The cells drawn, nearest first, in one call.
    std::vector<GLsizei> counts;
    std::vector<const void*> firsts;
    for (const auto& [distance, c] : shown) {
        if (occlusion && occlusion->hidden(c->box.cast<double>())) continue;
        counts.push_back(c->count);
        firsts.push_back(reinterpret_cast<const void*>(size_t(c->first) * sizeof(unsigned)));
    }
    s.cellsInView = shown.size(), s.cellsDrawn = counts.size();
    if (!counts.empty())
        glMultiDrawElements(GL_TRIANGLES, counts.data(), GL_UNSIGNED_INT, firsts.data(), GLsizei(counts.size()));
    if (!s.textured.empty()) {
        const GLuint p = s.texturedProgram;
        glUseProgram(p);
        glUniformMatrix4fv(glGetUniformLocation(p, "viewProjection"), 1, GL_FALSE, viewProjection.data());
        glUniform3f(glGetUniformLocation(p, "eye"), float(eye.x()), float(eye.y()), float(eye.z()));
        glUniform1i(glGetUniformLocation(p, "reflectanceTexture"), 0);
        glUniform1i(glGetUniformLocation(p, "emissionTexture"), 1);
        for (const Textured& t : s.textured) {
            glActiveTexture(GL_TEXTURE0);
            glBindTexture(GL_TEXTURE_2D, t.reflectance);
            glActiveTexture(GL_TEXTURE1);
            glBindTexture(GL_TEXTURE_2D, t.emission);
            glBindSampler(1, 0);
            glUniform1i(glGetUniformLocation(p, "textures"), (t.reflectance ? 1 : 0) + (t.emission ? 2 : 0));
            const Rgb& r = t.reflectanceFactor;
            const Rgb& e = t.emissionFactor;
            glUniform3f(glGetUniformLocation(p, "reflectance"), float(r[0]), float(r[1]), float(r[2]));
            glUniform3f(glGetUniformLocation(p, "emission"), float(e[0]), float(e[1]), float(e[2]));
            glDrawElements(GL_TRIANGLES, t.count, GL_UNSIGNED_INT,
                           reinterpret_cast<const void*>(size_t(t.first) * sizeof(unsigned)));
        }
        glActiveTexture(GL_TEXTURE0);
        glUseProgram(s.diffuse);
    }
    for (const Specular& sp : s.objects) {
        if (sp.object == exclude) continue;
        const void* first = reinterpret_cast<const void*>(size_t(sp.first) * sizeof(unsigned));
        if (probes == 0) {  // black, as their patches' radiance is
            glDrawElements(GL_TRIANGLES, sp.count, GL_UNSIGNED_INT, first);
            continue;
        }
        const GLuint p = s.specular;
        glUseProgram(p);
        glUniformMatrix4fv(glGetUniformLocation(p, "viewProjection"), 1, GL_FALSE, viewProjection.data());
        glUniform3f(glGetUniformLocation(p, "eye"), float(eye.x()), float(eye.y()), float(eye.z()));
        glActiveTexture(GL_TEXTURE0);
        glBindTexture(GL_TEXTURE_CUBE_MAP, sp.probe[size_t(probes - 1)]);
        glUniform1i(glGetUniformLocation(p, "probe"), 0);
        glActiveTexture(GL_TEXTURE1);
        glBindTexture(GL_TEXTURE_CUBE_MAP, sp.probe[size_t(probes - 1)]);
        glBindSampler(1, s.nearest);
        glUniform1i(glGetUniformLocation(p, "probeNearest"), 1);
        glActiveTexture(GL_TEXTURE0);
        const Vec3& c = sp.probeCentre;
        glUniform3f(glGetUniformLocation(p, "probeCentre"), float(c.x()), float(c.y()), float(c.z()));
        glUniform1f(glGetUniformLocation(p, "reach"), float(s.sceneSize));
        glUniform1i(glGetUniformLocation(p, "glass"), sp.glass ? 1 : 0);
        glUniform3f(glGetUniformLocation(p, "tint"), float(sp.tint[0]), float(sp.tint[1]), float(sp.tint[2]));
        glUniform1f(glGetUniformLocation(p, "ior"), float(sp.ior));
        glUniform1i(glGetUniformLocation(p, "sphere"), sp.sphere ? 1 : 0);
        glUniform3f(glGetUniformLocation(p, "centre"), float(sp.centre.x()), float(sp.centre.y()),
                    float(sp.centre.z()));
        glUniform1f(glGetUniformLocation(p, "radius"), float(sp.radius));
        // A ball's far side is hidden by its near side: not shaded at all (its shading is the cost).
        if (sp.sphere) glEnable(GL_CULL_FACE);
        glDrawElements(GL_TRIANGLES, sp.count, GL_UNSIGNED_INT, first);
        if (sp.sphere && !s.cullBackFaces) glDisable(GL_CULL_FACE);
        glUseProgram(s.diffuse);
    }
    glDisable(GL_CULL_FACE);
    glDisable(GL_POLYGON_OFFSET_FILL);
}

void SceneDraw::setOcclusionCulling(bool on) { s_->occlusionCulling = on; }

std::pair<size_t, size_t> SceneDraw::cellsInViewAndDrawn() const { return {s_->cellsInView, s_->cellsDrawn}; }

void SceneDraw::drawEdges(const Eigen::Matrix4f& viewProjection) const {
    const State& s = *s_;
    glUseProgram(s.diffuse);
    glUniformMatrix4fv(glGetUniformLocation(s.diffuse, "viewProjection"), 1, GL_FALSE, viewProjection.data());
    glUniform1i(glGetUniformLocation(s.diffuse, "edges"), 1);
    glBindVertexArray(s.edgeVao);
    glDrawElements(GL_LINES, s.edgeCount, GL_UNSIGNED_INT, nullptr);
}

}  // namespace penumbra
