#include "isohex/pipeline/Merge.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <unordered_map>

#include "isohex/core/Error.hpp"
#include "isohex/core/MeshIO.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/octree/RepairedDomain.hpp"
#include "isohex/pipeline/FieldProjector.hpp"
#include "isohex/pipeline/Part.hpp"
#include "isohex/pipeline/SelectionDomain.hpp"

namespace isohex::pipeline {

namespace {

// One part file as read.
struct PartFile {
    std::string path;
    HexMesh mesh;
    std::vector<NodeKey> keys;
    std::vector<std::uint8_t> onCut;
    std::vector<std::array<std::int32_t, 3>> curves;
    int index = 0, count = 0, axis = 0, coreLo = 0, coreHi = 0;
    std::array<int, 3> dims{};
    double step = 0;
};

struct KeyHash {
    std::size_t operator()(const NodeKey& k) const {
        return std::hash<std::int64_t>()(k.cell * 31 + k.sheet);
    }
};

// A cut node seen so far: where it went and which part first had it.
struct Seen {
    Index merged = kNone;
    int part = 0;
    int times = 1;
};

// What the phases of mergeParts share.
struct MergeState {
    std::vector<PartFile> parts;  // in part order
    MergeResult r;
    std::map<std::pair<std::int32_t, std::int32_t>, std::int32_t> surfaceIds;  // (inside, outside) -> merged id
    std::map<std::array<std::int32_t, 3>, std::int32_t> curveIds;
    std::unordered_map<NodeKey, Seen, KeyHash> cut;
};

const std::vector<double>& required(const io::NamedArrays& a, const std::string& name, bool point,
                                    const std::string& path) {
    const std::vector<double>* v = point ? a.point(name) : a.field(name);
    if (!v)
        throw Error(path + ": not a part file (it has no '" + name +
                    "' array); write parts with isohex mesh INPUT --part K/N -o part.vtu");
    return *v;
}

PartFile readPart(const std::string& path) {
    PartFile f;
    f.path = path;
    io::NamedArrays a;
    f.mesh = io::readWithArrays(path, {"isohex_cell", "isohex_sheet", "isohex_on_cut"},
                                {"isohex_part", "isohex_curves"}, a);
    const auto& cell = required(a, "isohex_cell", true, path);
    const auto& sheet = required(a, "isohex_sheet", true, path);
    const auto& onCut = required(a, "isohex_on_cut", true, path);
    const auto& meta = required(a, "isohex_part", false, path);
    if (meta.size() < 9) throw Error(path + ": its isohex_part array is damaged (" + std::to_string(meta.size()) +
                                     " values, expected 9)");
    f.keys.resize(cell.size());
    f.onCut.resize(cell.size());
    for (std::size_t v = 0; v < cell.size(); ++v) {
        f.keys[v] = {static_cast<std::int64_t>(cell[v]), static_cast<std::int32_t>(sheet[v])};
        f.onCut[v] = onCut[v] != 0;
    }
    f.index = static_cast<int>(meta[0]);
    f.count = static_cast<int>(meta[1]);
    f.axis = static_cast<int>(meta[2]);
    f.coreLo = static_cast<int>(meta[3]);
    f.coreHi = static_cast<int>(meta[4]);
    f.dims = {static_cast<int>(meta[5]), static_cast<int>(meta[6]), static_cast<int>(meta[7])};
    f.step = meta[8];
    if (const auto* c = a.field("isohex_curves"))
        for (std::size_t i = 0; i + 2 < c->size(); i += 3)
            f.curves.push_back({static_cast<std::int32_t>((*c)[i]), static_cast<std::int32_t>((*c)[i + 1]),
                                static_cast<std::int32_t>((*c)[i + 2])});
    return f;
}

// Reads every part and checks they are the N parts of one split, each once.
void readParts(MergeState& s, const std::vector<std::string>& paths) {
    if (paths.empty()) throw Error("no part files given; name the part files of one split (isohex mesh --part K/N)");
    for (const auto& p : paths) s.parts.push_back(readPart(p));
    std::sort(s.parts.begin(), s.parts.end(), [](const PartFile& a, const PartFile& b) { return a.index < b.index; });
    const PartFile& first = s.parts.front();
    for (const PartFile& f : s.parts)
        if (f.count != first.count || f.dims != first.dims || f.axis != first.axis)
            throw Error(f.path + ": is part " + std::to_string(f.index) + "/" + std::to_string(f.count) +
                        " of another split than " + first.path + " (" + std::to_string(first.index) + "/" +
                        std::to_string(first.count) + "): a different part count or grid; mesh every part with the "
                        "same input and options");
    for (std::size_t i = 0; i < s.parts.size(); ++i) {
        const PartFile& f = s.parts[i];
        if (i > 0 && f.index == s.parts[i - 1].index)
            throw Error(f.path + " and " + s.parts[i - 1].path + " are both part " + std::to_string(f.index) + "/" +
                        std::to_string(f.count) + "; give each part once");
    }
    for (int k = 1; k <= first.count; ++k)
        if (std::none_of(s.parts.begin(), s.parts.end(), [&](const PartFile& f) { return f.index == k; }))
            throw Error("part " + std::to_string(k) + "/" + std::to_string(first.count) +
                        " is missing; merge needs all " + std::to_string(first.count) + " parts of the split");
    for (std::size_t i = 1; i < s.parts.size(); ++i)
        if (s.parts[i].coreLo != s.parts[i - 1].coreHi)
            throw Error(s.parts[i].path + ": its slab does not start where " + s.parts[i - 1].path +
                        "'s ends; mesh every part with the same input and options");
    s.r.parts = first.count;
}

// The merged surfaces and curves: every part's, each once, in sorted order.
void mergeSurfaces(MergeState& s) {
    for (const PartFile& f : s.parts) {
        for (const auto& t : f.mesh.surfaces) s.surfaceIds.emplace(std::make_pair(t.inside, t.outside), 0);
        for (const auto& c : f.curves) s.curveIds.emplace(c, 0);
    }
    std::int32_t id = 0;
    for (auto& [tag, i] : s.surfaceIds) {
        i = id++;
        SurfaceTag t;
        t.inside = tag.first;
        t.outside = tag.second;
        for (const PartFile& f : s.parts)
            for (const auto& pt : f.mesh.surfaces)
                if (pt.inside == t.inside && pt.outside == t.outside && t.name.empty()) t.name = pt.name;
        s.r.mesh.surfaces.push_back(t);
    }
    id = 0;
    for (auto& [c, i] : s.curveIds) {
        i = id++;
        s.r.mesh.curves.push_back(c);
    }
}

// A part's node class in the merged mesh's surface and curve numbering.
NodeClass mergedClass(const MergeState& s, const PartFile& f, NodeClass c) {
    if (c.kind == NodeKind::Surface && c.id >= 0 && static_cast<std::size_t>(c.id) < f.mesh.surfaces.size()) {
        const auto& t = f.mesh.surfaces[static_cast<std::size_t>(c.id)];
        c.id = s.surfaceIds.at({t.inside, t.outside});
    } else if (c.kind == NodeKind::Curve) {
        c.id = c.id >= 0 && static_cast<std::size_t>(c.id) < f.curves.size()
                   ? s.curveIds.at(f.curves[static_cast<std::size_t>(c.id)])
                   : -1;
    }
    return c;
}

// The nodes of part p (index into s.parts) in the merged numbering; its cut
// nodes matched by key with the lower parts' cut nodes.
std::vector<Index> joinNodes(MergeState& s, std::size_t p) {
    PartFile& f = s.parts[p];
    HexMesh& m = s.r.mesh;
    std::vector<Index> to(f.mesh.nodeCount(), kNone);
    CutMatch* below = p > 0 ? &s.r.cuts[p - 1] : nullptr;
    for (std::size_t v = 0; v < f.mesh.nodeCount(); ++v) {
        const NodeKey key = f.keys[v];
        const auto it = s.cut.find(key);
        if (it != s.cut.end()) {
            Seen& seen = it->second;
            if (!f.onCut[v] || seen.part != static_cast<int>(p) - 1 || seen.times > 1)
                throw Error(f.path + ": node " + std::to_string(v) + " (grid cell " + std::to_string(key.cell) +
                            ", sheet " + std::to_string(key.sheet) + ") is also a node of " +
                            s.parts[static_cast<std::size_t>(seen.part)].path +
                            " but not on their common cut: the parts overlap; mesh every part with the same input, "
                            "options and isohex version");
            ++seen.times;
            const Vec3& a = m.nodes[static_cast<std::size_t>(seen.merged)];
            const Vec3& b = f.mesh.nodes[v];
            const double d = std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
            if (d > kCutOffsetRefused * f.step)
                throw Error(f.path + ": node " + std::to_string(v) + " on the cut with part " +
                            std::to_string(p) + " lies " + std::to_string(d) +
                            " from where that part put it: the two parts meshed the cut differently (please report "
                            "this with the input and options)");
            below->maxOffset = std::max(below->maxOffset, d);
            s.r.onCut[static_cast<std::size_t>(seen.merged)] = 1;
            ++below->nodes;
            to[v] = seen.merged;
            continue;
        }
        to[v] = m.addNode(f.mesh.nodes[v], mergedClass(s, f, f.mesh.nodeClass[v]));
        s.r.onCut.push_back(0);
        if (f.onCut[v]) s.cut.emplace(key, Seen{to[v], static_cast<int>(p), 1});
    }
    return to;
}

// Every cut node must have been matched by the part across its cut.
void checkMatched(const MergeState& s) {
    std::size_t unmatched = 0;
    const Seen* one = nullptr;
    for (const auto& [key, seen] : s.cut)
        if (seen.times < 2) {
            ++unmatched;
            if (!one || seen.merged < one->merged) one = &seen;
        }
    if (unmatched == 0) return;
    const Vec3& at = s.r.mesh.nodes[static_cast<std::size_t>(one->merged)];
    throw Error(std::to_string(unmatched) + " node(s) on the cuts have no match in the neighbouring part (the first "
                "of " + s.parts[static_cast<std::size_t>(one->part)].path + " at " + std::to_string(at[0]) + ", " +
                std::to_string(at[1]) + ", " + std::to_string(at[2]) +
                "): the parts did not mesh their cut alike; mesh every part with the same input, options and isohex "
                "version (please report it if they were)");
}

// The scan's whole grid must be the one the parts were cut from.
void checkScanGrid(const MergeState& s, const std::string& scanPath, const octree::Grid& g) {
    const PartFile& f = s.parts.front();
    const auto sp = g.spacing();
    const double step = std::min({sp[0], sp[1], sp[2]});
    if (g.dims == f.dims && std::abs(step - f.step) <= 1e-9 * f.step) return;
    throw Error(scanPath + ": with these options its grid is " + std::to_string(g.dims[0]) + " x " +
                std::to_string(g.dims[1]) + " x " + std::to_string(g.dims[2]) + " points of step " +
                std::to_string(step) + ", but " + f.path + " was cut from " + std::to_string(f.dims[0]) + " x " +
                std::to_string(f.dims[1]) + " x " + std::to_string(f.dims[2]) + " of step " + std::to_string(f.step) +
                "; give merge --scan the scan and the mesh options of the parts");
}

// Reads and joins the parts (the band pass left to the caller).
MergeState joinParts(const std::vector<std::string>& paths) {
    MergeState s;
    readParts(s, paths);
    mergeSurfaces(s);
    for (std::size_t p = 1; p < s.parts.size(); ++p) s.r.cuts.push_back({static_cast<int>(p), 0, 0.0});
    for (std::size_t p = 0; p < s.parts.size(); ++p) {
        const std::vector<Index> to = joinNodes(s, p);
        PartFile& f = s.parts[p];
        for (std::size_t h = 0; h < f.mesh.hexCount(); ++h) {
            Hex hex = f.mesh.hexes[h];
            for (Index& v : hex) v = to[static_cast<std::size_t>(v)];
            s.r.mesh.addHex(hex, f.mesh.material[h]);
        }
        s.r.hexesPerPart.push_back(f.mesh.hexCount());
        s.r.nodesPerPart.push_back(f.mesh.nodeCount());
        f.mesh = {};  // what is merged is not needed twice
    }
    checkMatched(s);
    return s;
}

}  // namespace

MergeResult mergeParts(const std::vector<std::string>& paths, bool optimiseBands) {
    const Stopwatch clock;
    MergeState s = joinParts(paths);
    if (optimiseBands) s.r.bands = optimiseCutBands(s.r.mesh, s.r.onCut);
    s.r.seconds = clock.seconds();
    return std::move(s.r);
}

MergeResult mergeParts(const std::vector<std::string>& paths, bool optimiseBands, const MergeScan& scan) {
    const Stopwatch clock;
    MergeState s = joinParts(paths);
    const Prepared& p = *scan.prepared;
    checkScanGrid(s, p.facts.input.path, p.facts.grid.grid);
    if (optimiseBands) {
        // First on the merged boundary (its nodes slide freely out of where
        // the frozen cuts left them), then on the scan's isosurface, with the
        // projector the single run's optimiser uses over the merged mesh's
        // surfaces and curves: the boundary nodes go back onto the isosurface
        // (MergeResult::scanBands).
        s.r.bands = optimiseCutBands(s.r.mesh, s.r.onCut);
        const FieldProjector projector(*static_cast<const SelectionDomain*>(p.domain.get()), s.r.mesh,
                                       static_cast<const octree::RepairedDomain*>(p.repairedDomain.get()));
        const CutBandScan band{&projector,
                               scan.surfaceToleranceVoxels * p.selection->materials.front().field.voxelSize(),
                               scan.stretchTarget};
        s.r.scanBands = optimiseCutBands(s.r.mesh, s.r.onCut, &band);
        for (int i = 1; i < kCutBandScanPasses; ++i) {
            const CutBandResult more = optimiseCutBands(s.r.mesh, s.r.onCut, &band);
            CutBandResult& b = *s.r.scanBands;
            b.seconds += more.seconds;
            if (!more.kept) continue;
            b.nodes = std::max(b.nodes, more.nodes);
            b.hexes = std::max(b.hexes, more.hexes);
            b.minAfter = more.minAfter;
            b.invertedAfter = more.invertedAfter;
            b.kept = true;
        }
    }
    s.r.seconds = clock.seconds();
    return std::move(s.r);
}

}  // namespace isohex::pipeline
