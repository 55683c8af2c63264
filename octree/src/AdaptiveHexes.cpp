#include "isohex/octree/AdaptiveHexes.hpp"

#include <algorithm>

#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include "isohex/core/Error.hpp"
#include "isohex/octree/TransitionTemplates.hpp"

namespace isohex::octree {

namespace {

constexpr std::int64_t kS = kKeySteps;
constexpr int kRef[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};

// The leaves of the tree, visited depth first from the roots in index order.
struct LeafWalk {
    const RefinementTree& tree;
    const Labels& labels;
    LeafHexes out;

    static std::int64_t power3(int l) {
        std::int64_t s = 1;
        for (int i = 0; i < l; ++i) s *= 3;
        return s;
    }

    void add(const std::array<NodeKey, 8>& h, std::int32_t material, int level, LeafForm form) {
        out.hexes.push_back(h);
        out.material.push_back(material);
        out.level.push_back(static_cast<std::uint8_t>(level));
        out.form.push_back(form);
    }

    // Counts a leaf of `level` cut as `form` when it gave a labelled hex.
    void countLeaf(int level, LeafForm form, std::size_t hexesBefore) {
        if (out.hexes.size() == hexesBefore) return;
        auto& perLevel = out.leavesPerForm;
        if (static_cast<std::size_t>(level) >= perLevel.size()) perLevel.resize(static_cast<std::size_t>(level) + 1, {});
        ++perLevel[static_cast<std::size_t>(level)][static_cast<std::size_t>(form)];
    }

    // Grid point (i, j, k): its hex when labelled.
    void point(int i, int j, int k) {
        if (!labels.grid.contains(i, j, k)) return;
        const std::int32_t m = labels.material[labels.grid.index(i, j, k)];
        if (m == 0) return;
        std::array<NodeKey, 8> h;
        for (int c = 0; c < 8; ++c) h[c] = nodeKey(kS * (i + kRef[c][0]), kS * (j + kRef[c][1]), kS * (k + kRef[c][2]));
        const std::size_t before = out.hexes.size();
        add(h, m, 0, LeafForm::Whole);
        countLeaf(0, LeafForm::Whole, before);
    }

    // The label of the grid point whose level-0 hex holds the centroid of h
    // (a level-0 hex's own point, a coarse leaf's centre point).
    std::int32_t centroidLabel(const std::array<NodeKey, 8>& h) const {
        std::int64_t sum[3] = {0, 0, 0};
        for (NodeKey k : h) {
            const auto q = keyCoords(k);
            for (int c = 0; c < 3; ++c) sum[c] += q[c];
        }
        return labels.at(static_cast<int>(sum[0] / (8 * kS)), static_cast<int>(sum[1] / (8 * kS)),
                         static_cast<int>(sum[2] / (8 * kS)));
    }

    void addLabelled(const std::array<NodeKey, 8>& h, int level, LeafForm form) {
        const std::int32_t m = centroidLabel(h);
        if (m != 0) add(h, m, level, form);
    }

    // An unrefined level-l cell: one hex, or its template's hexes, each with
    // the label at its centroid (a leaf may straddle a surface).
    void leaf(int l, int i, int j, int k, std::uint8_t marks) {
        const std::int64_t side = power3(l);
        const std::int64_t a[3] = {side * i, side * j, side * k};
        const TemplateChoice choice = chooseTemplate(marks);
        if (choice.action == TemplateChoice::Action::Promote)
            throw Error("internal error: a leaf of the refinement tree has marked corners no template takes");
        const LeafForm form = leafForm(choice);
        const std::size_t before = out.hexes.size();
        if (choice.action == TemplateChoice::Action::Plain) {
            std::array<NodeKey, 8> h;
            for (int c = 0; c < 8; ++c)
                h[c] = nodeKey(kS * (a[0] + side * kRef[c][0]), kS * (a[1] + side * kRef[c][1]),
                               kS * (a[2] + side * kRef[c][2]));
            addLabelled(h, l, form);
        } else {
            const std::int64_t child = side / 3;  // template coordinates are twelfths of a child
            for (const TemplateHex& th : templateHexes(choice.kind)) {
                const TemplateHex t = choice.symmetry.apply(th);
                std::array<NodeKey, 8> h;
                for (int c = 0; c < 8; ++c)
                    h[c] = nodeKey(kS * a[0] + t[c][0] * child, kS * a[1] + t[c][1] * child, kS * a[2] + t[c][2] * child);
                addLabelled(h, l, form);
            }
        }
        countLeaf(l, form, before);
    }

