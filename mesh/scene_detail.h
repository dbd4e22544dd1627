// What the scene readers share (scene_loader.cpp for our JSON, gltf_scene.cpp for glTF): reading a
// file with its checks, error context, the geometry checks and the length normalisation.
#pragma once

#include <cstdint>
#include <initializer_list>
#include <set>
#include <string>
#include <vector>

#include "core/error.h"
#include "mesh/scene.h"

namespace penumbra::scene_detail {

// A scene or mesh file larger than this is refused before it is read.
constexpr uintmax_t kMaxFileBytes = uintmax_t(1) << 31;
// Coordinates beyond this many metres are taken as a unit mistake, not a scene.
constexpr double kAbsurdMetres = 1e8;

uint64_t fnv1a(const std::string& bytes, uint64_t h = 1469598103934665603ull);

// The bytes of a regular file: a folder, a device (/dev/zero was read until memory ran out), a pipe
// or a file past kMaxFileBytes is refused by name, and so is one that cannot be opened, with why.
std::string readFile(const std::string& path, const std::string& what);

// Context for error messages: "scene.json: objects[2] 'floor': vertices: ..."
struct Where {
    std::string file, path;
    Where at(const std::string& key) const { return {file, path.empty() ? key : path + "." + key}; }
    Where index(size_t i, const std::string& name = "") const {
        return {file, cat(path, "[", i, "]", name.empty() ? "" : " '" + name + "'")};
    }
    [[noreturn]] void fail(const std::string& what) const {
        throw Error(cat(file, ": ", path.empty() ? "" : path + ": ", what));
    }
};

// `p` in inside units of `metres` metres each (Scene::metresPerUnit).
void checkCoordinate(const Vec3& p, double metres, const Where& w);
void checkQuad(const std::vector<Vec3>& v, const Where& w);
void checkTriangle(const std::vector<Vec3>& v, const Where& w);

// The shape of an object read from a polygon soup (glTF, OBJ): one triangle is our `triangle`; one
// planar convex quad, or two triangles that make one (an exporter's split of a quad face), our `quad`,
// meshed as the JSON scene's; anything else our `mesh` (from `file`).
void shapeFromSoup(SceneObject& o, PolygonSoup soup, const std::string& file, const Where& w);

// Whether `path` ends in one of `extensions` (".glb", ...), in any case.
bool hasExtension(const std::string& path, std::initializer_list<const char*> extensions);

// `wanted`, or `wanted-2`, `wanted-3`, ... : the first not yet in `names` (which takes it); a changed
// name goes into `renamed` for the log.
std::string uniqueName(const std::string& wanted, std::set<std::string>& names, std::vector<std::string>& renamed);

// The log lines of an imported file: the names changed to tell objects apart, and each note once.
void logImport(const std::string& path, const std::vector<std::string>& renamed, const std::set<std::string>& notes);

// Brings a scene far below a millimetre or above a thousand kilometres across to half a unit to one
// unit across inside, by a power of two (Scene::metresPerUnit); refuses one whose areas in m^2
// would leave double precision.
void normaliseLengths(Scene& scene, const Where& top);

}  // namespace penumbra::scene_detail
