// Triangle surfaces: Assimp reads every format (in a plugin loaded on first
// use, AssimpRead.cpp); this file checks the files Assimp mishandles before,
// the surface after, and voxelises.
#include "isohex/imaging/Surface.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <cctype>
#include <fstream>
#include <limits>
#include <cstdlib>
#include <iterator>
#include <sstream>
#include <unordered_map>
#include <vector>

#include <unistd.h>

#include <openvdb/tools/MeshToVolume.h>

#include "ReaderPlugins.hpp"
#include "isohex/core/DisjointSets.hpp"
#include "isohex/core/Error.hpp"

namespace isohex::imaging {
namespace {

std::string at(const Vec3& p) {
    std::ostringstream s;
    s.precision(6);
    s << "(" << p[0] << ", " << p[1] << ", " << p[2] << ")";
    return s.str();
}

}  // namespace

double TriangleSurface::volume() const {
    double v = 0.0;
    for (const auto& t : triangles) {
        const Vec3 &a = vertices[t[0]], &b = vertices[t[1]], &c = vertices[t[2]];
        v += a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
             a[2] * (b[0] * c[1] - b[1] * c[0]);
    }
    return v / 6.0;
}

double TriangleSurface::area() const {
    double s = 0.0;
    for (const auto& t : triangles) {
        const Vec3 &a = vertices[t[0]], &b = vertices[t[1]], &c = vertices[t[2]];
        const Vec3 u{b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w{c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        const Vec3 n{u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        s += 0.5 * std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    }
    return s;
}

SurfaceTopology surfaceTopology(const TriangleSurface& s) {
    DisjointSets<std::int32_t> sets(s.vertices.size());
    std::vector<std::uint8_t> used(s.vertices.size(), 0);
    std::vector<std::pair<std::int32_t, std::int32_t>> edges;
    edges.reserve(3 * s.triangles.size());
    for (const auto& t : s.triangles)
        for (int k = 0; k < 3; ++k) {
            const std::int32_t a = t[k], b = t[(k + 1) % 3];
            used[static_cast<std::size_t>(a)] = 1;
            sets.unite(a, b);
            edges.emplace_back(std::min(a, b), std::max(a, b));
        }
    std::sort(edges.begin(), edges.end());
    const auto e = static_cast<long long>(std::unique(edges.begin(), edges.end()) - edges.begin());
    SurfaceTopology out;
    long long v = 0;
    for (std::size_t i = 0; i < used.size(); ++i)
        if (used[i]) {
            ++v;
            if (sets.isRoot(static_cast<std::int32_t>(i))) ++out.components;
        }
    out.euler = v - e + static_cast<long long>(s.triangles.size());
    return out;
}

void checkClosedManifold(TriangleSurface& s) {
    const std::string src = s.source.empty() ? std::string("surface") : s.source;
    if (s.triangles.empty()) {
        throw Error(src + ": holds no triangles; isohex needs a closed triangle surface.");
    }
    // Per undirected edge: how often it is used, and the net direction
    // (+1 for a->b with a<b, -1 for b->a). A closed, consistently oriented
    // surface uses each edge twice, once in each direction.
    struct Use {
        int count = 0, net = 0;
    };
    std::unordered_map<std::uint64_t, Use> edges;
    edges.reserve(s.triangles.size() * 2);
    for (const auto& t : s.triangles)
        for (int e = 0; e < 3; ++e) {
            const std::uint32_t a = t[e], b = t[(e + 1) % 3];
            const std::uint64_t key = (std::uint64_t(std::min(a, b)) << 32) | std::max(a, b);
            auto& u = edges[key];
            ++u.count;
            u.net += a < b ? 1 : -1;
        }
    std::int64_t open = 0, nonManifold = 0, flippedEdges = 0;
    std::uint64_t openExample = 0, nmExample = 0, flipExample = 0;
    for (const auto& [key, u] : edges) {
        if (u.count == 1) {
            if (open++ == 0 || key < openExample) openExample = key;
        } else if (u.count > 2) {
            if (nonManifold++ == 0 || key < nmExample) nmExample = key;
        } else if (u.net != 0) {
            if (flippedEdges++ == 0 || key < flipExample) flipExample = key;
        }
    }
    auto edgeAt = [&](std::uint64_t key) {
        return at(s.vertices[key >> 32]) + " - " + at(s.vertices[key & 0xffffffffu]);
    };
    if (open > 0) {
        throw Error(src + ": the surface is open: " + std::to_string(open) +
                    " edges belong to a single triangle (e.g. " + edgeAt(openExample) +
                    "). isohex needs a closed (watertight) surface; fill the holes (e.g. MeshLab "
                    "'Close Holes') and retry.");
    }
    if (nonManifold > 0) {
        throw Error(src + ": the surface is not manifold: " + std::to_string(nonManifold) +
                    " edges are shared by more than two triangles (e.g. " + edgeAt(nmExample) +
                    "). Separate the touching parts or remove duplicate triangles, then retry.");
    }
    if (flippedEdges > 0) {
        throw Error(src + ": triangle orientation is inconsistent: across " +
                    std::to_string(flippedEdges) + " edges (e.g. " + edgeAt(flipExample) +
                    ") neighbouring triangles face opposite ways. Re-orient the faces coherently "
                    "(e.g. MeshLab 'Re-Orient all faces coherently') and retry.");
    }
    if (s.volume() < 0.0) {
        for (auto& t : s.triangles) std::swap(t[1], t[2]);
        s.flipped = true;
    }
}

// Assimp 5.2 (Debian's build has its internal asserts on) aborts the whole
// process when an OFF file holds fewer vertex or face lines than its header
// promises, and reads a face index beyond the vertices as some other vertex.
// So the comment-free text is checked first: the counts on the header, one
// line of at least three numbers per vertex, and per face a corner count of
// at least 3 followed by that many indices below the vertex count.
static void checkOffCounts(const std::string& file, const std::string& text) {
    std::istringstream in(text);
    std::string line;
    std::vector<std::string> lines;
    while (std::getline(in, line)) lines.push_back(line);
    auto fail = [&](const std::string& what) {
        throw Error(file + ": " + what + ". The file is truncated or not a valid OFF file; re-export it.");
    };
    if (lines.empty()) fail("the file is empty");
    std::istringstream head(lines[0]);
    std::string magic;
    head >> magic;
    if (magic.size() < 3 || magic.compare(magic.size() - 3, 3, "OFF") != 0) fail("the first line is not an OFF header");
    long long nv = -1, nf = -1;
    std::size_t next = 1;
    if (!(head >> nv >> nf)) {  // the counts on the next line
        if (lines.size() < 2) fail("the header has no vertex and face counts");
        std::istringstream counts(lines[1]);
        if (!(counts >> nv >> nf)) fail("the line after the header does not hold the vertex and face counts");
        next = 2;
    }
    if (nv < 3 || nf < 1) fail("the header promises " + std::to_string(nv) + " vertices and " + std::to_string(nf) + " faces");
    const std::size_t have = lines.size() - next;
    if (have < static_cast<std::size_t>(nv + nf)) {
        const std::size_t vertexLines = std::min<std::size_t>(have, static_cast<std::size_t>(nv));
        fail("the header promises " + std::to_string(nv) + " vertices and " + std::to_string(nf) +
             " faces but the file has " + std::to_string(vertexLines) + " vertex line(s) and " +
             std::to_string(have - vertexLines) + " face line(s)");
    }
    for (long long i = 0; i < nv; ++i) {
        std::istringstream v(lines[next + static_cast<std::size_t>(i)]);
        double x, y, z;
        if (!(v >> x >> y >> z))
            fail("vertex " + std::to_string(i) + " (line " + std::to_string(next + i + 1) +
                 " not counting comment and blank lines) does not hold three numbers");
    }
    for (long long f = 0; f < nf; ++f) {
        const std::size_t at = next + static_cast<std::size_t>(nv + f);
        std::istringstream fl(lines[at]);
        long long n = 0;
        if (!(fl >> n) || n < 3) fail("face " + std::to_string(f) + " (line " + std::to_string(at + 1) +
                                      " not counting comment and blank lines) does not start with a corner count of 3 or more");
        for (long long k = 0; k < n; ++k) {
            long long idx = -1;
            if (!(fl >> idx)) fail("face " + std::to_string(f) + " has fewer than its " + std::to_string(n) + " corners");
            if (idx < 0 || idx >= nv)
                fail("face " + std::to_string(f) + " uses vertex " + std::to_string(idx) + " but there are only " +
                     std::to_string(nv) + " vertices (0 to " + std::to_string(nv - 1) + ")");
        }
    }
}

// Debian's Assimp 5.2.5 crashes (segmentation fault) on a binary PLY file
// cut short, and reads an ASCII one cut short, or a face index beyond the
// vertices, as a surface with holes, which the closed-surface check then
// blames on the surface. So the file is walked first as its header
// describes it: every element's items, list lengths included, must be in the
// file, and the face lists' indices below the vertex count. Only the layout
// is checked; Assimp still does the reading.
namespace {

// A PLY file walked as its header describes it: the whole file in memory, the
// read position, and what the header declared. The phases run in order:
// readHeader, checkDeclarations, checkBody.
class PlyLayout {
public:
    explicit PlyLayout(const std::string& file) : file_(file) {
        std::ifstream in(file, std::ios::binary);
        data_.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }

    // The header: its lines up to end_header, with the format and each
    // element's count and properties.
    void readHeader() {
        bool ended = false;
        for (int lineNo = 1; pos_ < data_.size() && !ended; ++lineNo) {
            std::size_t nl = data_.find('\n', pos_);
            if (nl == std::string::npos) nl = data_.size();
            std::istringstream line(data_.substr(pos_, nl - pos_));
            pos_ = std::min(nl + 1, data_.size());  // a header cut before its last newline ends at the end
            std::string word;
            line >> word;
            if (lineNo == 1) {
                if (word != "ply") fail("the first line is not 'ply'");
                continue;
            }
            if (word == "format") {
                line >> format_;
            } else if (word == "element") {
                Element e;
                if (!(line >> e.name >> e.count) || e.count < 0)
                    fail("header line " + std::to_string(lineNo) + " is not 'element NAME COUNT'");
                elements_.push_back(e);
            } else if (word == "property") {
                if (elements_.empty()) fail("header line " + std::to_string(lineNo) + " has a property before any element");
                elements_.back().props.push_back(readProperty(line, lineNo));
            } else if (word == "end_header") {
                ended = true;
            }
        }
        if (!ended) fail("the header has no end_header line");
    }

    // The format is one PLY knows, and there are at least 3 vertices.
    void checkDeclarations() {
        ascii_ = format_ == "ascii";
        little_ = format_ == "binary_little_endian";
        if (!ascii_ && !little_ && format_ != "binary_big_endian")
            fail("the header's format '" + format_ + "' is not ascii or binary");
        for (const Element& e : elements_)
            if (e.name == "vertex") vertices_ = e.count;
        if (vertices_ < 3) fail("the header declares no vertex element with at least 3 vertices");
    }

    // The body, element by element: every item is in the file, list lengths
    // are whole and the faces' vertex indices name vertices.
    void checkBody() {
        if (ascii_) text_.str(data_.substr(pos_));
        for (const Element& e : elements_) {
            if (e.props.empty()) continue;  // nothing stored per item
            for (long long i = 0; i < e.count; ++i) checkItem(e, i);
        }
    }

private:
    struct Property {
        int countSize = 0;  // list: bytes of the length; 0 for a scalar
        int size = 0;       // bytes of the value (of each item for a list)
        bool integer = false, isSigned = false;
        bool vertexIndices = false;  // the face list of vertex indices
    };
    struct Element {
        std::string name;
        long long count = 0;
        std::vector<Property> props;
    };

    [[noreturn]] void fail(const std::string& what) const {
        throw Error(file_ + ": " + what + ". The file is truncated or not a valid PLY file; re-export it.");
    }

    // Bytes of a PLY scalar type (0 if unknown), and whether it is an integer and signed.
    static int typeSize(const std::string& t, bool& integer, bool& isSigned) {
        integer = t != "float" && t != "float32" && t != "double" && t != "float64";
        isSigned = t == "char" || t == "int8" || t == "short" || t == "int16" || t == "int" || t == "int32";
        if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
        if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
        if (t == "int" || t == "uint" || t == "int32" || t == "uint32" || t == "float" || t == "float32") return 4;
        if (t == "double" || t == "float64") return 8;
        return 0;
    }

    // The rest of a "property" header line: a scalar type, or "list" with its
    // length and item types and the property's name.
    Property readProperty(std::istringstream& line, int lineNo) const {
        std::string t;
        line >> t;
        Property pr;
        if (t == "list") {
            std::string ct, it;
            line >> ct >> it;
            bool ci = false, cs = false;
            pr.countSize = typeSize(ct, ci, cs);
            pr.size = typeSize(it, pr.integer, pr.isSigned);
            if (pr.countSize == 0 || pr.size == 0 || !ci)
                fail("header line " + std::to_string(lineNo) + " has a list property of unknown types '" + ct + " " + it + "'");
            std::string name;
            line >> name;
            pr.vertexIndices = name == "vertex_indices" || name == "vertex_index";
        } else {
            pr.size = typeSize(t, pr.integer, pr.isSigned);
            if (pr.size == 0) fail("header line " + std::to_string(lineNo) + " has a property of unknown type '" + t + "'");
        }
        return pr;
    }

    // One binary value at the read position; false if the data ends first.
    // Only integers are looked at (a real value reads as 0).
    bool readBinary(int size, bool integer, bool isSigned, double& value) {
        if (data_.size() - pos_ < static_cast<std::size_t>(size)) return false;
        unsigned char b[8];
        for (int i = 0; i < size; ++i)
            b[i] = static_cast<unsigned char>(data_[pos_ + static_cast<std::size_t>(little_ ? i : size - 1 - i)]);
        pos_ += static_cast<std::size_t>(size);
        std::uint64_t u = 0;
        for (int i = size - 1; i >= 0; --i) u = (u << 8) | b[i];
        if (!integer) {
            value = 0;
        } else if (isSigned) {
            const std::uint64_t sign = std::uint64_t{1} << (8 * size - 1);
            value = static_cast<double>(static_cast<long long>(u ^ sign) - static_cast<long long>(sign));
        } else {
            value = static_cast<double>(u);
        }
        return true;
    }

    // One ASCII value as a token; false if the data ends first. Only list
    // lengths and vertex indices (`needed`) are parsed: other values may be
    // nan or inf, which a PLY may hold in its normals or colours.
    bool readAscii(double& value, bool needed) {
        if (!(text_ >> token_)) return false;
        if (!needed) return true;
        char* end = nullptr;
        value = std::strtod(token_.c_str(), &end);
        if (end == token_.c_str() || *end != '\0') value = std::numeric_limits<double>::quiet_NaN();
        return true;
    }

    // Item `i` of element `e`: each property's values, a list's length first.
    void checkItem(const Element& e, long long i) {
        const bool face = e.name == "face";
        auto cut = [&] {
            fail("the header promises " + std::to_string(e.count) + " " + e.name + " item(s) but the data ends at " +
                 e.name + " " + std::to_string(i));
        };
        for (const Property& pr : e.props) {
            double n = 1, v = 0;
            if (pr.countSize > 0) {
                if (!(ascii_ ? readAscii(n, true) : readBinary(pr.countSize, true, false, n))) cut();
                if (!(n >= 0) || n != std::floor(n) || n > static_cast<double>(data_.size()))
                    fail(e.name + " " + std::to_string(i) + " has a list length of " + std::to_string(n));
            }
            for (long long k = 0; k < static_cast<long long>(n); ++k) {
                const bool index = face && pr.vertexIndices && pr.integer;
                if (!(ascii_ ? readAscii(v, index) : readBinary(pr.size, pr.integer, pr.isSigned, v))) cut();
                if (index && !(std::isfinite(v) && v == std::floor(v)))
                    fail("face " + std::to_string(i) + " has a vertex index that is not a whole number");
                if (index && !(v >= 0 && v < static_cast<double>(vertices_)))
                    fail("face " + std::to_string(i) + " uses vertex " + std::to_string(static_cast<long long>(v)) +
                         " but there are only " + std::to_string(vertices_) + " vertices (0 to " +
                         std::to_string(vertices_ - 1) + ")");
            }
        }
    }

    const std::string file_;
    std::string data_;
    std::size_t pos_ = 0;  // header, then binary body: the next byte to read
    std::string format_;
    std::vector<Element> elements_;
    bool ascii_ = false, little_ = false;
    long long vertices_ = -1;
    std::istringstream text_;  // an ASCII body
    std::string token_;
};

void checkPlyLayout(const std::string& file) {
    PlyLayout ply(file);
    ply.readHeader();
    ply.checkDeclarations();
    ply.checkBody();
}

}  // namespace

TriangleSurface loadSurface(const std::filesystem::path& path) {
    const std::string file = path.string();
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) {
        throw Error(file + ": no such file. Check the path (relative paths start at " +
                    std::filesystem::current_path().string() + ").");
    }
    std::string ext = path.extension().string();
    for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    std::string offText;
    if (ext == ".off") {
        // Assimp 5.2's OFF reader loses faces when '#' comment lines sit
        // between the blocks (assimp issue 2228); the OFF format allows them,
        // so hand Assimp the text without comments.
        std::ifstream in(path, std::ios::binary);
        std::string line;
        while (std::getline(in, line)) {
            if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
            if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
            offText += line;
            offText += '\n';
        }
        checkOffCounts(file, offText);
    } else if (ext == ".ply") {
        checkPlyLayout(file);
    }
    TriangleSurface s = detail::surfaceReader().read(file, ext == ".off" ? &offText : nullptr);
    // Assimp reads "nan" in an OBJ or binary STL as a coordinate, and the
    // level set's bounding box breaks on coordinates near 1e200.
    for (std::size_t i = 0; i < s.vertices.size(); ++i)
        for (int a = 0; a < 3; ++a)
            if (!(std::fabs(s.vertices[i][a]) <= 1e15)) {
                std::ostringstream m;
                m << file << ": vertex " << i << " has coordinate " << s.vertices[i][a]
                  << "; isohex reads finite coordinates up to 1e15 in size. Check the file's content and units.";
                throw Error(m.str());
            }
    checkClosedManifold(s);
    return s;
}

SurfaceLevelSet surfaceToLevelSet(TriangleSurface surface, const LevelSetOptions& o) {
    const std::string src = surface.source.empty() ? std::string("surface") : surface.source;
    if (!(o.elementSize > 0.0) || !(o.voxelsPerElement > 0.0) || !(o.halfWidthVoxels >= 1.0)) {
        throw Error(src + ": element size, voxels per element must be positive and the band at "
                    "least one voxel wide.");
    }
    const double voxel = o.elementSize / o.voxelsPerElement;
    Vec3 lo = surface.vertices.front(), hi = lo;
    for (const auto& p : surface.vertices)
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], p[a]);
            hi[a] = std::max(hi[a], p[a]);
        }
    // Voxels stored: the band around the surface, or the whole inside too.
    const double band = 2.0 * o.halfWidthVoxels * surface.area() / (voxel * voxel);
    const double inside = o.fillInterior ? std::fabs(surface.volume()) / (voxel * voxel * voxel) : 0.0;
    const double bytes = (band + inside) * 4.5 * 2.0;  // values + leaf overhead, built twice
    double budget = o.maxMemoryMB * 1024.0 * 1024.0;
    if (!(o.maxMemoryMB > 0.0)) budget = 0.8 * double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGE_SIZE));
    if (bytes > budget) {
        std::ostringstream m;
        m.precision(3);
        m << src << ": a level set with voxel size " << voxel << " (element size " << o.elementSize
          << ") needs about " << bytes / (1024.0 * 1024.0) << " MiB (estimate), more than the budget of "
          << budget / (1024.0 * 1024.0) << " MiB. Use a larger element size or raise max-memory.";
        throw Error(m.str());
    }

    auto transform = openvdb::math::Transform::createLinearTransform(voxel);
    std::vector<openvdb::Vec3s> points;
    points.reserve(surface.vertices.size());
    for (const auto& p : surface.vertices) {
        // The adapter wants index-space points.
        const openvdb::Vec3d i = transform->worldToIndex(openvdb::Vec3d(p[0], p[1], p[2]));
        points.emplace_back(float(i[0]), float(i[1]), float(i[2]));
    }
    std::vector<openvdb::Vec3I> tris;
    tris.reserve(surface.triangles.size());
    for (const auto& t : surface.triangles) tris.emplace_back(t[0], t[1], t[2]);
    std::vector<openvdb::Vec4I> quads;
    openvdb::tools::QuadAndTriangleDataAdapter<openvdb::Vec3s, openvdb::Vec3I> mesh(points, tris);
    const float interior = o.fillInterior ? std::numeric_limits<float>::max() : float(o.halfWidthVoxels);
    auto grid = openvdb::tools::meshToVolume<openvdb::FloatGrid>(mesh, *transform,
                                                                 float(o.halfWidthVoxels), interior);
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    grid->setName(surface.source.empty() ? "surface" : std::filesystem::path(surface.source).stem().string());

    SurfaceLevelSet out;
    out.grid = grid;
    out.voxelSize = voxel;
    out.field = ImplicitField(grid, o.interpolation);
    out.surface = std::move(surface);
    return out;
}

}  // namespace isohex::imaging
