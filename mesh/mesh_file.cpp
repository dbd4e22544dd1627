#include "mesh/mesh_file.h"

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/PolyMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <new>
#include <sstream>
#include <vector>

#include "core/error.h"

namespace penumbra {

namespace {
struct ReadTraits : public OpenMesh::DefaultTraits {
    typedef OpenMesh::Vec3d Point;
};
using ReadMesh = OpenMesh::PolyMesh_ArrayKernelT<ReadTraits>;
}  // namespace

namespace {

// The PLY scalar types (each by two names), their sizes and how to read one in the machine's order.
struct PlyType {
    const char *name, *alias;
    int bytes;
    double (*decode)(const unsigned char*);
};
template <typename T>
double decodeAs(const unsigned char* raw) {
    T x;
    std::memcpy(&x, raw, sizeof x);
    return double(x);
}
const PlyType kPlyTypes[] = {{"char", "int8", 1, decodeAs<int8_t>},    {"uchar", "uint8", 1, decodeAs<uint8_t>},
                             {"short", "int16", 2, decodeAs<int16_t>}, {"ushort", "uint16", 2, decodeAs<uint16_t>},
                             {"int", "int32", 4, decodeAs<int32_t>},   {"uint", "uint32", 4, decodeAs<uint32_t>},
                             {"float", "float32", 4, decodeAs<float>}, {"double", "float64", 8, decodeAs<double>}};
const PlyType* plyType(const std::string& t) {
    for (const PlyType& k : kPlyTypes)
        if (t == k.name || t == k.alias) return &k;
    return nullptr;
}

// A PLY file as OpenMesh reads it, refused where OpenMesh would hang, crash or take memory without
// end. The header, line by line, as the format defines it: OpenMesh's reader reads it word by word
// whatever the lines, and loops forever once the words run out before an end_header (found by
// tests/fuzz: a misspelt keyword; a property line of four words, whose last ones it took for the
// next line's keyword and swallowed end_header with). So each line must hold exactly the words
// OpenMesh takes from it. Then the data, walked value by value: a face's list length a whole number
// up to a million (a face of -1 corners ran OpenMesh out of memory), its vertex indices in range,
// every value a finite number, and no element cut short.
void checkPly(std::istream& in, uintmax_t size, const std::string& where) {
    struct Property {
        bool list = false;
        std::string countType, type, name;
    };
    struct Element {
        std::string name;
        long long count = 0;
        std::vector<Property> properties;
    };
    std::vector<Element> elements;
    std::string format;
    uintmax_t claimed = 0;
    bool ended = false;
    std::string line;
    auto header = [](const std::string& t) {
        return t == "ply" || t == "format" || t == "comment" || t == "obj_info" || t == "element" || t == "property" ||
               t == "end_header";
    };
    for (size_t number = 1; !ended && std::getline(in, line); ++number) {
        if (!line.empty() && line.back() == '\r') line.pop_back();
        std::istringstream words(line);
        std::string keyword;
        words >> keyword;
        if (number == 1 ? keyword != "ply" : !header(keyword) || keyword == "ply")
            throw Error(cat(where, " line ", number, ": not a PLY header line: '", line.substr(0, 40), "'"));
        ended = keyword == "end_header";
        auto bad = [&](const char* what) {
            throw Error(cat(where, " line ", number, ": ", what, ": '", line.substr(0, 40), "'"));
        };
        std::string a, b, c, name, rest;
        if (keyword == "obj_info") {
            while (words >> a)
                if (header(a)) bad("an obj_info line holding a header keyword");
        } else if (keyword == "format") {
            if (!(words >> a >> b) || (a != "ascii" && a != "binary_little_endian" && a != "binary_big_endian") ||
                b != "1.0" || words >> rest)
                bad("expected format ascii, binary_little_endian or binary_big_endian, version 1.0");
            format = a;
        } else if (keyword == "element") {
            long long count = -1;
            if (!(words >> a >> count) || count < 0 || words >> rest)
                bad("expected element NAME COUNT, the count a whole number");
            claimed += uintmax_t(count);
            elements.push_back({a, count, {}});
        } else if (keyword == "property") {
            if (elements.empty()) bad("a property before any element (OpenMesh crashed on it)");
            const bool list = words >> a && a == "list";
            if (list ? !(words >> b >> c >> name) || !plyType(b) || !plyType(c) : !plyType(a) || !(words >> name))
                bad("expected property TYPE NAME or property list TYPE TYPE NAME");
            if (words >> rest || header(name)) bad("expected property TYPE NAME or property list TYPE TYPE NAME");
            elements.back().properties.push_back(list ? Property{true, b, c, name} : Property{false, "", a, name});
        }
    }
    if (!ended) throw Error(cat(where, ": its PLY header has no end_header line"));
    if (format.empty()) throw Error(cat(where, ": its PLY header has no format line"));
    if (claimed > size)
        throw Error(cat(where, " claims ", claimed, " elements in ", size, " bytes: it is damaged or cut short"));

    long long vertices = 0;
    for (const Element& e : elements)
        if (e.name == "vertex") vertices = e.count;
    // One value of `type`: a token of ascii, or its bytes in the file's order.
    const bool ascii = format == "ascii",
               swap = (format == "binary_big_endian") != (__BYTE_ORDER__ == __ORDER_BIG_ENDIAN__);
    std::string token;
    auto value = [&](const std::string& type, const std::string& at) {
        if (ascii) {
            if (!(in >> token)) throw Error(cat(where, ": its data ends inside ", at));
            double v = 0;
            if (!finiteNumber(token, v))
                throw Error(cat(where, ": ", at, ": '", token.substr(0, 24), "' is not a finite number"));
            return v;
        }
        unsigned char raw[8] = {};
        const PlyType* t = plyType(type);
        if (!in.read(reinterpret_cast<char*>(raw), t->bytes)) throw Error(cat(where, ": its data ends inside ", at));
        if (swap) std::reverse(raw, raw + t->bytes);
        const double v = t->decode(raw);
        if (!std::isfinite(v)) throw Error(cat(where, ": ", at, ": a value that is not a finite number"));
        return v;
    };
    for (const Element& e : elements)
        for (long long k = 0; k < e.count; ++k)
            for (const Property& p : e.properties) {
                const std::string at = cat(e.name, " ", k);
                if (!p.list) {
                    value(p.type, at);
                    continue;
                }
                const double n = value(p.countType, at);
                if (n < 0 || n > 1e6 || n != std::floor(n))
                    throw Error(cat(where, ": ", at, ": a list of ", n,
                                    " entries (expected a whole number from 0 to 1,000,000)"));
                const bool indices = e.name == "face" && (p.name == "vertex_indices" || p.name == "vertex_index");
                for (long long m = 0; m < (long long)n; ++m) {
                    const double index = value(p.type, at);
                    if (indices && (index < 0 || index >= double(vertices) || index != std::floor(index)))
                        throw Error(cat(where, ": ", at, ": vertex index ", index, " is out of range (", vertices,
                                        " vertices)"));
                }
            }
}

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
    // A vertex's coordinates, each a finite number (OpenMesh read "nan" and dropped every face
    // touching it, and the file was refused as holding no faces).
    auto checkCoordinates = [&](std::istringstream& words, const std::string& at) {
        for (int k = 0; k < 3; ++k) {
            std::string token;
            double v = 0;
            if (!(words >> token)) throw Error(cat(where, at, ": a vertex needs three coordinates"));
            if (!finiteNumber(token, v))
                throw Error(cat(where, at, ": vertex coordinate '", token.substr(0, 24), "' is not a finite number"));
        }
    };
    if (ext == ".obj") {
        std::string line;
        long long vertices = 0;
        for (size_t number = 1; std::getline(in, line); ++number) {
            // The keyword is the line's first word, after any blanks (as OpenMesh reads it: " f /2"
            // passed a check that looked at the first character, and an empty face tripped an
            // assertion in OpenMesh's reader: found by tests/fuzz).
            std::istringstream words(line);
            std::string keyword;
            words >> keyword;
            if (keyword == "v") {
                ++vertices;
                checkCoordinates(words, cat(" line ", number));
            }
            if (keyword != "f") continue;
            int corners = 0;
            for (std::string token; words >> token; ++corners) {
                const long long index = std::strtoll(token.c_str(), nullptr, 10);
                if (index == 0 || index > vertices || index < -vertices)
                    throw Error(cat(where, " line ", number, ": face vertex index ", token.substr(0, token.find('/')),
                                    " is out of range (", vertices, " vertices before it)"));
            }
            if (corners < 3)
                throw Error(cat(where, " line ", number, ": a face of ", corners, " vertices (3 or more)"));
        }
    } else if (ext == ".off") {
        // As OpenMesh reads it: the keyword [ST][C][N][4][n]OFF alone on the first line (an 'OFF1'
        // header had it take counts out of other bytes and ask for 16 GiB; "OFF 0 0" had it take the
        // next line's numbers as counts), the counts on the next.
        std::string word, line;
        std::getline(in, word);
        while (!word.empty() && std::isspace(static_cast<unsigned char>(word.back()))) word.pop_back();
        const bool header = word.size() >= 3 && word.compare(word.size() - 3, 3, "OFF") == 0 &&
                            word.find_first_not_of("STCN4n") == word.size() - 3;
        if (!header) {
            const std::string keyword = word.substr(0, word.find_first_of(" \t"));
            if (keyword != word && keyword.size() >= 3 && keyword.compare(keyword.size() - 3, 3, "OFF") == 0)
                throw Error(cat(where, ": the keyword ", keyword,
                                " must stand alone on the first line, the counts on the next (its first line is '",
                                word.substr(0, 20), "', which OpenMesh misreads)"));
            throw Error(cat(where, ": not a text OFF file (its first line is '", word.substr(0, 20),
                            "'; binary OFF is not read: save it as text OFF, PLY or OBJ)"));
        }
        auto whole = [](const std::string& v) {
            return !v.empty() && v.size() < 12 && v.find_first_not_of("0123456789") == std::string::npos;
        };
        // Three whole numbers, each all digits (OpenMesh read "0-1" as 0 faces and -1 edges, and
        // reserved for 2^32 of them).
        std::string t[4];
        std::getline(in, line);
        std::istringstream countWords(line);
        if (!(countWords >> t[0] >> t[1] >> t[2]) || countWords >> t[3] || !whole(t[0]) || !whole(t[1]) || !whole(t[2]))
            throw Error(cat(where, ": expected the vertex, face and edge counts on the line after ", word));
        const long long vertices = std::atoll(t[0].c_str()), faces = std::atoll(t[1].c_str());
        if (uintmax_t(vertices + faces) > size) tooMany(uintmax_t(vertices + faces), "vertices and faces");
        // Each face: its corner count (3 or more) and that many vertex indices in range (a face of
        // "-01" corners grew OpenMesh's list until memory ran out).
        long long seen = 0;
        while (seen < vertices + faces && std::getline(in, line)) {
            std::istringstream words(line);
            std::string first;
            if (!(words >> first) || first[0] == '#') continue;
            if (seen++ < vertices) {
                std::istringstream coordinates(line);
                checkCoordinates(coordinates, cat(": vertex ", seen - 1));
                continue;
            }
            const long long corners = whole(first) ? std::atoll(first.c_str()) : -1;
            if (corners < 3 || corners > 1000000)
                throw Error(cat(where, ": face ", seen - vertices, " has '", first.substr(0, 12),
                                "' corners (expected a whole number of 3 or more)"));
            for (long long k = corners; k > 0; --k) {
                std::string index;
                if (!(words >> index) || !whole(index) || std::atoll(index.c_str()) >= vertices)
                    throw Error(cat(where, ": face ", seen - vertices, " has a vertex index out of range or missing (",
                                    vertices, " vertices)"));
            }
        }
    } else if (ext == ".ply") {
        checkPly(in, size, where);
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
    bool read = false;
    try {
        read = OpenMesh::IO::read_mesh(mesh, path, opt);
    } catch (const std::bad_alloc&) {  // by the file's name, not a bare "out of memory"
        std::error_code sizeError;
        throw Error(cat(field, ": mesh file '", path, "': out of memory reading its ", fs::file_size(path, sizeError),
                        " bytes"));
    }
    if (!read) throw Error(cat(field, ": mesh file '", path, "' cannot be read as ", ext.substr(1)));
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

std::string colouredPly(const std::vector<Vec3>& vertices, const std::vector<std::array<int, 3>>& triangles,
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
    std::ostringstream bytes;
    if (!OpenMesh::IO::write_mesh(mesh, bytes, ".ply", options)) throw Error("OpenMesh could not make the PLY file");
    return bytes.str();
}

}  // namespace penumbra
