#include "mesh/mesh_file.h"

#include <filesystem>

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/PolyMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>

#include "core/error.h"

namespace penumbra {

namespace {
struct ReadTraits : public OpenMesh::DefaultTraits {
    typedef OpenMesh::Vec3d Point;
};
using ReadMesh = OpenMesh::PolyMesh_ArrayKernelT<ReadTraits>;
}  // namespace

PolygonSoup readPolygonSoup(const std::string& path, const std::string& field) {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (!fs::exists(path, ec)) throw Error(cat(field, ": mesh file '", path, "' does not exist"));
    if (!fs::is_regular_file(path, ec)) throw Error(cat(field, ": mesh file '", path, "' is not a regular file"));
    std::string ext = fs::path(path).extension().string();
    for (auto& c : ext) c = char(std::tolower(c));
    if (ext != ".obj" && ext != ".ply" && ext != ".off" && ext != ".stl")
        throw Error(cat(field, ": mesh file '", path, "' has an unsupported format '", ext,
                        "' (expected .obj, .ply, .off or .stl)"));
    omlog().disable();
    omerr().disable();
    omout().disable();
    ReadMesh mesh;
    OpenMesh::IO::Options opt;
    if (!OpenMesh::IO::read_mesh(mesh, path, opt))
        throw Error(cat(field, ": mesh file '", path, "' cannot be read as ", ext.substr(1)));
    if (mesh.n_faces() == 0) throw Error(cat(field, ": mesh file '", path, "' holds no faces"));
    PolygonSoup soup;
    soup.vertices.reserve(mesh.n_vertices());
    for (auto v : mesh.vertices()) {
        const auto& p = mesh.point(v);
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
            throw Error(cat(field, ": mesh file '", path, "' has a non-finite vertex coordinate"));
        soup.vertices.emplace_back(p[0], p[1], p[2]);
    }
    for (auto f : mesh.faces()) {
        std::vector<int> face;
        for (auto v : mesh.fv_range(f)) face.push_back(v.idx());
        soup.faces.push_back(std::move(face));
    }
    return soup;
}

}  // namespace penumbra
