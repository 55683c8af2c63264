#include "isohex/core/Sheets.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "Parallel.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/HexCell.hpp"
#include "isohex/core/QuadSurface.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Validate.hpp"
#include "isohex/core/VecMath.hpp"

namespace isohex {

namespace {

using namespace vec;

// Reference coordinates of the VTK hex corners.
constexpr int kRef[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};

// The three faces (hexcell::kFaces) that meet at each corner.
constexpr int kCornerFaces[8][3] = {{0, 2, 4}, {1, 2, 4}, {1, 3, 4}, {0, 3, 4},
                                    {0, 2, 5}, {1, 2, 5}, {1, 3, 5}, {0, 3, 5}};

std::uint64_t mix64(std::uint64_t h) {  // splitmix64's finaliser
    h ^= h >> 30;
    h *= 0xBF58476D1CE4E5B9ull;
    h ^= h >> 27;
    h *= 0x94D049BB133111EBull;
    return h ^ (h >> 31);
}

// A hash of the set of a quad's four nodes (the same for any order of them).
std::uint64_t quadHash(Index a, Index b, Index c, Index d) {
    if (a > b) std::swap(a, b);
    if (c > d) std::swap(c, d);
    if (a > c) std::swap(a, c);
    if (b > d) std::swap(b, d);
    if (b > c) std::swap(b, c);
    const auto word = [](Index x, Index y) {
        return static_cast<std::uint64_t>(static_cast<std::uint32_t>(x)) << 32 | static_cast<std::uint32_t>(y);
    };
    return mix64(mix64(word(a, b)) ^ word(c, d));
}

int cornerAt(int x, int y, int z) {
    for (int c = 0; c < 8; ++c)
        if (kRef[c][0] == x && kRef[c][1] == y && kRef[c][2] == z) return c;
    return -1;
}

}  // namespace

PillowResult pillow(HexMesh& mesh, const std::vector<Index>& shrinkSet, const PillowOptions& opt) {
    if (shrinkSet.empty()) throw Error("cannot pillow: the shrink set is empty");
    const std::size_t H = mesh.hexCount(), N = mesh.nodeCount();
    std::vector<std::uint8_t> inS(H, 0);
    for (Index h : shrinkSet) {
        if (h < 0 || static_cast<std::size_t>(h) >= H)
            throw Error("cannot pillow: shrink set names hex " + std::to_string(h) + " but the mesh has " +
                        std::to_string(H) + " hexes");
        inS[h] = 1;
    }
    std::vector<Index> S;  // the shrink set, sorted and without repeats
    S.reserve(shrinkSet.size());
    for (std::size_t h = 0; h < H; ++h)
        if (inS[h]) S.push_back(static_cast<Index>(h));

    // Nodes on the boundary of the shrink set, by parity: each face of a
    // shrink-set hex XORs a 64-bit hash of its four nodes into each of them. A
    // face two shrink-set hexes share cancels, so a node stays 0 unless a
    // boundary face meets it (or, with chance 2^-64 per node, its boundary
    // faces' hashes cancel: then the sheet misses faces, the manifold check
    // below fails and the exact pass over the whole shrink set is used).
    // Only the hexes that touch such nodes need the node -> hex adjacency.
    std::vector<std::uint64_t> parity(N, 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, S.size(), 4096), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const Hex& hx = mesh.hexes[S[i]];
            std::uint64_t fh[6];
            for (int f = 0; f < 6; ++f) {
                const auto& lf = hexcell::kFaces[f];
                fh[f] = quadHash(hx[lf[0]], hx[lf[1]], hx[lf[2]], hx[lf[3]]);
            }
            for (int c = 0; c < 8; ++c)
                std::atomic_ref<std::uint64_t>(parity[static_cast<std::size_t>(hx[c])])
                    .fetch_xor(fh[kCornerFaces[c][0]] ^ fh[kCornerFaces[c][1]] ^ fh[kCornerFaces[c][2]],
                               std::memory_order_relaxed);
        }
    });

    std::vector<std::pair<Index, int>> faces;
    std::vector<std::array<Index, 4>> quadNodes;
    std::vector<Index> T;  // positions in S of the hexes that hold a boundary node
    Csr nodeS;             // node -> hexes of T, as items 8 * (position in T) + corner
    auto hexOf = [&](Index item) { return S[static_cast<std::size_t>(T[static_cast<std::size_t>(item) / 8])]; };
    auto findBoundary = [&](bool exact) {
        std::vector<std::uint8_t> touches(S.size(), 0);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, S.size(), 4096), [&](const auto& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                bool t = exact;
                for (Index v : mesh.hexes[S[i]]) t = t || parity[static_cast<std::size_t>(v)] != 0;
                touches[i] = t;
            }
        });
        T.clear();
        for (std::size_t i = 0; i < S.size(); ++i)
            if (touches[i]) T.push_back(static_cast<Index>(i));
        nodeS = detail::bucketItems(N, 8 * T.size(), [&](std::size_t i) {
            return mesh.hexes[S[static_cast<std::size_t>(T[i / 8])]][i % 8];
        });

        // Faces of shrink-set hexes that no other shrink-set hex shares: the
        // boundary of the shrink set, seen from inside (outward normals), in
        // (hex, face) order for any thread count.
        std::vector<std::uint8_t> faceMask(T.size(), 0);
        std::atomic<Index> overfull{kNone};
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, T.size(), 1024), [&](const auto& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                const Index self = S[static_cast<std::size_t>(T[i])];
                const Hex& hx = mesh.hexes[self];
                std::uint8_t mask = 0;
                for (int f = 0; f < 6; ++f) {
                    const auto& lf = hexcell::kFaces[f];
                    if (!exact && (parity[hx[lf[0]]] == 0 || parity[hx[lf[1]]] == 0 || parity[hx[lf[2]]] == 0 ||
                                   parity[hx[lf[3]]] == 0))
                        continue;  // a node of the face is interior: the face is shared
                    // Another hex holding the face holds both ends of its diagonal
                    // lf[0]-lf[2]: walk the two (sorted) rows together, then check
                    // the other diagonal only for the hexes they share.
                    int sharers = 0;
                    const Index* a = nodeS.begin(hx[lf[0]]);
                    const Index* ae = nodeS.end(hx[lf[0]]);
                    const Index* b = nodeS.begin(hx[lf[2]]);
                    const Index* be = nodeS.end(hx[lf[2]]);
                    while (a != ae && b != be) {
                        const Index ha = hexOf(*a), hb = hexOf(*b);
                        if (ha < hb) {
                            ++a;
                        } else if (hb < ha) {
                            ++b;
                        } else {
                            if (ha != self) {
                                const Hex& ho = mesh.hexes[ha];
                                sharers += std::find(ho.begin(), ho.end(), hx[lf[1]]) != ho.end() &&
                                           std::find(ho.begin(), ho.end(), hx[lf[3]]) != ho.end();
                            }
                            ++a;
                            ++b;
                        }
                    }
                    if (sharers == 0) mask |= static_cast<std::uint8_t>(1u << f);
                    if (sharers > 1) {
                        Index expected = kNone;
                        overfull.compare_exchange_strong(expected, self);
                    }
                }
                faceMask[i] = mask;
            }
        });
        if (overfull.load() != kNone)
            throw Error("cannot pillow: a face of hex " + std::to_string(overfull.load()) +
                        " is shared by more than two hexes; repair the mesh first");
        faces.clear();
        quadNodes.clear();
        for (std::size_t i = 0; i < T.size(); ++i)
            for (int f = 0; f < 6; ++f)
                if (faceMask[i] >> f & 1) {
                    const Index h = S[static_cast<std::size_t>(T[i])];
                    const Hex& hx = mesh.hexes[h];
                    const auto& lf = hexcell::kFaces[f];
                    faces.emplace_back(h, f);
                    quadNodes.push_back({hx[lf[0]], hx[lf[1]], hx[lf[2]], hx[lf[3]]});
                }
    };
    findBoundary(opt.exactBoundary);
    ManifoldCheck mc = checkManifold(quadNodes, N, true);
    if (!mc.ok() && !opt.exactBoundary) {
        findBoundary(true);
        mc = checkManifold(quadNodes, N, true);
    }
    if (faces.empty()) throw Error("cannot pillow: the shrink set has no boundary");
    if (!mc.ok()) {
        std::string msg = "cannot pillow: the boundary of the shrink set is not a closed 2-manifold (" +
                          std::to_string(mc.badEdges.size()) + " non-manifold edges, " +
                          std::to_string(mc.badNodes.size()) + " nodes where parts touch";
        const Index v = mc.badNodes.empty() ? mc.badEdges[0][0] : mc.badNodes[0];
        msg += ", first at node " + std::to_string(v) + " " + at(mesh.nodes[v]) +
               "); repair the region's non-manifold edges and nodes first";
        throw Error(msg);
    }

    // Split nodes, numbered in increasing original index.
    PillowResult res;
    res.firstNewHex = static_cast<Index>(H);
    res.firstNewNode = static_cast<Index>(N);
    std::vector<Index> copy(N, kNone);
    for (const auto& q : quadNodes)
        for (Index v : q) copy[v] = 0;
    Index next = static_cast<Index>(N);
    for (std::size_t v = 0; v < N; ++v)
        if (copy[v] == 0) {
            copy[v] = next++;
            res.copyOf.push_back(static_cast<Index>(v));
        }
    const std::size_t C = res.copyOf.size();

    // Averaged outward normal (area weighted) and local edge length per split node.
    // (indexed by copy: only split nodes need them)
    std::vector<Vec3> normal(C, Vec3{0, 0, 0});
    std::vector<double> edgeSum(C, 0.0);
    std::vector<int> edgeCount(C, 0);
    for (const auto& q : quadNodes) {
        const Vec3 n = 0.5 * cross(mesh.nodes[q[2]] - mesh.nodes[q[0]], mesh.nodes[q[3]] - mesh.nodes[q[1]]);
        for (int i = 0; i < 4; ++i) {
            const std::size_t c = static_cast<std::size_t>(copy[q[i]] - static_cast<Index>(N));
            normal[c] = normal[c] + n;
            edgeSum[c] += norm(mesh.nodes[q[(i + 1) % 4]] - mesh.nodes[q[i]]) +
                          norm(mesh.nodes[q[(i + 3) % 4]] - mesh.nodes[q[i]]);
            edgeCount[c] += 2;
        }
    }
    // Each copy starts at its node plus `push`, an inward step of `inset`
    // local edge lengths that the loop below halves where it inverts a hex.
    // Inward is the averaged inward normal, or towards the centroid of the
    // shrink-set hexes around the node where the normal points away from them.
    std::vector<Vec3> push(C);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, C, 1024), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const Index v = res.copyOf[i];
            Vec3 c{0, 0, 0};
            int n = 0;
            for (const Index* it = nodeS.begin(v); it != nodeS.end(v); ++it) {
                for (Index u : mesh.hexes[hexOf(*it)]) c = c + mesh.nodes[u];
                n += 8;
            }
            const Vec3 toCentre = (1.0 / n) * c - mesh.nodes[v];
            const double len = norm(normal[i]);
            Vec3 dir = len > 0 ? (-1.0 / len) * normal[i] : Vec3{0, 0, 0};
            if (dot(dir, toCentre) <= 0) {
                const double l = norm(toCentre);
                dir = l > 0 ? (1.0 / l) * toCentre : Vec3{0, 0, 0};
            }
            push[i] = (opt.inset * edgeSum[i] / edgeCount[i]) * dir;
        }
    });

    // Apply: copies, shrink-set hexes take them, one new hex per boundary quad.
    mesh.nodes.reserve(N + C);
    mesh.nodeClass.reserve(N + C);
    for (std::size_t i = 0; i < C; ++i) mesh.addNode(mesh.nodes[res.copyOf[i]] + push[i], NodeClass{});
    // Only the hexes of T hold boundary nodes, so only they can hold a split node.
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, T.size(), 4096), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i)
            for (Index& v : mesh.hexes[S[static_cast<std::size_t>(T[i])]])
                if (v < static_cast<Index>(N) && copy[v] != kNone) v = copy[v];
    });
    mesh.hexes.reserve(H + faces.size());
    mesh.material.reserve(H + faces.size());
    for (std::size_t i = 0; i < faces.size(); ++i) {
        const auto& q = quadNodes[i];
        mesh.addHex({copy[q[0]], copy[q[1]], copy[q[2]], copy[q[3]], q[0], q[1], q[2], q[3]},
                    mesh.material[faces[i].first]);
    }

    // Shorten the inward step of copies where a hex around them inverted.
    std::vector<Index> watch;  // hexes that contain a copy (all among T)
    for (Index t : T)
        for (Index v : mesh.hexes[S[static_cast<std::size_t>(t)]])
            if (v >= static_cast<Index>(N)) {
                watch.push_back(S[static_cast<std::size_t>(t)]);
                break;
            }
    for (std::size_t h = H; h < mesh.hexCount(); ++h) watch.push_back(static_cast<Index>(h));
    // Each round, every inverted hex around a copy that moved asks how many
    // more halvings of its copies' steps (all together, up to maxHalvings) make
    // it valid; a copy takes the most any of its hexes asks for, and the hexes
    // around the copies that moved are checked again. A hex that no step length
    // can fix (a shrink-set hex inverted before the split, or a sheet hex on a
    // surface quad that folds against its copies' steps) asks for the shortest
    // step at once. This settles in a few rounds over the few hexes involved,
    // where halving once per round re-checked every hex maxHalvings times.
    const int maxK = std::max(0, opt.maxHalvings);
    std::vector<int> halvings(C, 0), want(C, 0);
    std::vector<std::uint8_t> bad(watch.size()), hopeless(watch.size(), 0), ask(watch.size(), 0);
    std::vector<std::uint8_t> moved(C, 1);  // round 0 checks every hex with a copy
    auto place = [&](std::size_t c, int k) {
        return mesh.nodes[res.copyOf[c]] + std::ldexp(1.0, -k) * push[c];
    };
    for (int round = 0; round <= maxK; ++round) {
        std::atomic<std::size_t> triggers{0};
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, watch.size(), 1024), [&](const auto& r) {
            std::size_t t = 0;
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                ask[i] = 0;
                const Hex& hx = mesh.hexes[watch[i]];
                bool changed = false;
                for (Index v : hx) changed = changed || (v >= static_cast<Index>(N) && moved[v - N]);
                if (!changed) continue;
                HexCoords x = hexCoords(mesh, watch[i]);
                bad[i] = !(minJacobianDeterminant(x) > 0);
                if (!bad[i]) continue;
                if (round == 0) {
                    // Shrink-set hex: its shape with the copies back on their
                    // nodes. Sheet hex: its shape with the copies a hair inside
                    // (each corner's sign there is that of the surface quad's
                    // corner normal against the copy's step, whatever the step's
                    // length, so halving cannot help if it is not positive).
                    const bool sheetHex = static_cast<std::size_t>(watch[i]) >= H;
                    HexCoords y = x;
                    for (int c = 0; c < 8; ++c)
                        if (hx[c] >= static_cast<Index>(N)) {
                            const std::size_t cc = static_cast<std::size_t>(hx[c] - N);
                            y[c] = mesh.nodes[res.copyOf[cc]];
                            if (sheetHex) y[c] = y[c] + 1e-3 * push[cc];
                        }
                    hopeless[i] = !(minJacobianDeterminant(y) > 0);
                }
                if (hopeless[i]) {  // no length helps: the shortest at once
                    ask[i] = static_cast<std::uint8_t>(maxK);
                    ++t;
                    continue;
                }
                int k = 1;
                for (; k < maxK; ++k) {
                    HexCoords y = x;
                    for (int c = 0; c < 8; ++c)
                        if (hx[c] >= static_cast<Index>(N)) {
                            const std::size_t cc = static_cast<std::size_t>(hx[c] - N);
                            y[c] = place(cc, std::min(maxK, halvings[cc] + k));
                        }
                    if (minJacobianDeterminant(y) > 0) break;
                }
                ask[i] = static_cast<std::uint8_t>(k);
                ++t;
            }
            triggers += t;
        });
        res.invertedAtStart = static_cast<std::size_t>(std::count(bad.begin(), bad.end(), 1));
        if (triggers == 0 || round == maxK) break;
        std::fill(want.begin(), want.end(), 0);
        for (std::size_t i = 0; i < watch.size(); ++i)
            if (ask[i])
                for (Index v : mesh.hexes[watch[i]])
                    if (v >= static_cast<Index>(N)) want[v - N] = std::max(want[v - N], static_cast<int>(ask[i]));
        bool any = false;
        for (std::size_t c = 0; c < C; ++c) {
            const int k = std::min(maxK, halvings[c] + want[c]);
            moved[c] = k != halvings[c];
            if (moved[c]) {
                any = true;
                halvings[c] = k;
                mesh.nodes[N + c] = place(c, k);
            }
        }
        if (!any) break;
    }
    return res;
}

