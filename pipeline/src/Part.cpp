#include "isohex/pipeline/Part.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Dense>

#include "isohex/core/Error.hpp"
#include "isohex/core/SettingError.hpp"

namespace isohex::pipeline {

namespace {

double smallestStep(const octree::Grid& g) {
    const auto s = g.spacing();
    return std::min({s[0], s[1], s[2]});
}

}  // namespace

void checkPartSettings(const MeshSettings& s) {
    if (!s.part) return;
    auto refuse = [](std::vector<MessagePart> why) {
        why.insert(why.begin(), std::string("cannot mesh in parts with "));
        throw SettingError(std::move(why));
    };
    if (s.keepLargest)
        refuse({Setting::KeepLargest, ": which region is largest is a question about the whole scan (mesh it whole, "
                "or select the region first, e.g. as a label map); leave out ", Setting::Part, " or ",
                Setting::KeepLargest});
    if (s.isosurfaceTopology)
        refuse({Setting::IsosurfaceTopology, ": its search spends one budget over the whole grid in grid order; "
                "leave out ", Setting::Part, " or ", Setting::IsosurfaceTopology});
    if (s.method == Method::Sheets)
        refuse({Setting::Method, " sheets: the sheets follow the whole surface; use ", Setting::Method, " dual"});
    if (s.meshExterior)
        refuse({Setting::MeshExterior, ": the box around the object is the whole scan's; leave out ", Setting::Part,
                " or ", Setting::MeshExterior});
    if (s.adaptive)
        refuse({Setting::Adaptive, ": the 27-tree's cuts must lie on its coarsest cells, which parts do not do yet; "
                "leave out ", Setting::Part, " or ", Setting::Adaptive});
    if (s.boundaryLayers != 1)
        refuse({Setting::BoundaryLayers, " above 1: the layers are diced sheets of the whole mesh; leave out ",
                Setting::Part, " or ", Setting::BoundaryLayers});
}

std::vector<std::int32_t> sortedMaterials(const HexMesh& mesh) {
    std::vector<std::int32_t> mats;
    for (std::int32_t m : mesh.material)
        if ((mats.empty() || m != mats.back()) && std::find(mats.begin(), mats.end(), m) == mats.end())
            mats.push_back(m);
    std::sort(mats.begin(), mats.end());
    return mats;
}

int partAxis(const octree::Grid& whole) {
    int axis = 0;
    for (int a = 1; a < 3; ++a)
        if (whole.dims[a] > whole.dims[axis]) axis = a;
    return axis;
}

namespace {

// The first layer of every slab and n (N + 1 entries) for n layers: equal
// layers, or balanced by the weights (integer sums: every part computes the
// same cuts), each moved up where needed so that every slab keeps
// kPartMinLayers.
std::vector<int> cutLayers(int n, int N, const std::vector<std::int64_t>& weights) {
    std::int64_t total = 0;
    for (std::int64_t x : weights) total += x;
    const bool balanced = static_cast<int>(weights.size()) == n && total > 0;
    std::vector<int> cuts(static_cast<std::size_t>(N) + 1, 0);
    cuts[static_cast<std::size_t>(N)] = n;
    std::int64_t before = 0;  // weight of the layers below c
    int c = 0;
    for (int k = 1; k < N; ++k) {
        int at = static_cast<int>(static_cast<long long>(n) * k / N);
        if (balanced) {
            for (; c < n && before * N < total * k; ++c) before += weights[static_cast<std::size_t>(c)];
            at = c;
        }
        cuts[static_cast<std::size_t>(k)] =
            std::clamp(at, cuts[static_cast<std::size_t>(k) - 1] + kPartMinLayers, n - (N - k) * kPartMinLayers);
    }
    return cuts;
}

}  // namespace

PartWindow partWindow(const octree::Grid& whole, PartSpec spec, const std::vector<std::int64_t>& layerWeights) {
    if (spec.count < 1 || spec.index < 1 || spec.index > spec.count)
        throw Error("part " + std::to_string(spec.index) + "/" + std::to_string(spec.count) +
                    ": K/N needs 1 <= K <= N");
    PartWindow w;
    w.spec = spec;
    w.whole = whole;
    w.axis = partAxis(whole);
    const int n = whole.dims[w.axis];
    if (n < spec.count * kPartMinLayers)
        throw SettingError({"the grid has " + std::to_string(n) + " layers along its longest axis, too few for " +
                                std::to_string(spec.count) + " parts of at least " + std::to_string(kPartMinLayers) +
                                " layers each; use fewer parts (", Setting::Part, ") or a smaller ", Setting::Size});
    const std::vector<int> cuts = cutLayers(n, spec.count, layerWeights);
    w.coreLo = cuts[static_cast<std::size_t>(spec.index) - 1];
    w.coreHi = cuts[static_cast<std::size_t>(spec.index)];
    w.first = w.cutBelow() ? std::max(0, w.coreLo - kPartGhostLayers) : 0;
    const int last = w.cutAbove() ? std::min(n, w.coreHi + kPartGhostLayers) : n;  // one past the window
    w.grid = whole;
    for (int c = 0; c < 3; ++c) w.grid.origin[c] += w.first * whole.axes[w.axis][c];
    w.grid.dims[w.axis] = last - w.first;
    return w;
}

std::vector<NodeKey> contourKeys(const HexMesh& mesh, const PartWindow& w) {
    Eigen::Matrix3d axes;
    for (int a = 0; a < 3; ++a)
        for (int c = 0; c < 3; ++c) axes(c, a) = w.grid.axes[a][c];
    const Eigen::Matrix3d toGrid = axes.inverse();
    std::vector<NodeKey> keys(mesh.nodeCount());
    for (std::size_t v = 0; v < mesh.nodeCount(); ++v) {
        const Vec3& p = mesh.nodes[v];
        const Eigen::Vector3d g =
            toGrid * Eigen::Vector3d(p[0] - w.grid.origin[0], p[1] - w.grid.origin[1], p[2] - w.grid.origin[2]);
        std::array<int, 3> cell{};
        for (int a = 0; a < 3; ++a) cell[a] = static_cast<int>(std::floor(g[a]));
        cell[w.axis] += w.first;
        if (!w.whole.contains(cell[0], cell[1], cell[2]))
            throw Error("part meshing: a contoured vertex lies outside the grid (please report this with the input)");
        keys[v] = {static_cast<std::int64_t>(w.whole.index(cell[0], cell[1], cell[2])), 0};
    }
    return keys;
}

void addCopyKeys(std::vector<NodeKey>& keys, const std::vector<PillowResult>& passes,
                 const std::vector<std::int32_t>& materials) {
    for (std::size_t p = 0; p < passes.size(); ++p) {
        const PillowResult& r = passes[p];
        if (static_cast<std::size_t>(r.firstNewNode) != keys.size())
            throw Error("part meshing: the sheets' copies are not numbered after the nodes they copy");
        for (Index original : r.copyOf) {
            const NodeKey k = keys[static_cast<std::size_t>(original)];
            if (k.sheet != 0) throw Error("part meshing: a sheet copied a copied node (please report this)");
            keys.push_back({k.cell, materials[p] + 1});
        }
    }
}

PartNodes keepOwnHexes(HexMesh& mesh, std::vector<NodeKey> keys, const PartWindow& w) {
    const std::size_t N = mesh.nodeCount();
    if (keys.size() != N) throw Error("part meshing: " + std::to_string(keys.size()) + " keys for " +
                                      std::to_string(N) + " nodes");
    auto layer = [&](Index v) { return w.whole.coords(static_cast<std::size_t>(keys[v].cell))[w.axis]; };
    std::vector<std::uint8_t> use(N, 0);  // bit 1: a kept hex, bit 2: a dropped one
    std::size_t kept = 0;
    for (std::size_t h = 0; h < mesh.hexCount(); ++h) {
        int top = 0;
        for (Index v : mesh.hexes[h]) top = std::max(top, layer(v));
        const bool own = top >= w.coreLo && top < w.coreHi;
        for (Index v : mesh.hexes[h]) use[v] |= own ? 1 : 2;
        if (own) {
            mesh.hexes[kept] = mesh.hexes[h];
            mesh.material[kept] = mesh.material[h];
            ++kept;
        }
    }
    mesh.hexes.resize(kept);
    mesh.material.resize(kept);
    std::vector<Index> renumber(N, kNone);
    PartNodes out;
    Index next = 0;
    for (std::size_t v = 0; v < N; ++v) {
        if (!(use[v] & 1)) continue;
        renumber[v] = next;
        mesh.nodes[next] = mesh.nodes[v];
        mesh.nodeClass[next] = mesh.nodeClass[v];
        out.keys.push_back(keys[v]);
        out.onCut.push_back(use[v] == 3 ? 1 : 0);
        if (use[v] == 3) {
            out.cutClasses.push_back(mesh.nodeClass[next]);
            mesh.nodeClass[next] = {NodeKind::Fixed, -1};
        }
        ++next;
    }
    mesh.nodes.resize(next);
    mesh.nodeClass.resize(next);
    for (Hex& h : mesh.hexes)
        for (Index& v : h) v = renumber[v];
    return out;
}

void unfreezeCutNodes(HexMesh& mesh, const PartNodes& nodes) {
    std::size_t c = 0;
    for (std::size_t v = 0; v < mesh.nodeCount(); ++v)
        if (nodes.onCut[v]) mesh.nodeClass[v] = nodes.cutClasses[c++];
}

void addPartArrays(io::WriteOptions& w, const HexMesh& mesh, const PartNodes& nodes, const PartWindow& win) {
    const std::size_t N = nodes.keys.size();
    std::vector<double> cell(N), sheet(N), onCut(N);
    for (std::size_t v = 0; v < N; ++v) {
        cell[v] = static_cast<double>(nodes.keys[v].cell);
        sheet[v] = nodes.keys[v].sheet;
        onCut[v] = nodes.onCut[v];
    }
    w.pointFields.emplace_back("isohex_cell", std::move(cell));
    w.pointFields.emplace_back("isohex_sheet", std::move(sheet));
    w.pointFields.emplace_back("isohex_on_cut", std::move(onCut));
    const auto& d = win.whole.dims;
    w.fieldData.emplace_back("isohex_part", std::vector<double>{double(win.spec.index), double(win.spec.count),
                                                                double(win.axis), double(win.coreLo),
                                                                double(win.coreHi), double(d[0]), double(d[1]),
                                                                double(d[2]), smallestStep(win.whole)});
    std::vector<double> curves;
    for (const auto& c : mesh.curves) curves.insert(curves.end(), c.begin(), c.end());
    w.fieldData.emplace_back("isohex_curves", std::move(curves));
}

}  // namespace isohex::pipeline
