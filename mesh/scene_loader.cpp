// Scene JSON -> Scene, with every check the contract asks for. Each error names the file, the
// object (by index and name) or field, and what was expected; nothing is written before this ends.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <vector>

#include "core/error.h"
#include "core/image_file.h"
#include "core/log.h"
#include "mesh/gltf_scene.h"
#include "mesh/mesh_file.h"
#include "mesh/obj_scene.h"
#include "mesh/scene.h"
#include "mesh/scene_detail.h"

namespace penumbra {
namespace scene_detail {

uint64_t fnv1a(const std::string& bytes, uint64_t h) {
    for (unsigned char c : bytes) h = (h ^ c) * 1099511628211ull;
    return h;
}

std::string readFile(const std::string& path, const std::string& what) {
    namespace fs = std::filesystem;
    std::error_code ec;
    const fs::file_status status = fs::status(path, ec);
    if (ec) throw Error(cat(path, ": cannot open the ", what, ": ", ec.message()));
    if (fs::is_directory(status)) throw Error(cat(path, ": is a folder, not a ", what));
    if (!fs::is_regular_file(status))
        throw Error(cat(path, ": is not a regular file (a device, pipe or socket), so not read as a ", what));
    const uintmax_t size = fs::file_size(path, ec);
    if (!ec && size > kMaxFileBytes)
        throw Error(cat(path, ": ", size, " bytes, more than a ", what, " may hold (", kMaxFileBytes, ")"));
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(cat(path, ": cannot open the ", what));
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

void checkCoordinate(const Vec3& p, double metres, const Where& w) {
    // A NaN passes the comparison below, and one in every vertex left the scene's box empty (found
    // by fuzz_import: an infinite extent).
    if (!p.allFinite()) w.fail(cat("coordinate (", p.x(), ", ", p.y(), ", ", p.z(), ") is not a finite number"));
    if (p.cwiseAbs().maxCoeff() * metres > kAbsurdMetres) {
        const Vec3 m = p * metres;
        w.fail(cat("coordinate (", m.x(), ", ", m.y(), ", ", m.z(), ") m lies more than ", kAbsurdMetres,
                   " m from the origin: check unit_scale"));
    }
}

void checkQuad(const std::vector<Vec3>& v, const Where& w) {
    const double diag = std::max((v[2] - v[0]).norm(), (v[3] - v[1]).norm());
    const Vec3 n = (v[1] - v[0]).cross(v[2] - v[0]);
    const Vec3 n2 = (v[2] - v[0]).cross(v[3] - v[0]);
    if (diag == 0 || n.norm() <= 1e-12 * diag * diag || n2.norm() <= 1e-12 * diag * diag)
        w.fail("degenerate quad: three of its vertices are collinear or coincide");
    const double off = std::abs(n.normalized().dot(v[3] - v[0]));
    if (off > 0.01 * diag)
        w.fail(cat("quad is not planar: its fourth vertex lies ", 100 * off / diag,
                   "% of the longest diagonal off the plane of the first three (at most 1%)"));
    // Every corner must turn the same way: a bow-tie or a dart would fold its patches.
    const Vec3 ref = n + n2;
    for (int k = 0; k < 4; ++k) {
        const Vec3 e0 = v[(k + 1) % 4] - v[k], e1 = v[(k + 2) % 4] - v[(k + 1) % 4];
        if (e0.cross(e1).dot(ref) <= 0) w.fail("quad is not convex (or its vertices are not in order around it)");
    }
}

void checkTriangle(const std::vector<Vec3>& v, const Where& w) {
    const double edge = std::max({(v[1] - v[0]).norm(), (v[2] - v[1]).norm(), (v[0] - v[2]).norm()});
    const double area2 = (v[1] - v[0]).cross(v[2] - v[0]).norm();
    if (edge == 0 || area2 <= 1e-12 * edge * edge) w.fail("zero-area triangle: its vertices are collinear or coincide");
}

void normaliseLengths(Scene& scene, const Where& top) {
    Eigen::AlignedBox3d box;
    for (const SceneObject& o : scene.objects) {
        for (const Vec3& v : o.vertices) box.extend(v);
        for (const Vec3& v : o.mesh.vertices) box.extend(v);
        if (o.type == ShapeType::Sphere) {
            const double r = o.radius * o.toWorld.linear().norm();  // at least the sphere's, at most 3x
            box.extend(o.toWorld * o.center + Vec3::Constant(r));
            box.extend(o.toWorld * o.center - Vec3::Constant(r));
        }
    }
    const double across = box.diagonal().norm(), metres = across * scene.metresPerUnit;
    if (!(metres >= 1e-100))
        top.fail(cat("the scene is ", metres,
                     " m across: below 1e-100 m its areas and powers leave double "
                     "precision; check unit_scale"));
    // Also above: 1e100 m squared is still a double, and the extent itself must be one (coordinates
    // near the largest double have a difference that is not).
    if (!(metres <= 1e100) || !(across <= 0x1p1000))
        top.fail(cat("the scene is ", metres,
                     " m across: above 1e100 m its areas and powers leave double "
                     "precision; check unit_scale and the vertices' coordinates"));
    if (metres >= 0x1p-10 && metres <= 0x1p20) return;
    const double s = std::ldexp(1.0, std::ilogb(across) + 1);  // inside: [0.5, 1) units across
    const Eigen::Affine3d shrink(Eigen::Scaling(1 / s));
    for (SceneObject& o : scene.objects) {
        for (Vec3& v : o.vertices) v /= s;
        for (Vec3& v : o.mesh.vertices) v /= s;
        o.toWorld = shrink * o.toWorld;
    }
    scene.metresPerUnit *= s;
}

namespace {

// Two triangles that share an edge and together make a planar convex quad, as that quad's corners
// in order (an exporter's split of a quad face); else empty.
std::vector<Vec3> quadOf(const std::vector<Vec3>& t) {
    if (t.size() != 6) return {};
    for (int r = 0; r < 3; ++r) {
        // First triangle rotated to (a, b, c); the second must hold c and a (reversed) and one more.
        const Vec3 &a = t[size_t(r)], &b = t[size_t((r + 1) % 3)], &c = t[size_t((r + 2) % 3)];
        for (int s = 0; s < 3; ++s) {
            const Vec3 &p = t[size_t(3 + s)], &q = t[size_t(3 + (s + 1) % 3)], &d = t[size_t(3 + (s + 2) % 3)];
            if (p == a && q == c) {
                std::vector<Vec3> quad{a, b, c, d};
                try {
                    checkQuad(quad, Where{"", ""});
                } catch (const Error&) {
                    return {};
                }
                return quad;
            }
        }
    }
    return {};
}

}  // namespace

bool hasExtension(const std::string& path, std::initializer_list<const char*> extensions) {
    const std::string ext = lowerExtension(path);
    for (const char* e : extensions)
        if (ext == e) return true;
    return false;
}

std::string uniqueName(const std::string& wanted, std::set<std::string>& names, std::vector<std::string>& renamed) {
    std::string name = wanted;
    for (int k = 2; !names.insert(name).second; ++k) name = cat(wanted, "-", k);
    if (name != wanted) renamed.push_back(cat("'", wanted, "' as '", name, "'"));
    return name;
}

void logImport(const std::string& path, const std::vector<std::string>& renamed, const std::set<std::string>& notes) {
    if (!renamed.empty()) {
        std::string list;
        for (const std::string& r : renamed) list += cat(list.empty() ? "" : ", ", r);
        logInfo(path, ": objects named alike are told apart: ", list);
    }
    for (const std::string& note : notes) logInfo(path, ": ", note);
}

void shapeFromSoup(SceneObject& o, PolygonSoup soup, const std::string& file, const Where& w) {
    std::vector<Vec3> corners;
    for (const auto& f : soup.faces)
        for (int v : f) corners.push_back(soup.vertices[size_t(v)]);
    const bool oneFace = soup.faces.size() == 1;
    std::vector<Vec3> quad = oneFace && corners.size() == 4 ? corners : quadOf(corners);
    if (!quad.empty() && oneFace) {
        try {
            checkQuad(quad, Where{"", ""});
        } catch (const Error&) {
            quad.clear();
        }
    }
    // Texture coordinates of the shape's corners: those of the soup's corner at the same point.
    const auto cornerUv = [&](const std::vector<Vec3>& shape) {
        std::vector<Vec2> uv;
        if (soup.faceUv.empty()) return uv;
        for (const Vec3& p : shape) {
            const size_t before = uv.size();
            for (size_t f = 0; f < soup.faces.size() && uv.size() == before; ++f)
                for (size_t k = 0; k < soup.faces[f].size(); ++k)
                    if (soup.vertices[size_t(soup.faces[f][k])] == p) {
                        uv.push_back(soup.faceUv[f][k]);
                        break;
                    }
        }
        if (uv.size() != shape.size()) uv.clear();
        return uv;
    };
    if (oneFace && corners.size() == 3) {
        o.type = ShapeType::Triangle;
        o.vertices = corners;
        checkTriangle(o.vertices, w);
        o.uv = cornerUv(o.vertices);
    } else if (!quad.empty()) {
        o.type = ShapeType::Quad;
        o.vertices = quad;
        o.uv = cornerUv(o.vertices);
    } else {
        o.type = ShapeType::Mesh;
        o.mesh = std::move(soup);
        o.file = file;
    }
}

}  // namespace scene_detail

namespace {

using namespace scene_detail;

using Json = nlohmann::json;

// Radiance beyond this, W sr^-1 m^-2: the sun's is about 2e7.
constexpr double kAbsurdRadiance = 1e20;

bool ignoredKey(const std::string& key) { return key == "comment" || (!key.empty() && key[0] == '_'); }

// The first key that an object of `text` (JSON the parser accepted) holds twice, with the lines of
// both, as "key 'white' on lines 3 and 7"; empty if none. The parser keeps the last silently: two
// "white" materials, or a second "objects": [] that emptied the scene.
std::string duplicateKey(const std::string& text) {
    struct Level {
        bool object;
        std::map<std::string, size_t> keys;  // key -> line
        bool expectKey;
    };
    std::vector<Level> stack;
    size_t line = 1;
    for (size_t i = 0; i < text.size(); ++i) {
        const char c = text[i];
        if (c == '\n') {
            ++line;
        } else if (c == '{' || c == '[') {
            stack.push_back({c == '{', {}, c == '{'});
        } else if (c == '}' || c == ']') {
            if (!stack.empty()) stack.pop_back();
        } else if (c == ',') {
            if (!stack.empty() && stack.back().object) stack.back().expectKey = true;
        } else if (c == '"') {
            std::string value;
            const size_t at = line;
            for (++i; i < text.size() && text[i] != '"'; ++i) {
                if (text[i] == '\\' && i + 1 < text.size()) value += text[i++];
                value += text[i];
            }
            if (!stack.empty() && stack.back().object && stack.back().expectKey) {
                stack.back().expectKey = false;
                const auto [it, fresh] = stack.back().keys.emplace(value, at);
                if (!fresh && !ignoredKey(value)) return cat("key '", value, "' on lines ", it->second, " and ", at);
            }
        }
    }
    return "";
}

// The scene JSON as it bears on a solve: without the camera and the ignored keys ("_..." and "comment"), for
// Scene::fingerprint in nlohmann's canonical form (keys sorted, numbers as parsed).
Json solveRelevant(const Json& j, bool top) {
    if (j.is_object()) {
        Json out = Json::object();
        for (const auto& [key, value] : j.items())
            if (!(ignoredKey(key) || (top && key == "camera"))) out[key] = solveRelevant(value, false);
        return out;
    }
    if (j.is_array()) {
        Json out = Json::array();
        for (const Json& v : j) out.push_back(solveRelevant(v, false));
        return out;
    }
    return j;
}

void checkKeys(const Json& j, const Where& w, std::initializer_list<const char*> allowed) {
    if (!j.is_object()) w.fail(cat("expected a JSON object, got ", j.type_name()));
    for (const auto& item : j.items()) {
        if (ignoredKey(item.key())) continue;
        bool known = false;
        for (const char* a : allowed) known = known || item.key() == a;
        if (!known) {
            std::string list;
            for (const char* a : allowed) list += cat(list.empty() ? "" : ", ", a);
            w.fail(cat("unknown key '", item.key(), "' (expected one of: ", list, ")"));
        }
    }
}

const Json& require(const Json& j, const char* key, const Where& w) {
    auto it = j.find(key);
    if (it == j.end()) w.fail(cat("missing required field '", key, "'"));
    return *it;
}

double number(const Json& j, const Where& w) {
    if (!j.is_number()) w.fail(cat("expected a number, got ", j.type_name()));
    const double v = j.get<double>();
    if (!std::isfinite(v)) w.fail("expected a finite number");
    return v;
}

Vec3 vec3(const Json& j, const Where& w) {
    if (!j.is_array() || j.size() != 3) w.fail("expected an array of three numbers");
    return Vec3(number(j[0], w.index(0)), number(j[1], w.index(1)), number(j[2], w.index(2)));
}

Rgb rgb(const Json& j, const Where& w) {
    if (j.is_number()) {
        const double v = number(j, w);
        return Rgb(v, v, v);
    }
    if (!j.is_array() || j.size() != 3) w.fail("expected an RGB array of three numbers");
    return Rgb(number(j[0], w.index(0)), number(j[1], w.index(1)), number(j[2], w.index(2)));
}

Rgb unitRgb(const Json& j, const Where& w) {
    const Rgb v = rgb(j, w);
    for (int c = 0; c < 3; ++c)
        if (v[c] < 0 || v[c] > 1) w.fail(cat("each channel must lie in [0, 1], got ", exact(v[c])));
    return v;
}

// A material's texture file (mesh/texture.h), named relative to the scene file; its texels join the
// scene's fingerprint. Reflectance textures must hold values in [0, 1].
std::shared_ptr<const Texture> parseTexture(const Json& j, const std::filesystem::path& sceneDir, bool reflectance,
                                            uint64_t& fingerprint, const Where& w) {
    if (!j.is_string() || j.get<std::string>().empty()) w.fail("expected the path of an image file");
    const std::string file = (sceneDir / j.get<std::string>()).string();
    std::shared_ptr<const Texture> t;
    try {
        t = readTextureFile(file);
    } catch (const Error& e) {
        w.fail(e.what());
    }
    if (reflectance && t->maximum() > 1)
        w.fail(cat(file, ": a reflectance texture's values must lie in [0, 1], it holds ", t->maximum()));
    for (int y = 0; y < t->height(); ++y)
        for (int x = 0; x < t->width(); ++x) {
            const Rgb v = t->texel(x, y);
            fingerprint = fnv1a(std::string(reinterpret_cast<const char*>(v.data()), sizeof(double) * 3), fingerprint);
        }
    return t;
}

Material parseMaterial(const std::string& name, const Json& j, const std::filesystem::path& sceneDir,
                       uint64_t& fingerprint, const Where& w) {
    Material m;
    m.name = name;
    if (!j.is_object())
        w.fail(cat("expected a material object such as {\"type\": \"diffuse\", \"reflectance\": 0.5}, got a ",
                   j.type_name()));
    const Json& type = require(j, "type", w);
    if (!type.is_string()) w.at("type").fail("expected a string");
    const std::string t = type.get<std::string>();
    if (t == "diffuse") {
        checkKeys(j, w, {"type", "reflectance", "emission", "reflectance_texture", "emission_texture", "double_sided"});
        m.type = MaterialType::Diffuse;
        if (j.contains("reflectance_texture"))
            m.reflectanceTexture =
                parseTexture(j["reflectance_texture"], sceneDir, true, fingerprint, w.at("reflectance_texture"));
        // With a texture the factor is optional (1: the texture alone).
        m.reflectance = m.reflectanceTexture && !j.contains("reflectance")
                            ? Rgb::Ones()
                            : unitRgb(require(j, "reflectance", w), w.at("reflectance"));
        if (j.contains("emission_texture")) {
            if (!j.contains("emission"))
                w.at("emission_texture").fail("needs \"emission\", the radiance it multiplies");
            m.emissionTexture =
                parseTexture(j["emission_texture"], sceneDir, false, fingerprint, w.at("emission_texture"));
        }
        if (j.contains("emission")) {
            m.emission = rgb(j["emission"], w.at("emission"));
            if ((m.emission < 0).any()) w.at("emission").fail("emission radiance must not be negative");
            // Light of 1e300 overflowed to infinite pixels without a word. Past 1e20 W sr^-1 m^-2 (a
            // hundred million suns) the solve's sums in double lose their digits too.
            if ((m.emission > kAbsurdRadiance).any())
                w.at("emission")
                    .fail(cat("emission radiance above ", kAbsurdRadiance,
                              " W sr^-1 m^-2 is taken as a unit mistake, not a lamp"));
        }
    } else if (t == "mirror") {
        checkKeys(j, w, {"type", "reflectance", "double_sided"});
        m.type = MaterialType::Mirror;
        m.reflectance = j.contains("reflectance") ? unitRgb(j["reflectance"], w.at("reflectance")) : Rgb::Ones();
    } else if (t == "dielectric") {
        checkKeys(j, w, {"type", "ior", "transmittance"});
        m.type = MaterialType::Dielectric;
        m.ior = number(require(j, "ior", w), w.at("ior"));
        if (!(m.ior > 0) || m.ior > 10) w.at("ior").fail(cat("index of refraction must lie in (0, 10], got ", m.ior));
        if (j.contains("transmittance")) m.transmittance = unitRgb(j["transmittance"], w.at("transmittance"));
    } else {
        w.at("type").fail(cat("unknown material type '", t, "' (expected diffuse, mirror or dielectric)"));
    }
    if (j.contains("double_sided")) {
        if (!j["double_sided"].is_boolean()) w.at("double_sided").fail("expected true or false");
        m.doubleSided = j["double_sided"].get<bool>();
    }
    return m;
}

// "uv": [[u, v], ...], one pair per vertex.
std::vector<Vec2> textureCoordinates(const Json& j, size_t count, const Where& w) {
    if (!j.is_array() || j.size() != count) w.fail(cat("expected ", count, " [u, v] pairs, one per vertex"));
    std::vector<Vec2> out;
    for (size_t k = 0; k < count; ++k) {
        const Json& p = j[k];
        if (!p.is_array() || p.size() != 2) w.index(k).fail("expected [u, v]");
        out.emplace_back(number(p[0], w.index(k).index(0)), number(p[1], w.index(k).index(1)));
    }
    return out;
}

Eigen::Affine3d parseTransform(const Json& j, const Where& w) {
    checkKeys(j, w, {"scale", "rotate_deg", "translate"});
    Vec3 scale(1, 1, 1), rot(0, 0, 0), tr(0, 0, 0);
    if (j.contains("scale")) {
        if (j["scale"].is_number()) {
            const double s = number(j["scale"], w.at("scale"));
            scale = Vec3(s, s, s);
        } else {
            scale = vec3(j["scale"], w.at("scale"));
        }
        for (int k = 0; k < 3; ++k)
            if (scale[k] == 0) w.at("scale").fail("a scale component is zero: the object would collapse");
    }
    if (j.contains("rotate_deg")) rot = vec3(j["rotate_deg"], w.at("rotate_deg"));
    if (j.contains("translate")) tr = vec3(j["translate"], w.at("translate"));
    const double d = kPi / 180;
    // Scale first, then rotations about x, then y, then z, then translation.
    Eigen::Affine3d t = Eigen::Affine3d::Identity();
    t.translate(tr);
    t.rotate(Eigen::AngleAxisd(rot.z() * d, Vec3::UnitZ()));
    t.rotate(Eigen::AngleAxisd(rot.y() * d, Vec3::UnitY()));
    t.rotate(Eigen::AngleAxisd(rot.x() * d, Vec3::UnitX()));
    t.scale(scale);
    return t;
}

std::vector<Vec3> polygon(const Json& j, size_t count, const Eigen::Affine3d& toWorld, double metres, const Where& w) {
    if (!j.is_array() || j.size() != count) w.fail(cat("expected an array of ", count, " vertices [x, y, z]"));
    std::vector<Vec3> v;
    for (size_t k = 0; k < count; ++k) {
        v.push_back(toWorld * vec3(j[k], w.index(k)));
        checkCoordinate(v.back(), metres, w.index(k));
    }
    return v;
}

Camera parseCameraJson(const Json& j, const Scene& scene, const Where& w) {
    checkKeys(j, w, {"position", "look_at", "up", "fov_y_deg", "resolution"});
    Camera c;
    c.position = scene.sceneUnit() * vec3(require(j, "position", w), w.at("position"));
    c.lookAt = scene.sceneUnit() * vec3(require(j, "look_at", w), w.at("look_at"));
    if (j.contains("up")) c.up = vec3(j["up"], w.at("up"));
    if (j.contains("fov_y_deg")) c.fovYDeg = number(j["fov_y_deg"], w.at("fov_y_deg"));
    checkCoordinate(c.position, scene.metresPerUnit, w.at("position"));
    const Vec3 forward = c.lookAt - c.position;
    if (forward.norm() == 0) w.at("look_at").fail("look_at equals position: the camera has no direction");
    if (c.up.norm() == 0 || forward.normalized().cross(c.up.normalized()).norm() < 1e-6)
        w.at("up").fail("up is zero or parallel to the viewing direction");
    if (!(c.fovYDeg > 0 && c.fovYDeg < 180))
        w.at("fov_y_deg").fail(cat("expected a field of view in (0, 180) degrees, got ", c.fovYDeg));
    if (j.contains("resolution")) {
        const Json& r = j["resolution"];
        const Where wr = w.at("resolution");
        if (!r.is_array() || r.size() != 2 || !r[0].is_number_integer() || !r[1].is_number_integer())
            wr.fail("expected [width, height] as two integers");
        // Read wide, then bounded: as int, 4294967328 wrapped to 32 and 2^64 - 1 read as -1.
        auto side = [&](const Json& v) {
            return v.is_number_unsigned() ? std::to_string(v.get<uint64_t>()) : std::to_string(v.get<int64_t>());
        };
        const auto inRange = [](const Json& v) {
            return v.is_number_unsigned() ? v.get<uint64_t>() >= 1 && v.get<uint64_t>() <= 16384
                                          : v.get<int64_t>() >= 1 && v.get<int64_t>() <= 16384;
        };
        if (!inRange(r[0]) || !inRange(r[1]))
            wr.fail(cat("width and height must lie in [1, 16384], got ", side(r[0]), "x", side(r[1])));
        c.width = int(r[0].get<int64_t>());
        c.height = int(r[1].get<int64_t>());
    }
    return c;
}

}  // namespace

bool Scene::hasEmitter() const {
    for (const auto& o : objects)
        if (materialOf(o).emits()) return true;
    return false;
}

bool Scene::hasSpecular() const {
    for (const auto& o : objects)
        if (materialOf(o).type != MaterialType::Diffuse) return true;
    return false;
}

bool Scene::hasTextures() const {
    for (const auto& o : objects)
        if (materialOf(o).textured()) return true;
    return false;
}

Camera parseCamera(const std::string& text, const Scene& scene, const std::string& where) {
    Json j;
    try {
        j = Json::parse(text);
    } catch (const Json::parse_error& e) {
        throw Error(cat(where, ": not valid JSON: ", e.what()));
    } catch (const Json::out_of_range&) {  // a literal beyond double precision, such as 1e999
        throw Error(cat(where, ": a number beyond double precision (numbers must be finite)"));
    }
    return parseCameraJson(j, scene, Where{where, ""});
}

namespace {

// Our JSON scene file (shared/CONTRACT.md).
Scene loadJsonScene(const std::string& path) {
    const std::string text = readFile(path, "scene file");
    Json root;
    try {
        root = Json::parse(text);
    } catch (const Json::parse_error& e) {
        size_t line = 1, col = 1;
        for (size_t i = 0; i + 1 < e.byte && i < text.size(); ++i) {
            if (text[i] == '\n')
                ++line, col = 1;
            else
                ++col;
        }
        std::string what = e.what();
        const auto p = what.find("syntax error");
        throw Error(
            cat(path, ":", line, ":", col, ": malformed JSON: ", p == std::string::npos ? what : what.substr(p)));
    } catch (const Json::out_of_range& e) {
        // The parser's only range error: a literal beyond double precision, such as 1e999.
        // The parser gives no position for it: the first line holding the literal it names.
        std::string what = e.what();
        const auto p = what.find("number overflow");
        std::string where = path;
        if (const auto q = what.find("parsing '"); q != std::string::npos) {
            const std::string literal = what.substr(q + 9, what.find('\'', q + 9) - q - 9);
            if (const auto at = text.find(literal); !literal.empty() && at != std::string::npos)
                where = cat(path, ":", 1 + std::count(text.begin(), text.begin() + long(at), '\n'));
        }
        throw Error(cat(where, ": malformed JSON: ", p == std::string::npos ? what : what.substr(p),
                        " (numbers must be finite)"));
    }
    if (const std::string twice = duplicateKey(text); !twice.empty())
        throw Error(cat(path, ": ", twice, " of one object: each key may appear once"));
    const Where top{path, ""};
    checkKeys(root, top, {"unit_scale", "materials", "objects", "camera"});

    Scene scene;
    scene.path = path;
    scene.fingerprint = fnv1a(solveRelevant(root, true).dump());
    scene.fileFingerprint = fnv1a(text);
    if (root.contains("unit_scale")) {
        scene.unitScale = number(root["unit_scale"], top.at("unit_scale"));
        if (!(scene.unitScale > 0)) top.at("unit_scale").fail("must be positive");
    }
    // A unit far from a metre is taken out first as a power of two (Scene::metresPerUnit), so that
    // the checks below see ordinary numbers (a unit_scale of 1e-300 made every quad "collinear").
    if (scene.unitScale < 0x1p-40 || scene.unitScale > 0x1p40)
        scene.metresPerUnit = std::ldexp(1.0, std::ilogb(scene.unitScale));

    const Json& mats = require(root, "materials", top);
    if (!mats.is_object()) top.at("materials").fail("expected an object mapping names to materials");
    const std::filesystem::path sceneDir = std::filesystem::path(path).parent_path();
    for (const auto& item : mats.items()) {
        if (ignoredKey(item.key())) continue;
        scene.materials.push_back(
            parseMaterial(item.key(), item.value(), sceneDir, scene.fingerprint, top.at("materials").at(item.key())));
    }
    for (const Material& m : scene.materials)
        if (m.textured()) {  // the textures' texels, already in the fingerprint
            scene.fileFingerprint = fnv1a(std::to_string(scene.fingerprint), scene.fileFingerprint);
            break;
        }

    const Json& objs = require(root, "objects", top);
    if (!objs.is_array()) top.at("objects").fail("expected an array of objects");
    std::set<std::string> names;
    for (size_t i = 0; i < objs.size(); ++i) {
        const Json& j = objs[i];
        std::string name;
        if (j.is_object() && j.contains("name") && j["name"].is_string()) name = j["name"].get<std::string>();
        const Where w = top.at("objects").index(i, name);
        if (!j.is_object()) w.fail("expected an object");
        if (!j.contains("name")) w.fail("missing required field 'name'");
        if (!j["name"].is_string() || name.empty()) w.at("name").fail("expected a non-empty string");
        if (!names.insert(name).second) w.at("name").fail(cat("duplicate object name '", name, "'"));

        SceneObject o;
        o.name = name;
        const Json& type = require(j, "type", w);
        if (!type.is_string()) w.at("type").fail("expected a string");
        const std::string t = type.get<std::string>();
        // A mesh of a glTF or OBJ file may keep the file's own materials instead of naming one.
        const bool fromFile = t == "mesh" && j.contains("materials");
        if (fromFile) {
            if (!j["materials"].is_string() || j["materials"].get<std::string>() != "from-file")
                w.at("materials").fail("expected \"from-file\" (the file's own materials), or give \"material\"");
            if (j.contains("material")) w.fail("give either \"material\" or \"materials\": \"from-file\", not both");
        } else {
            const Json& matName = require(j, "material", w);
            if (!matName.is_string()) w.at("material").fail("expected a material name");
            for (size_t m = 0; m < scene.materials.size(); ++m)
                if (scene.materials[m].name == matName.get<std::string>()) o.material = int(m);
            if (o.material < 0) w.at("material").fail(cat("unknown material '", matName.get<std::string>(), "'"));
        }

        const Eigen::Affine3d scale(Eigen::Scaling(scene.sceneUnit()));
        o.toWorld = scale * (j.contains("transform") ? parseTransform(j["transform"], w.at("transform"))
                                                     : Eigen::Affine3d::Identity());
        if (t == "quad") {
            checkKeys(j, w, {"name", "type", "material", "vertices", "transform", "uv"});
            o.type = ShapeType::Quad;
            o.vertices = polygon(require(j, "vertices", w), 4, o.toWorld, scene.metresPerUnit, w.at("vertices"));
            checkQuad(o.vertices, w.at("vertices"));
            o.uv = j.contains("uv") ? textureCoordinates(j["uv"], 4, w.at("uv"))
                                    : std::vector<Vec2>{Vec2(0, 0), Vec2(1, 0), Vec2(1, 1), Vec2(0, 1)};
        } else if (t == "triangle") {
            checkKeys(j, w, {"name", "type", "material", "vertices", "transform", "uv"});
            o.type = ShapeType::Triangle;
            o.vertices = polygon(require(j, "vertices", w), 3, o.toWorld, scene.metresPerUnit, w.at("vertices"));
            checkTriangle(o.vertices, w.at("vertices"));
            o.uv = j.contains("uv") ? textureCoordinates(j["uv"], 3, w.at("uv"))
                                    : std::vector<Vec2>{Vec2(0, 0), Vec2(1, 0), Vec2(0, 1)};
        } else if (t == "sphere") {
            checkKeys(j, w, {"name", "type", "material", "center", "radius", "transform"});
            o.type = ShapeType::Sphere;
            o.center = vec3(require(j, "center", w), w.at("center"));
            o.radius = number(require(j, "radius", w), w.at("radius"));
            if (!(o.radius > 0)) w.at("radius").fail(cat("radius must be positive, got ", o.radius));
            checkCoordinate(o.toWorld * o.center, scene.metresPerUnit, w.at("center"));
            if (o.radius * scene.unitScale > kAbsurdMetres)
                w.at("radius").fail("radius is absurdly large: check unit_scale");
        } else if (t == "mesh") {
            checkKeys(j, w, {"name", "type", "material", "materials", "file", "transform"});
            o.type = ShapeType::Mesh;
            const Json& file = require(j, "file", w);
            if (!file.is_string()) w.at("file").fail("expected a path");
            o.file = (sceneDir / file.get<std::string>()).string();
            // The file's bytes into the fingerprints, once it has been read (and its errors named).
            const auto fingerprint = [&] {
                const std::string bytes = readFile(o.file, "mesh file");
                scene.fingerprint = fnv1a(bytes, scene.fingerprint);
                scene.fileFingerprint = fnv1a(bytes, scene.fileFingerprint);
            };
            const bool gltf = isGltfPath(o.file);
            if (fromFile && !gltf && !isObjPath(o.file))
                w.at("materials")
                    .fail("\"from-file\" needs a glTF (.glb, .gltf) or OBJ file, whose materials it takes");
            if (fromFile) {
                // The file's objects, each with its material, named "<this object>/<the file's name>"
                // (and its materials "<this object>/<material>"), in the scene's units, as every mesh
                // file is, with this object's transform.
                const Scene parts = gltf ? readGltfScene(o.file) : readObjScene(o.file);
                const int firstMaterial = int(scene.materials.size());
                for (Material m : parts.materials) {
                    m.name = cat(name, "/", m.name);
                    scene.materials.push_back(std::move(m));
                }
                for (SceneObject part : parts.objects) {
                    part.name = cat(name, "/", part.name);
                    if (!names.insert(part.name).second)
                        w.fail(cat("its part '", part.name, "' clashes with an object"));
                    part.material += firstMaterial;
                    for (auto* points : {&part.vertices, &part.mesh.vertices})
                        for (Vec3& v : *points) {
                            v = o.toWorld * v;
                            checkCoordinate(v, scene.metresPerUnit, w.at("file"));
                        }
                    scene.objects.push_back(std::move(part));
                }
                fingerprint();
                if (parts.hasTextures())
                    scene.fingerprint = fnv1a(std::to_string(parts.fingerprint), scene.fingerprint);
                continue;
            }
            if (gltf) {
                // The file's triangles, all of them, with this object's material (and their texture
                // coordinates, if every part has them).
                bool uvs = true;
                for (const SceneObject& part : readGltfScene(o.file).objects) {
                    const int first = int(o.mesh.vertices.size());
                    uvs = uvs && part.hasUv();
                    if (part.type == ShapeType::Mesh) {
                        o.mesh.vertices.insert(o.mesh.vertices.end(), part.mesh.vertices.begin(),
                                               part.mesh.vertices.end());
                        for (std::vector<int> f : part.mesh.faces) {
                            for (int& v : f) v += first;
                            o.mesh.faces.push_back(std::move(f));
                        }
                        if (uvs)
                            o.mesh.faceUv.insert(o.mesh.faceUv.end(), part.mesh.faceUv.begin(), part.mesh.faceUv.end());
                    } else {
                        o.mesh.vertices.insert(o.mesh.vertices.end(), part.vertices.begin(), part.vertices.end());
                        std::vector<int> f(part.vertices.size());
                        for (size_t k = 0; k < f.size(); ++k) f[k] = first + int(k);
                        o.mesh.faces.push_back(std::move(f));
                        if (uvs) o.mesh.faceUv.push_back(part.uv);
                    }
                }
                if (!uvs) o.mesh.faceUv.clear();
            } else {
                o.mesh = readPolygonSoup(o.file, w.at("file").path);
            }
            for (auto& v : o.mesh.vertices) {
                v = o.toWorld * v;
                checkCoordinate(v, scene.metresPerUnit, w.at("file"));
            }
            fingerprint();
        } else {
            w.at("type").fail(cat("unknown object type '", t, "' (expected quad, triangle, mesh or sphere)"));
        }
        scene.objects.push_back(std::move(o));
    }
    if (scene.objects.empty()) top.at("objects").fail("the scene is empty: it has no objects");
    normaliseLengths(scene, top);

    if (root.contains("camera")) {
        scene.camera = parseCameraJson(root["camera"], scene, top.at("camera"));
        scene.hasCamera = true;
    }
    if (!scene.hasEmitter())
        logWarning(path, ": no material emits light: every radiosity will be zero (a black answer)");
    return scene;
}

// The back of an object: its faces in reverse order, so that its front is the object's back, set
// back behind it by `d` (along each face's normal; a mesh's vertices along their faces' mean normal):
// a ray arriving at the object meets the front strictly first, and rays leaving either face start
// on their own side of both.
SceneObject backFace(const SceneObject& o, double d) {
    SceneObject b = o;
    b.sourceNode = b.sourcePrimitive = -1;  // not a part of the file's own (the round trip skips it)
    if (o.type == ShapeType::Quad || o.type == ShapeType::Triangle) {
        const auto& v = o.vertices;
        const Vec3 n = (o.type == ShapeType::Quad ? (v[2] - v[0]).cross(v[3] - v[1]) : (v[1] - v[0]).cross(v[2] - v[0]))
                           .normalized();
        std::reverse(b.vertices.begin() + 1, b.vertices.end());
        if (!b.uv.empty()) std::reverse(b.uv.begin() + 1, b.uv.end());
        for (Vec3& p : b.vertices) p -= d * n;
        return b;
    }
    std::vector<Vec3> normal(o.mesh.vertices.size(), Vec3::Zero());
    for (const auto& f : o.mesh.faces)
        for (size_t k = 1; k + 1 < f.size(); ++k) {
            const Vec3& a = o.mesh.vertices[size_t(f[0])];
            const Vec3 n = (o.mesh.vertices[size_t(f[k])] - a).cross(o.mesh.vertices[size_t(f[k + 1])] - a);
            for (int i : {f[0], f[k], f[k + 1]}) normal[size_t(i)] += n;
        }
    for (size_t i = 0; i < normal.size(); ++i)
        if (normal[i].squaredNorm() > 0) b.mesh.vertices[i] -= d * normal[i].normalized();
    for (auto& f : b.mesh.faces) std::reverse(f.begin() + 1, f.end());
    for (auto& f : b.mesh.faceUv) std::reverse(f.begin() + 1, f.end());
    return b;
}

// Double-sided materials (Material::doubleSided): each object's back added as an object of its own,
// `<name>#back`, right after it, 1e-5 of the scene's diagonal behind (ten times the tracer's ray
// offset: the two never meet a ray at one distance).
void addBackFaces(Scene& scene) {
    if (std::none_of(scene.materials.begin(), scene.materials.end(), [](const Material& m) { return m.doubleSided; }))
        return;
    Eigen::AlignedBox3d box;
    for (const SceneObject& o : scene.objects) {
        for (const Vec3& v : o.vertices) box.extend(v);
        for (const Vec3& v : o.mesh.vertices) box.extend(v);
    }
    std::set<std::string> names;
    for (const SceneObject& o : scene.objects) names.insert(o.name);
    std::vector<std::string> renamed, spheres;
    std::vector<SceneObject> out;
    for (SceneObject& o : scene.objects) {
        const bool twin = scene.materialOf(o).doubleSided;
        if (twin && o.type == ShapeType::Sphere) spheres.push_back(o.name);
        std::optional<SceneObject> back;
        if (twin && o.type != ShapeType::Sphere) back = backFace(o, 1e-5 * box.diagonal().norm());
        out.push_back(std::move(o));
        if (!back) continue;
        back->name = uniqueName(out.back().name + "#back", names, renamed);
        out.push_back(std::move(*back));
    }
    if (out.size() > scene.objects.size())
        logInfo(scene.path, ": ", out.size() - scene.objects.size(),
                " objects of double-sided materials: each back an object of its own, named '<object>#back'");
    for (const std::string& s : spheres)
        logInfo(scene.path, ": sphere '", s, "' of a double-sided material: its inside is not added");
    scene.objects = std::move(out);
}

}  // namespace

Scene loadScene(const std::string& path) {
    Scene scene = isGltfPath(path) ? loadGltfScene(path) : isObjPath(path) ? loadObjScene(path) : loadJsonScene(path);
    addBackFaces(scene);
    for (const SceneObject& o : scene.objects)
        if (scene.materialOf(o).textured() && !o.hasUv())
            logInfo(path, ": object '", o.name, "' has no texture coordinates",
                    o.type == ShapeType::Sphere ? " (a sphere)" : "", ": it takes its textures' mean");
    return scene;
}

}  // namespace penumbra
