#include "mesh/mesh_file.h"

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/PolyMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <filesystem>

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

namespace penumbra {

void writeColouredPly(const std::string& path, const std::vector<Vec3>& vertices,
                      const std::vector<std::array<int, 3>>& triangles,
                      const std::vector<std::array<unsigned char, 3>>& colours) {
    OpenMesh::PolyMesh_ArrayKernelT<> mesh;
    mesh.request_vertex_colors();
    std::vector<OpenMesh::VertexHandle> handles;
    handles.reserve(vertices.size());
    for (size_t i = 0; i < vertices.size(); ++i) {
        const Vec3& p = vertices[i];
        handles.push_back(mesh.add_vertex({float(p.x()), float(p.y()), float(p.z())}));
        mesh.set_color(handles.back(), {colours[i][0], colours[i][1], colours[i][2]});
    }
    for (const auto& t : triangles) mesh.add_face(handles[size_t(t[0])], handles[size_t(t[1])], handles[size_t(t[2])]);
    OpenMesh::IO::Options options = OpenMesh::IO::Options::VertexColor | OpenMesh::IO::Options::Binary;
    if (!OpenMesh::IO::write_mesh(mesh, path, options)) throw Error(cat(path, ": cannot write the PLY file"));
}

}  // namespace penumbra