std::vector<PillowResult> pillowAllMaterials(HexMesh& mesh, int layers, const PillowOptions& opt) {
    if (layers < 1) throw Error("boundary layers must be at least 1 (got " + std::to_string(layers) + ")");
    // The materials present, in increasing order (a few: no sort of the
    // whole per-hex array).
    std::vector<std::int32_t> mats;
    for (std::int32_t m : mesh.material)
        if (mats.empty() || m != mats.back())
            if (std::find(mats.begin(), mats.end(), m) == mats.end()) mats.push_back(m);
    std::sort(mats.begin(), mats.end());
    std::vector<PillowResult> out;
    for (std::int32_t m : mats) {
        std::vector<Index> shrink;
        shrink.reserve(mesh.hexCount());
        for (std::size_t h = 0; h < mesh.hexCount(); ++h)
            if (mesh.material[h] == m) shrink.push_back(static_cast<Index>(h));
        PillowResult r = pillow(mesh, shrink, opt);
        if (layers > 1) {
            const Topology topo = buildTopology(mesh);
            const DualSheets sheets = buildSheets(mesh, topo);
            const Index s = sheetThroughEdge(mesh, topo, sheets, r.firstNewNode, r.copyOf[0]);
            dice(mesh, topo, sheets, s, layers - 1);
        }
        out.push_back(std::move(r));
    }
    return out;
}

