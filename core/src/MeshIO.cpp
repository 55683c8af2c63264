// Format dispatch for mesh files, plus the small helpers the writers share.
#include "isohex/core/MeshIO.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <filesystem>
#include <system_error>

#include "MeshFormatPlugin.hpp"
#include "MeshIODetail.hpp"
#include "isohex/core/AtomicFile.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/HexCell.hpp"

namespace isohex::io {

namespace {

struct Extension {
    const char* ext;
    Format format;
};
constexpr Extension kExtensions[] = {
    {".vtu", Format::Vtu},       {".msh", Format::Msh},       {".exo", Format::Exodus}, {".e", Format::Exodus},
    {".ex2", Format::Exodus},    {".inp", Format::Abaqus},    {".mesh", Format::Medit},
};

std::string joined(const std::vector<std::string>& items) {
    std::string s;
    for (const auto& i : items) s += (s.empty() ? "" : ", ") + i;
    return s;
}

}  // namespace

Format formatFromPath(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    for (const auto& e : kExtensions)
        if (ext == e.ext) return e.format;
    throw Error(path + ": unknown mesh file type '" + ext + "'; use one of " + joined(writableExtensions()));
}

bool canRead(Format f) { return f == Format::Vtu || f == Format::Msh; }

std::vector<std::string> writableExtensions() {
    std::vector<std::string> out;
    for (const auto& e : kExtensions) out.emplace_back(e.ext);
    return out;
}

std::vector<std::string> readableExtensions() {
    std::vector<std::string> out;
    for (const auto& e : kExtensions)
        if (canRead(e.format)) out.emplace_back(e.ext);
    return out;
}

void write(const HexMesh& mesh, const std::string& path, const WriteOptions& opt) {
    const Format format = formatFromPath(path);
    mesh.checkConsistent(path);
    if (mesh.hexes.empty())
        throw Error(path + ": the mesh has no hexahedra; nothing to write (check the input and the selection)");
    if (!opt.scaledJacobian.empty() && opt.scaledJacobian.size() != mesh.hexCount())
        throw Error(path + ": " + std::to_string(opt.scaledJacobian.size()) +
                    " scaled Jacobian values given for " + std::to_string(mesh.hexCount()) + " hexes");
    for (std::size_t i = 0; i < opt.cellFields.size(); ++i) {
        const auto& [name, values] = opt.cellFields[i];
        if (name.empty() || name == "material" || name == "scaled_jacobian")
            throw Error(path + ": cell field name '" + name + "' is empty or reserved");
        for (std::size_t j = 0; j < i; ++j)
            if (opt.cellFields[j].first == name) throw Error(path + ": cell field '" + name + "' given twice");
        if (values.size() != mesh.hexCount())
            throw Error(path + ": cell field '" + name + "' has " + std::to_string(values.size()) +
                        " values for " + std::to_string(mesh.hexCount()) + " hexes");
    }
    for (const auto& [name, values] : opt.pointFields)
        if (name.empty() || name == "node_class" || name == "node_surface" || values.size() != mesh.nodeCount())
            throw Error(path + ": point field '" + name + "' is reserved or has " + std::to_string(values.size()) +
                        " values for " + std::to_string(mesh.nodeCount()) + " nodes");
    if ((!opt.pointFields.empty() || !opt.fieldData.empty()) && format != Format::Vtu)
        throw Error(path + ": point fields and field data are written to .vtu files only");
    // A format's library is loaded before the temporary file exists.
    const bool viaPlugin = format == Format::Vtu || format == Format::Msh || format == Format::Exodus;
    const detail::MeshFormatPlugin* plugin = viaPlugin ? &detail::meshFormatPlugin(format) : nullptr;
    writeAtomically(path, opt.overwrite, [&](const std::string& tmp) {
        switch (format) {
            case Format::Vtu:
            case Format::Msh:
            case Format::Exodus: plugin->write(mesh, tmp, path, opt); break;
            case Format::Abaqus: detail::writeAbaqus(mesh, tmp, path); break;
            case Format::Medit: detail::writeMedit(mesh, tmp, path); break;
        }
    });
}

namespace {

HexMesh readChecked(const std::string& path, const detail::ArrayRequest* arrays) {
    Format format{};
    try {
        format = formatFromPath(path);
    } catch (const Error&) {
        // formatFromPath lists every format isohex writes; a reader wants
        // the ones it can read.
        std::string ext = std::filesystem::path(path).extension().string();
        throw Error(path + ": unknown mesh file type '" + ext + "'; isohex reads " + joined(readableExtensions()));
    }
    if (!canRead(format))
        throw Error(path + ": isohex writes this format but cannot read it; read one of " +
                    joined(readableExtensions()));
    detail::requireReadableFile(path);
    if (arrays && format != Format::Vtu) throw Error(path + ": expected a .vtu file (with isohex's arrays)");
    HexMesh mesh = detail::meshFormatPlugin(format).read(path, arrays);  // canRead: .vtu or .msh
    mesh.checkConsistent(path);
    if (mesh.hexCount() == 0)
        throw Error(path + ": the mesh holds no hexahedra, so there is nothing to judge, smooth or convert; check "
                           "that this is the right file");
    // Surfaces are named by material pairs, and a pair's negative side means
    // the outside: a negative material id would be taken for it (interfaces
    // written as boundaries, duplicate surface names).
    for (std::size_t h = 0; h < mesh.material.size(); ++h)
        if (mesh.material[h] < 0)
            throw Error(path + ": hex " + std::to_string(h) + " has material id " + std::to_string(mesh.material[h]) +
                        "; isohex needs material ids of 0 or more (negative ids mean the outside). Renumber the "
                        "materials and retry.");
    // The quality measures multiply three squared edge lengths, which
    // overflows to infinity past about 1e51 and then the optimiser's steps
    // never end (`smooth` hung on a mesh scaled by 1e300). No unit puts a
    // real mesh anywhere near 1e30.
    for (std::size_t v = 0; v < mesh.nodes.size(); ++v)
        for (int a = 0; a < 3; ++a)
            if (!(std::abs(mesh.nodes[v][static_cast<std::size_t>(a)]) <= 1e30)) {
                std::ostringstream m;
                m << path << ": node " << v << " has coordinate " << mesh.nodes[v][static_cast<std::size_t>(a)]
                  << "; isohex reads coordinates up to 1e30 in size (and finite). Check the file's units and content.";
                throw Error(m.str());
            }
    return mesh;
}

const std::vector<double>* findArray(const std::vector<std::pair<std::string, std::vector<double>>>& list,
                                     const std::string& name) {
    for (const auto& [n, values] : list)
        if (n == name) return &values;
    return nullptr;
}

}  // namespace

const std::vector<double>* NamedArrays::point(const std::string& name) const { return findArray(pointFields, name); }
const std::vector<double>* NamedArrays::field(const std::string& name) const { return findArray(fieldData, name); }

HexMesh read(const std::string& path) { return readChecked(path, nullptr); }

HexMesh readWithArrays(const std::string& path, const std::vector<std::string>& pointNames,
                       const std::vector<std::string>& fieldNames, NamedArrays& arrays) {
    arrays = {};
    const detail::ArrayRequest request{pointNames, fieldNames, arrays};
    return readChecked(path, &request);
}

namespace detail {

void requireReadableFile(const std::string& path) {
    namespace fs = std::filesystem;
    std::error_code ec;
    const auto st = fs::status(path, ec);
    if (ec || !fs::exists(st)) throw Error(path + ": no such file");
    if (fs::is_directory(st)) throw Error(path + ": is a folder, not a mesh file");
    if (!fs::is_regular_file(st)) throw Error(path + ": is not a regular file");
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) throw Error(path + ": cannot open: " + std::strerror(errno));
    std::fclose(f);
}

std::vector<std::int32_t> materialsOf(const HexMesh& mesh) {
    std::vector<std::int32_t> mats(mesh.material);
    std::sort(mats.begin(), mats.end());
    mats.erase(std::unique(mats.begin(), mats.end()), mats.end());
    return mats;
}

std::vector<int> positiveIds(const std::vector<std::int32_t>& mats) {
    std::vector<int> ids(mats.size());
    std::vector<std::int32_t> used;
    for (std::int32_t m : mats)
        if (m > 0) used.push_back(m);
    std::int32_t candidate = 1;
    for (std::size_t i = 0; i < mats.size(); ++i) {
        if (mats[i] > 0) {
            ids[i] = mats[i];
            continue;
        }
        while (std::binary_search(used.begin(), used.end(), candidate)) ++candidate;
        ids[i] = candidate;
        used.insert(std::lower_bound(used.begin(), used.end(), candidate), candidate);
    }
    return ids;
}

std::vector<std::vector<Index>> hexesByMaterial(const HexMesh& mesh, const std::vector<std::int32_t>& mats) {
    std::vector<std::vector<Index>> out(mats.size());
    for (std::size_t h = 0; h < mesh.hexCount(); ++h) {
        const auto it = std::lower_bound(mats.begin(), mats.end(), mesh.material[h]);
        out[static_cast<std::size_t>(it - mats.begin())].push_back(static_cast<Index>(h));
    }
    return out;
}

std::vector<NamedPatch> namedSurfaces(const HexMesh& mesh) {
    std::vector<NamedPatch> out;
    if (mesh.hexes.empty()) return out;
    for (SurfacePatch& p : surfacePatches(mesh, buildTopology(mesh))) {
        std::string name = p.tag.name;
        if (name.empty())
            for (const SurfaceTag& s : mesh.surfaces)
                if (s.inside == p.tag.inside && s.outside == p.tag.outside && !s.name.empty()) name = s.name;
        if (name.empty()) name = surfaceName(p.tag);
        out.push_back({std::move(name), std::move(p)});
    }
    return out;
}

std::array<Index, 4> faceNodes(const HexMesh& mesh, Index hex, int face) {
    const Hex& h = mesh.hexes[hex];
    const auto& f = hexcell::kFaces[face];
    return {h[f[0]], h[f[1]], h[f[2]], h[f[3]]};
}

TextOut::TextOut(const std::string& tmpPath, const std::string& path) : path_(path) {
    file_ = std::fopen(tmpPath.c_str(), "wb");
    if (!file_) throw Error(path + ": cannot create the file: " + std::strerror(errno));
    buffer_.reserve(1 << 20);
}

TextOut::~TextOut() {
    if (file_) std::fclose(file_);
}

void TextOut::flush() {
    if (buffer_.empty()) return;
    if (std::fwrite(buffer_.data(), 1, buffer_.size(), file_) != buffer_.size())
        throw Error(path_ + ": write failed: " + std::strerror(errno));
    buffer_.clear();
}

TextOut& TextOut::operator<<(std::string_view s) {
    buffer_.append(s);
    if (buffer_.size() >= (1 << 20)) flush();
    return *this;
}

TextOut& TextOut::operator<<(char c) {
    buffer_.push_back(c);
    return *this;
}

TextOut& TextOut::operator<<(std::int64_t v) {
    char buf[24];
    auto r = std::to_chars(buf, buf + sizeof buf, v);
    return *this << std::string_view(buf, static_cast<std::size_t>(r.ptr - buf));
}

TextOut& TextOut::operator<<(double v) {
    char buf[32];
    auto r = std::to_chars(buf, buf + sizeof buf, v);
    return *this << std::string_view(buf, static_cast<std::size_t>(r.ptr - buf));
}

void TextOut::close() {
    flush();
    std::FILE* f = file_;
    file_ = nullptr;
    const bool bad = std::ferror(f) != 0;
    if (std::fclose(f) != 0 || bad) throw Error(path_ + ": write failed: " + std::strerror(errno));
}

}  // namespace detail

}  // namespace isohex::io
