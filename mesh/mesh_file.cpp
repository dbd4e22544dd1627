#include "mesh/mesh_file.h"

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/PolyMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.h"

namespace penumbra {

namespace {
struct ReadTraits : public OpenMesh::DefaultTraits {
    typedef OpenMesh::Vec3d Point;
};
using ReadMesh = OpenMesh::PolyMesh_ArrayKernelT<ReadTraits>;
}  // namespace

namespace {

// Refuses a mesh file whose header claims more elements than its bytes can hold (an OFF file of 60
// bytes claiming 100,000 elements hung OpenMesh's reader; PLY and STL headers claiming 2^31 faces ran
// out of memory) and an OBJ face whose vertex index is out of range (OpenMesh dropped it silently):
// by the file's name, and the line where there is one.
void checkMeshFile(const std::string& path, const std::string& ext, const std::string& field) {
    namespace fs = std::filesystem;
    std::error_code ec;
    const uintmax_t size = fs::file_size(path, ec);
    if (ec) return;  // the reader says what is wrong
    std::ifstream in(path, std::ios::binary);
    const std::string where = cat(field, ": mesh file '", path, "'");
    auto tooMany = [&](uintmax_t claimed, const std::string& what) {
        throw Error(cat(where, " claims ", claimed, " ", what, " in ", size, " bytes: it is damaged or cut short"));
    };
    if (ext == ".obj") {
        std::string line;
        long long vertices = 0;
        for (size_t number = 1; std::getline(in, line); ++number) {
            if (line.size() > 1 && line[0] == 'v' && (line[1] == ' ' || line[1] == '\t')) ++vertices;
            if (line.size() < 2 || line[0] != 'f' || (line[1] != ' ' && line[1] != '\t')) continue;
            std::istringstream tokens(line.substr(2));
            for (std::string token; tokens >> token;) {
                const long long index = std::atoll(token.c_str());
                if (index == 0 || index > vertices || -index > vertices)
                    throw Error(cat(where, " line ", number, ": face vertex index ", token.substr(0, token.find('/')),
                                    " is out of range (", vertices, " vertices before it)"));
            }
        }
    } else if (ext == ".off") {
        std::string word;
        long long counts[2] = {0, 0};
        in >> word;  // OFF, COFF, NOFF, ...
        for (long long& c : counts)
            if (!(in >> c)) return;  // binary or malformed: the reader decides
        if (counts[0] < 0 || counts[1] < 0 || uintmax_t(counts[0] + counts[1]) > size)
            tooMany(uintmax_t(counts[0]) + uintmax_t(counts[1]), "vertices and faces");
    } else if (ext == ".ply") {
        uintmax_t claimed = 0;
        for (std::string line; std::getline(in, line) && line.rfind("end_header", 0) != 0;) {
            std::istringstream words(line);
            std::string element, name;
            long long count = 0;
            if (words >> element >> name >> count && element == "element") {
                if (count < 0) tooMany(uintmax_t(0), "elements (a negative count)");
                claimed += uintmax_t(count);
            }
        }
        if (claimed > size) tooMany(claimed, "elements");
    } else if (ext == ".stl") {
        char head[84] = {};
        in.read(head, sizeof head);
        if (in.gcount() == 84 && std::string(head, 5) != "solid") {
            uint32_t triangles = 0;
            std::memcpy(&triangles, head + 80, 4);
            if (84 + 50 * uintmax_t(triangles) > size) tooMany(triangles, "triangles");
        }
    }
}

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
    checkMeshFile(path, ext, field);
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