// ----------------------------------------------------------------- dicing

std::size_t dice(HexMesh& mesh, const Topology& topo, const DualSheets& sheets, Index sheet, int copies) {
    if (copies < 1) throw Error("dice: the number of copies must be at least 1 (got " + std::to_string(copies) + ")");
    if (sheet < 0 || static_cast<std::size_t>(sheet) >= sheets.count())
        throw Error("dice: no sheet " + std::to_string(sheet));
    const int k = copies;
    // Hexes of the sheet and the direction the sheet crosses them in.
    std::vector<std::pair<Index, int>> hexDir;
    for (const Index* h = sheets.sheetHexes.begin(sheet); h != sheets.sheetHexes.end(sheet); ++h) {
        int dir = -1;
        for (int d = 0; d < 3; ++d)
            if (sheets.hexSheets[*h][d] == sheet) {
                if (dir >= 0)
                    throw Error("dice: sheet " + std::to_string(sheet) + " crosses itself in hex " +
                                std::to_string(*h) + "; dicing a self-intersecting sheet is not supported");
                dir = d;
            }
        hexDir.emplace_back(*h, dir);
    }
    // Which edges lie in a surface (for the class of the new nodes).
    std::vector<std::uint8_t> edgeOnSurface(topo.edges.size(), 0);
    auto markQuadEdges = [&](Index q) {
        const Quad& quad = topo.quads[q];
        const int f = quad.localFace[0];
        const Index h = quad.hex[0];
        for (int e = 0; e < 12; ++e) {
            const auto& le = hexcell::kEdges[e];
            const auto& lf = hexcell::kFaces[f];
            const bool in0 = std::find(lf.begin(), lf.end(), le[0]) != lf.end();
            const bool in1 = std::find(lf.begin(), lf.end(), le[1]) != lf.end();
            if (in0 && in1) edgeOnSurface[topo.hexEdges[h][e]] = 1;
        }
    };
    for (Index q : topo.boundaryQuads) markQuadEdges(q);
    for (Index q : topo.interfaceQuads) markQuadEdges(q);

    // k new nodes per sheet edge, from its first (smaller) node to its second.
    const std::size_t N = mesh.nodeCount();
    std::vector<Index> base(topo.edges.size(), kNone);
    Index next = static_cast<Index>(N);
    for (const Index* e = sheets.sheetEdges.begin(sheet); e != sheets.sheetEdges.end(sheet); ++e) {
        base[*e] = next;
        next += k;
    }
    mesh.nodes.resize(static_cast<std::size_t>(next));
    mesh.nodeClass.resize(static_cast<std::size_t>(next));
    const std::size_t E = sheets.sheetEdges.size(sheet);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, E, 256), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const Index e = sheets.sheetEdges.begin(sheet)[i];
            const auto [a, b] = topo.edges[e];
            const NodeClass ca = mesh.nodeClass[a], cb = mesh.nodeClass[b];
            NodeClass c{};
            if (edgeOnSurface[e]) {
                if (ca == cb && ca.kind != NodeKind::Fixed) c = ca;
                else if (ca.kind == NodeKind::Surface) c = ca;
                else if (cb.kind == NodeKind::Surface) c = cb;
            }
            for (int j = 1; j <= k; ++j) {
                const double t = static_cast<double>(j) / (k + 1);
                mesh.nodes[base[e] + j - 1] = mesh.nodes[a] + t * (mesh.nodes[b] - mesh.nodes[a]);
                mesh.nodeClass[base[e] + j - 1] = c;
            }
        }
    });

    // Split each sheet hex into k+1 along its direction.
    const std::size_t H = mesh.hexCount();
    mesh.hexes.resize(H + hexDir.size() * k);
    mesh.material.resize(H + hexDir.size() * k);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, hexDir.size(), 256), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const auto [h, d] = hexDir[i];
            const Hex old = mesh.hexes[h];
            // point t (0..k+1) along the sheet edge that starts at corner c
            auto pointFrom = [&](int c, int t) -> Index {
                int ref[3] = {kRef[c][0], kRef[c][1], kRef[c][2]};
                ref[d] = 1;
                const int other = cornerAt(ref[0], ref[1], ref[2]);
                if (t == 0) return old[c];
                if (t == k + 1) return old[other];
                int le = -1;
                for (int e = 4 * d; e < 4 * d + 4; ++e) {
                    const auto& p = hexcell::kEdges[e];
                    if ((p[0] == c && p[1] == other) || (p[1] == c && p[0] == other)) le = e;
                }
                const Index e = topo.hexEdges[h][le];
                return topo.edges[e][0] == old[c] ? base[e] + t - 1 : base[e] + (k + 1 - t) - 1;
            };
            for (int j = 0; j <= k; ++j) {
                Hex sub;
                for (int c = 0; c < 8; ++c) {
                    int ref[3] = {kRef[c][0], kRef[c][1], kRef[c][2]};
                    const int up = ref[d];
                    ref[d] = 0;
                    sub[c] = pointFrom(cornerAt(ref[0], ref[1], ref[2]), j + up);
                }
                const std::size_t slot = j == 0 ? static_cast<std::size_t>(h) : H + i * k + (j - 1);
                mesh.hexes[slot] = sub;
                mesh.material[slot] = mesh.material[h];
            }
        }
    });
    return hexDir.size() * k;
}