    void cell(int l, int i, int j, int k) {
        if (l == 0) {
            point(i, j, k);
            return;
        }
        const RefinementLevel& L = tree.levels[static_cast<std::size_t>(l)];
        if (!L.contains(i, j, k)) return;
        const std::size_t c = L.index(i, j, k);
        if (!L.refined[c]) {
            leaf(l, i, j, k, L.marks[c]);
            return;
        }
        for (int z = 0; z < 3; ++z)
            for (int y = 0; y < 3; ++y)
                for (int x = 0; x < 3; ++x) cell(l - 1, 3 * i + x, 3 * j + y, 3 * k + z);
    }
};

}  // namespace

LeafForm leafForm(const TemplateChoice& choice) {
    if (choice.action != TemplateChoice::Action::Template) return LeafForm::Whole;
    return static_cast<LeafForm>(1 + static_cast<int>(choice.kind));
}

LeafHexes leafHexes(const RefinementTree& tree, const Labels& labels) {
    if (tree.points != labels.grid.dims) throw Error("internal error: the refinement tree was built for another grid");
    for (int c = 0; c < 3; ++c)
        if (kS * (static_cast<std::int64_t>(tree.points[c]) + 1) >= (std::int64_t{1} << 21))
            throw Error("the grid is too large for the adaptive mesher (more than 174,000 points along an axis)");
    LeafWalk walk{tree, labels, {}};
    const RefinementLevel& roots = tree.levels.back();
    for (int k = 0; k < roots.dims[2]; ++k)
        for (int j = 0; j < roots.dims[1]; ++j)
            for (int i = 0; i < roots.dims[0]; ++i) walk.cell(tree.top(), i, j, k);
    return std::move(walk.out);
}

AdaptiveMesh assembleAdaptive(const LeafHexes& leaves, const Grid& grid, const NodePlacer& place) {
    AdaptiveMesh out;
    auto& keys = out.nodeKeys;
    keys.reserve(leaves.hexes.size() * 8);
    for (const auto& h : leaves.hexes) keys.insert(keys.end(), h.begin(), h.end());
    tbb::parallel_sort(keys.begin(), keys.end());
    keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
    HexMesh& mesh = out.mesh;
    mesh.nodes.resize(keys.size());
    mesh.nodeClass.assign(keys.size(), NodeClass{});
    tbb::parallel_for(std::size_t{0}, keys.size(), [&](std::size_t n) {
        const auto q = keyCoords(keys[n]);
        mesh.nodes[n] = grid.point(q[0] / double(kS) - 0.5, q[1] / double(kS) - 0.5, q[2] / double(kS) - 0.5);
        if (place) place(keys[n], mesh.nodes[n], mesh.nodeClass[n]);
    });
    const bool mirrored = grid.determinant() < 0;
    mesh.hexes.resize(leaves.hexes.size());
    tbb::parallel_for(std::size_t{0}, leaves.hexes.size(), [&](std::size_t h) {
        Hex hex;
        for (int c = 0; c < 8; ++c)
            hex[c] = static_cast<Index>(std::lower_bound(keys.begin(), keys.end(), leaves.hexes[h][c]) - keys.begin());
        if (mirrored) {
            std::swap(hex[1], hex[3]);
            std::swap(hex[5], hex[7]);
        }
        mesh.hexes[h] = hex;
    });
    mesh.material = leaves.material;
    out.hexLevel = leaves.level;
    for (std::size_t h = 0; h < leaves.level.size(); ++h) {
        const std::uint8_t l = leaves.level[h];
        if (l >= out.hexesPerLevel.size()) {
            out.hexesPerLevel.resize(l + 1u, 0);
            out.hexesPerForm.resize(l + 1u, {});
        }
        ++out.hexesPerLevel[l];
        ++out.hexesPerForm[l][static_cast<std::size_t>(leaves.form[h])];
    }
    out.leavesPerForm = leaves.leavesPerForm;
    out.leavesPerForm.resize(out.hexesPerForm.size(), {});
    return out;
}

UniformNodes::UniformNodes(const Labels& labels, const HexMesh& uniform) {
    const Grid& g = labels.grid;
    const auto [nx, ny, nz] = g.dims;
    dims = {nx + 1, ny + 1, nz + 1};
    // The uniform mesh's hexes are the labelled points in index order, corner
    // c at cell p + kRef[c] (two corner pairs swapped on a mirrored grid, as
    // dualContourHexes does).
    node.assign(static_cast<std::size_t>(nx + 1) * (ny + 1) * (nz + 1), kNone);
    const bool mirrored = g.determinant() < 0;
    std::size_t h = 0;
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                if (labels.material[g.index(i, j, k)] == 0) continue;
                if (h >= uniform.hexes.size()) throw Error("internal error: the uniform mesh has fewer hexes than labelled points");
                Hex hex = uniform.hexes[h++];
                if (mirrored) {
                    std::swap(hex[1], hex[3]);
                    std::swap(hex[5], hex[7]);
                }
                for (int c = 0; c < 8; ++c)
                    node[(static_cast<std::size_t>(k + kRef[c][2]) * dims[1] + static_cast<std::size_t>(j + kRef[c][1])) *
                             dims[0] +
                         static_cast<std::size_t>(i + kRef[c][0])] = hex[c];
            }
    if (h != uniform.hexes.size()) throw Error("internal error: the uniform mesh has more hexes than labelled points");
}

Index UniformNodes::at(NodeKey key) const {
    const auto q = keyCoords(key);
    if (q[0] % kS || q[1] % kS || q[2] % kS) return kNone;  // not a level-0 node
    if (q[0] / kS >= dims[0] || q[1] / kS >= dims[1] || q[2] / kS >= dims[2]) return kNone;
    return node[(static_cast<std::size_t>(q[2] / kS) * static_cast<std::size_t>(dims[1]) +
                 static_cast<std::size_t>(q[1] / kS)) *
                    static_cast<std::size_t>(dims[0]) +
                static_cast<std::size_t>(q[0] / kS)];
}

AdaptiveMesh coarsenDualMesh(const Labels& labels, const RefinementTree& tree, const HexMesh& uniform) {
    const UniformNodes cellNode(labels, uniform);
    const NodePlacer place = [&](NodeKey key, Vec3& x, NodeClass& cls) {
        const Index v = cellNode.at(key);
        if (v == kNone) return;
        x = uniform.nodes[static_cast<std::size_t>(v)];
        cls = uniform.nodeClass[static_cast<std::size_t>(v)];
    };
    AdaptiveMesh out = assembleAdaptive(leafHexes(tree, labels), labels.grid, place);
    out.mesh.surfaces = uniform.surfaces;
    out.mesh.curves = uniform.curves;
    return out;
}

}  // namespace isohex::octree