// ----------------------------------------------------------------- extraction

namespace {
std::set<std::string> topologicalDefects(const ValidityReport& r) {
    std::set<std::string> out;
    for (const auto& [key, d] : r.defects)
        if (key != "inverted_hex") out.insert(key);
    return out;
}
}  // namespace

std::size_t extract(HexMesh& mesh, const Topology& topo, const DualSheets& sheets, Index sheet) {
    if (sheet < 0 || static_cast<std::size_t>(sheet) >= sheets.count())
        throw Error("extract: no sheet " + std::to_string(sheet));
    const std::size_t N = mesh.nodeCount();
    std::vector<std::uint8_t> edgeOnSurface(topo.edges.size(), 0);
    for (const auto* list : {&topo.boundaryQuads, &topo.interfaceQuads})
        for (Index q : *list) {
            const Quad& quad = topo.quads[q];
            for (int e = 0; e < 12; ++e) {
                const auto& le = hexcell::kEdges[e];
                const auto& lf = hexcell::kFaces[quad.localFace[0]];
                if (std::find(lf.begin(), lf.end(), le[0]) != lf.end() &&
                    std::find(lf.begin(), lf.end(), le[1]) != lf.end())
                    edgeOnSurface[topo.hexEdges[quad.hex[0]][e]] = 1;
            }
        }
    // Decide the fate of each collapsed edge.
    std::vector<Index> target(N);
    std::iota(target.begin(), target.end(), 0);
    std::vector<std::uint8_t> used(N, 0);
    std::vector<Vec3> newPos;
    std::vector<NodeClass> newClass;
    for (const Index* pe = sheets.sheetEdges.begin(sheet); pe != sheets.sheetEdges.end(sheet); ++pe) {
        const auto [a, b] = topo.edges[*pe];
        const NodeClass ca = mesh.nodeClass[a], cb = mesh.nodeClass[b];
        const bool fa = ca.kind != NodeKind::Interior, fb = cb.kind != NodeKind::Interior;
        auto refuse = [&](const std::string& why) {
            throw Error("cannot extract sheet " + std::to_string(sheet) + ": its edge from node " +
                        std::to_string(a) + " " + at(mesh.nodes[a]) + " to node " + std::to_string(b) + " " + why);
        };
        if (used[a] || used[b]) refuse("shares a node with another of its edges (the sheet touches itself)");
        used[a] = used[b] = 1;
        Index keep = a, gone = b;
        Vec3 pos = mesh.nodes[a];
        NodeClass cls = ca;
        if (fa && fb) {
            if (!(ca == cb)) refuse("joins two different surfaces or curves; collapsing it would merge them");
            if (ca.kind != NodeKind::Surface || !edgeOnSurface[*pe])
                refuse("runs through the solid between two nodes of one surface; collapsing it would pinch the surface");
            pos = 0.5 * (mesh.nodes[a] + mesh.nodes[b]);
        } else if (fb) {
            keep = b;
            gone = a;
            pos = mesh.nodes[b];
            cls = cb;
        } else if (!fa) {
            pos = 0.5 * (mesh.nodes[a] + mesh.nodes[b]);
        }
        target[gone] = keep;
        target[keep] = keep;
        newPos.push_back(pos);
        newClass.push_back(cls);
    }

    HexMesh out;
    // Hexes of the sheet disappear; the others are remapped.
    std::vector<std::uint8_t> inSheet(mesh.hexCount(), 0);
    for (const Index* h = sheets.sheetHexes.begin(sheet); h != sheets.sheetHexes.end(sheet); ++h) inSheet[*h] = 1;
    std::set<std::int32_t> before(mesh.material.begin(), mesh.material.end()), after;
    std::vector<Index> newId(N, kNone);
    Index nextNode = 0;
    for (std::size_t v = 0; v < N; ++v)
        if (target[v] == static_cast<Index>(v)) newId[v] = nextNode++;
    out.nodes.resize(nextNode);
    out.nodeClass.resize(nextNode);
    for (std::size_t v = 0; v < N; ++v)
        if (newId[v] != kNone) {
            out.nodes[newId[v]] = mesh.nodes[v];
            out.nodeClass[newId[v]] = mesh.nodeClass[v];
        }
    {
        std::size_t i = 0;
        for (const Index* pe = sheets.sheetEdges.begin(sheet); pe != sheets.sheetEdges.end(sheet); ++pe, ++i) {
            const auto [a, b] = topo.edges[*pe];
            const Index keep = target[a] == a ? a : b;
            out.nodes[newId[keep]] = newPos[i];
            out.nodeClass[newId[keep]] = newClass[i];
        }
    }
    for (std::size_t h = 0; h < mesh.hexCount(); ++h) {
        if (inSheet[h]) continue;
        Hex nh;
        for (int c = 0; c < 8; ++c) nh[c] = newId[target[mesh.hexes[h][c]]];
        out.addHex(nh, mesh.material[h]);
        after.insert(mesh.material[h]);
    }
    for (std::int32_t m : before)
        if (!after.count(m))
            throw Error("cannot extract sheet " + std::to_string(sheet) + ": it holds every hex of material " +
                        std::to_string(m));
    // Nodes used only by the removed hexes (none for a proper sheet) are dropped.
    out.surfaces = mesh.surfaces;
    const auto was = topologicalDefects(validate(mesh));
    const ValidityReport rep = validate(out);
    for (const auto& key : topologicalDefects(rep))
        if (!was.count(key))
            throw Error("cannot extract sheet " + std::to_string(sheet) + ": the result would have " +
                        std::to_string(rep.count(key)) + " defect(s) of kind " + key);
    const std::size_t removed = mesh.hexCount() - out.hexCount();
    mesh = std::move(out);
    return removed;
}

// ----------------------------------------------------------------- selection

Index sheetThroughEdge(const HexMesh& mesh, const Topology& topo, const DualSheets& sheets, Index a, Index b) {
    const Index e = edgeBetween(mesh, topo, a, b);
    if (e == kNone) throw Error("no mesh edge joins nodes " + std::to_string(a) + " and " + std::to_string(b));
    return sheets.edgeSheet[static_cast<std::size_t>(e)];
}

std::vector<Index> sheetsTouchingSurfaces(const Topology& topo, const DualSheets& sheets) {
    std::vector<std::uint8_t> touch(sheets.count(), 0);
    for (std::size_t e = 0; e < topo.edges.size(); ++e)
        if (topo.nodeOnBoundary[topo.edges[e][0]] || topo.nodeOnBoundary[topo.edges[e][1]]) touch[sheets.edgeSheet[e]] = 1;
    std::vector<Index> out;
    for (std::size_t s = 0; s < touch.size(); ++s)
        if (touch[s]) out.push_back(static_cast<Index>(s));
    return out;
}

std::vector<Index> fundamentalSheets(const HexMesh& mesh, const Topology& topo, const DualSheets& sheets) {
    std::vector<std::uint8_t> onSurface(mesh.nodeCount(), 0);
    for (Index v : topo.boundaryNodes) onSurface[v] = 1;
    for (Index q : topo.interfaceQuads)
        for (Index v : topo.quads[q].nodes) onSurface[v] = 1;
    std::vector<Index> out;
    for (std::size_t s = 0; s < sheets.count(); ++s) {
        bool ok = true;
        for (const Index* e = sheets.sheetEdges.begin(s); ok && e != sheets.sheetEdges.end(s); ++e)
            ok = onSurface[topo.edges[*e][0]] != onSurface[topo.edges[*e][1]];
        if (ok) out.push_back(static_cast<Index>(s));
    }
    return out;
}

std::vector<Index> randomSheets(const DualSheets& sheets, std::size_t count, std::uint64_t seed,
                                const std::vector<Index>& exclude) {
    std::vector<std::uint8_t> skip(sheets.count(), 0);
    for (Index s : exclude)
        if (s >= 0 && static_cast<std::size_t>(s) < skip.size()) skip[s] = 1;
    std::vector<Index> pool;
    for (std::size_t s = 0; s < sheets.count(); ++s)
        if (!skip[s]) pool.push_back(static_cast<Index>(s));
    std::mt19937_64 rng(seed);
    // Fisher-Yates with our own index draw, so the sequence is the same on every platform.
    for (std::size_t i = 0; i < pool.size() && i < count; ++i) {
        const std::size_t j = i + static_cast<std::size_t>(rng() % (pool.size() - i));
        std::swap(pool[i], pool[j]);
    }
    pool.resize(std::min(count, pool.size()));
    return pool;
}

}  // namespace isohex
