#include "isohex/core/Pillow.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <functional>
#include <numeric>
#include <span>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_reduce.h>
#include <tbb/parallel_for.h>

#include "isohex/core/Dice.hpp"
#include "isohex/core/Dual.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/HexCell.hpp"
#include "isohex/core/HugePages.hpp"
#include "isohex/core/NodeTargets.hpp"
#include "isohex/core/Parallel.hpp"
#include "isohex/core/QuadSurface.hpp"
#include "isohex/core/SheetSelection.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/core/VecMath.hpp"

// Pillow works on the few nodes and hexes near the shrink set's boundary:
//   1. the shrink set, sorted (sortedShrinkSet);
//   2. candidate nodes: those a face-parity hash puts on the boundary, or every
//      node in the exact pass (nodesWithParity, everyNode);
//   3. the shrink-set hexes holding a candidate, and their faces no other
//      shrink-set hex shares: the boundary quads (hexesHoldingCandidates,
//      boundaryFaceMasks, boundaryQuads), checked to be a closed 2-manifold;
//   4. one copy per boundary node, started a step inside (inwardSteps), the
//      shrink-set hexes moved onto the copies and one hex per boundary quad
//      (splitNodes);
//   5. steps halved where a hex around a copy inverted (StepSettler).
// Every parallel loop writes by position or combines in a fixed order, so the
// result is the same for any thread count.

namespace isohex {

namespace {

using namespace vec;
using parallel::keepWhere;
using parallel::rowsInOrder;

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

inline void prefetch(const void* p) {
#if defined(__GNUC__)
    __builtin_prefetch(p);
#else
    (void)p;
#endif
}

// minJacobianDeterminant(x) > 0 for the hex with corners *x[0..7]: the same
// arithmetic in the same order (so the same verdict, bit for bit), without
// building the nine frames, and stopping at the first one not positive (a
// NaN corner determinant is passed over, as std::min does there).
bool jacobianPositive(const Vec3* const x[8]) {
    Vec3 a, b, c;
    for (int k = 0; k < 3; ++k) {
        a[k] = ((*x[1])[k] + (*x[2])[k] + (*x[5])[k] + (*x[6])[k]) - ((*x[0])[k] + (*x[3])[k] + (*x[4])[k] + (*x[7])[k]);
        b[k] = ((*x[2])[k] + (*x[3])[k] + (*x[6])[k] + (*x[7])[k]) - ((*x[0])[k] + (*x[1])[k] + (*x[4])[k] + (*x[5])[k]);
        c[k] = ((*x[4])[k] + (*x[5])[k] + (*x[6])[k] + (*x[7])[k]) - ((*x[0])[k] + (*x[1])[k] + (*x[2])[k] + (*x[3])[k]);
    }
    if (!(dot(a, cross(b, c)) / 64.0 > 0)) return false;
    for (int k = 0; k < 8; ++k) {
        const auto& n = hexcell::kCornerNeighbours[k];
        if (dot(*x[n[0]] - *x[k], cross(*x[n[1]] - *x[k], *x[n[2]] - *x[k])) <= 0) return false;
    }
    return true;
}

// ------------------------------------------------------------ the boundary

// The shrink set sorted and without repeats: the caller's own when it already
// is, else `storage`. Throws on a hex index out of range.
std::span<const Index> sortedShrinkSet(const std::vector<Index>& shrinkSet, std::size_t H, BigVec<Index>& storage) {
    bool increasing = true;
    for (std::size_t i = 0; i < shrinkSet.size(); ++i) {
        const Index h = shrinkSet[i];
        if (h < 0 || static_cast<std::size_t>(h) >= H)
            throw Error("cannot pillow: shrink set names hex " + std::to_string(h) + " but the mesh has " +
                        std::to_string(H) + " hexes");
        increasing = increasing && (i == 0 || shrinkSet[i - 1] < h);
    }
    if (increasing) return std::span<const Index>(shrinkSet);
    BigVec<std::uint8_t> inS(H, 0);
    for (Index h : shrinkSet) inS[h] = 1;
    storage = keepWhere(H, [&](std::size_t h) { return inS[h] != 0; });
    return std::span<const Index>(storage);
}

// Per thread, a 32-bit parity per node.
using Parities = tbb::enumerable_thread_specific<BigVec<std::uint32_t>>;

// Nodes on the boundary of the shrink set, by parity: each face of a
// shrink-set hex XORs a 32-bit hash of its four nodes (the sum of one hash per
// node, so the same in any order) into each of them. A face two shrink-set
// hexes share cancels, so a node stays 0 unless a boundary face meets it (or,
// with chance 2^-32 per node, its boundary faces' hashes cancel: then the
// sheet misses faces, the manifold check fails and the exact pass over the
// whole shrink set is used). Each thread XORs into its own array (XOR
// commutes: the same result for any thread count, without an atomic per
// corner). 32 bits rather than 64 halve the arrays these scattered writes land
// in; a miss only costs the exact pass.
void addFaceParities(const HexMesh& mesh, std::span<const Index> S, Parities& parities) {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, S.size(), 4096), [&](const auto& r) {
        std::uint32_t* parity = parities.local().data();
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const Hex& hx = mesh.hexes[S[i]];
            std::uint32_t nodeHash[8], fh[6];
            for (int c = 0; c < 8; ++c)
                nodeHash[c] = static_cast<std::uint32_t>(
                    mix64(static_cast<std::uint64_t>(static_cast<std::uint32_t>(hx[c])) + 0x9E3779B97F4A7C15ull) >> 32);
            for (int f = 0; f < 6; ++f) {
                const auto& lf = hexcell::kFaces[f];
                fh[f] = nodeHash[lf[0]] + nodeHash[lf[1]] + nodeHash[lf[2]] + nodeHash[lf[3]];
            }
            for (int c = 0; c < 8; ++c)
                parity[hx[c]] ^= fh[kCornerFaces[c][0]] ^ fh[kCornerFaces[c][1]] ^ fh[kCornerFaces[c][2]];
        }
    });
}

constexpr std::uint32_t kNoSlot = ~std::uint32_t{0};

// The candidate nodes for the boundary, numbered in increasing node order
// ("slots"). Per node its slot or kNoSlot (in the parity pass the storage of
// the first parity array, so no further N-sized array is written), and one
// bit per node for "is a candidate" (small enough to stay in cache while
// every hex of S is tested against it).
struct Candidates {
    BigVec<std::uint32_t> slot;
    BigVec<std::uint64_t> isCand;
    BigVec<Index> node;  // per slot, its node
    Index slotOf(Index v) const { return static_cast<Index>(slot[static_cast<std::size_t>(v)]); }  // kNoSlot: kNone
    bool candidate(Index v) const { return (isCand[static_cast<std::size_t>(v) >> 6] >> (v & 63) & 1) != 0; }
    std::size_t count() const { return node.size(); }
};

// Every node a candidate, slot = node: the exact pass.
Candidates everyNode(std::size_t N) {
    Candidates c;
    c.slot.assign(N, 0);
    std::iota(c.slot.begin(), c.slot.end(), 0);
    c.node.resize(N);
    std::iota(c.node.begin(), c.node.end(), 0);
    c.isCand.assign((N + 63) / 64, ~std::uint64_t{0});
    return c;
}

// The nodes whose parity is not 0: XORs the threads' arrays into the first,
// then numbers those nodes in increasing order, in fixed blocks.
Candidates nodesWithParity(Parities& parities, std::size_t N) {
    Candidates c;
    std::vector<BigVec<std::uint32_t>*> locals;
    for (auto& local : parities) locals.push_back(&local);
    c.slot = std::move(*locals[0]);
    auto& slot = c.slot;
    constexpr std::size_t B = std::size_t{1} << 14;
    const std::size_t blocks = (N + B - 1) / B;
    std::vector<Index> count(blocks + 1, 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks, 1), [&](const auto& r) {
        for (std::size_t b = r.begin(); b != r.end(); ++b) {
            Index k = 0;
            for (std::size_t v = b * B, e = std::min(N, v + B); v < e; ++v) {
                std::uint32_t p = slot[v];
                for (std::size_t l = 1; l < locals.size(); ++l) p ^= (*locals[l])[v];
                slot[v] = p;
                k += p != 0;
            }
            count[b + 1] = k;
        }
    });
    for (std::size_t b = 0; b < blocks; ++b) count[b + 1] += count[b];
    c.node.resize(static_cast<std::size_t>(count[blocks]));
    c.isCand.assign((N + 63) / 64, 0);  // B is a multiple of 64: each block owns whole words
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks, 1), [&](const auto& r) {
        for (std::size_t b = r.begin(); b != r.end(); ++b) {
            Index k = count[b];
            for (std::size_t v = b * B, e = std::min(N, v + B); v < e; ++v)
                if (slot[v] != 0) {
                    c.node[static_cast<std::size_t>(k)] = static_cast<Index>(v);
                    slot[v] = static_cast<std::uint32_t>(k++);
                    c.isCand[v >> 6] |= std::uint64_t{1} << (v & 63);
                } else {
                    slot[v] = kNoSlot;
                }
        }
    });
    parities.clear();
    return c;
}

// T: the positions in S of the hexes that hold a candidate node, with those
// hexes and their corners' slots copied out in order (the passes below read
// them in sequence instead of scattered over the mesh), and per slot the
// positions in T of the hexes holding it. Only these hexes need the node ->
// hex adjacency.
struct CandidateHexes {
    BigVec<Index> T;
    BigVec<Hex> hex;
    BigVec<std::array<Index, 8>> slot;
    BigCsr nodeT;  // slot -> positions in T, increasing
    std::size_t size() const { return T.size(); }
};

// Finds T in one pass over S, copying each kept hex out as it is written.
// Releases the candidates' bitset, which is not needed after.
CandidateHexes hexesHoldingCandidates(const HexMesh& mesh, std::span<const Index> S, Candidates& cand) {
    CandidateHexes t;
    t.T = keepWhere(
        S.size(),
        [&](std::size_t i) {
            for (Index v : mesh.hexes[S[i]])
                if (cand.candidate(v)) return true;
            return false;
        },
        [&](std::size_t kept) {
            t.hex.resize(kept);
            t.slot.resize(kept);
        },
        [&](std::size_t i, Index k) {
            const Hex& hx = mesh.hexes[S[i]];
            t.hex[static_cast<std::size_t>(k)] = hx;
            for (int c = 0; c < 8; ++c) t.slot[static_cast<std::size_t>(k)][c] = cand.slotOf(hx[c]);
        });
    release(cand.isCand);
    t.nodeT = rowsInOrder(cand.count(), t.T.size(), [&](std::size_t lo, std::size_t hi, auto emit) {
        for (std::size_t k = lo; k < hi; ++k)
            for (Index s : t.slot[k])
                if (s != kNone) emit(s, static_cast<Index>(k));
    });
    return t;
}

// Per hex of T, a bit per face that no other shrink-set hex shares: the
// boundary of the shrink set, seen from inside (outward normals). Throws if a
// face is shared by more than two hexes.
BigVec<std::uint8_t> boundaryFaceMasks(std::span<const Index> S, const CandidateHexes& t) {
    BigVec<std::uint8_t> faceMask(t.size(), 0);
    std::atomic<Index> overfull{kNone};
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, t.size(), 1024), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const Index self = S[static_cast<std::size_t>(t.T[i])];
            const Hex& hx = t.hex[i];
            const auto& sl = t.slot[i];
            std::uint8_t mask = 0;
            for (int f = 0; f < 6; ++f) {
                const auto& lf = hexcell::kFaces[f];
                if (sl[lf[0]] == kNone || sl[lf[1]] == kNone || sl[lf[2]] == kNone || sl[lf[3]] == kNone)
                    continue;  // a node of the face is interior: the face is shared
                // Another hex holding the face holds both ends of its diagonal
                // lf[0]-lf[2]: walk the two (sorted) rows together, then check
                // the other diagonal only for the hexes they share.
                int sharers = 0;
                const Index* a = t.nodeT.begin(sl[lf[0]]);
                const Index* ae = t.nodeT.end(sl[lf[0]]);
                const Index* b = t.nodeT.begin(sl[lf[2]]);
                const Index* be = t.nodeT.end(sl[lf[2]]);
                while (a != ae && b != be) {
                    if (*a < *b) {
                        ++a;
                    } else if (*b < *a) {
                        ++b;
                    } else {
                        if (*a != static_cast<Index>(i)) {
                            const Hex& ho = t.hex[static_cast<std::size_t>(*a)];
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
    return faceMask;
}

// The boundary quads in (hex, face) order for any thread count: the face,
// its nodes and their slots, and per slot its quad corners.
struct BoundaryQuads {
    BigVec<std::pair<Index, int>> faces;  // (shrink-set hex, local face)
    BigVec<std::array<Index, 4>> nodes;
    BigVec<std::array<Index, 4>> slots;
    BigCsr around;  // slot -> 4 * quad + corner, increasing
    std::size_t size() const { return faces.size(); }
};

BoundaryQuads boundaryQuads(std::span<const Index> S, const CandidateHexes& t, const BigVec<std::uint8_t>& faceMask,
                            std::size_t candidates) {
    BigVec<Index> first(t.size() + 1, 0);  // first face of each hex of T
    for (std::size_t i = 0; i < t.size(); ++i) first[i + 1] = first[i] + std::popcount(faceMask[i]);
    const std::size_t Q = static_cast<std::size_t>(first[t.size()]);
    BoundaryQuads b;
    b.faces.resize(Q);
    b.nodes.resize(Q);
    b.slots.resize(Q);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, t.size(), 4096), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            std::size_t q = static_cast<std::size_t>(first[i]);
            const Index h = S[static_cast<std::size_t>(t.T[i])];
            const Hex& hx = t.hex[i];
            const auto& sl = t.slot[i];
            for (int f = 0; f < 6; ++f)
                if (faceMask[i] >> f & 1) {
                    const auto& lf = hexcell::kFaces[f];
                    b.faces[q] = {h, f};
                    b.nodes[q] = {hx[lf[0]], hx[lf[1]], hx[lf[2]], hx[lf[3]]};
                    b.slots[q] = {sl[lf[0]], sl[lf[1]], sl[lf[2]], sl[lf[3]]};
                    ++q;
                }
        }
    });
    b.around = rowsInOrder(candidates, Q, [&](std::size_t lo, std::size_t hi, auto emit) {
        for (std::size_t q = lo; q < hi; ++q)
            for (int c = 0; c < 4; ++c) emit(b.slots[q][c], static_cast<Index>(4 * q + c));
    });
    return b;
}

// The shrink set's boundary: its candidate nodes, the hexes holding them and
// its quads.
struct Boundary {
    Candidates cand;
    CandidateHexes hexes;
    BoundaryQuads quads;
};

Boundary findBoundary(const HexMesh& mesh, std::span<const Index> S, Parities& parities, bool exact) {
    Boundary b;
    b.cand = exact ? everyNode(mesh.nodeCount()) : nodesWithParity(parities, mesh.nodeCount());
    b.hexes = hexesHoldingCandidates(mesh, S, b.cand);
    const BigVec<std::uint8_t> faceMask = boundaryFaceMasks(S, b.hexes);
    b.quads = boundaryQuads(S, b.hexes, faceMask, b.cand.count());
    return b;
}

// Whether the boundary quads form a closed 2-manifold (bad edges and nodes as
// node ids). Every boundary node by parity lies on a boundary face unless a
// node of that face was missed: reported as a bad node, so that the exact
// pass is used then.
ManifoldCheck checkBoundary(const Boundary& b, bool exact) {
    const BigCsr& around = b.quads.around;
    ManifoldCheck mc =
        checkManifold(b.quads.slots.data(), around.offsets.data(), around.items.data(), around.rows(), true);
    for (auto& e : mc.badEdges) e = {b.cand.node[e[0]], b.cand.node[e[1]]};
    for (auto& v : mc.badNodes) v = b.cand.node[v];
    if (!exact && mc.ok())
        for (std::size_t s = 0; s < around.rows(); ++s)
            if (around.size(s) == 0) {
                mc.badNodes.push_back(b.cand.node[s]);
                break;
            }
    return mc;
}

// The boundary by parity, or by the exact pass where asked or where the
// parity result is not a closed manifold. Throws if the shrink set has no
// boundary or it is not a closed 2-manifold.
Boundary findManifoldBoundary(const HexMesh& mesh, std::span<const Index> S, bool exactFirst) {
    const std::size_t N = mesh.nodeCount();
    Parities parities([N] { return BigVec<std::uint32_t>(N, 0); });
    if (!exactFirst) addFaceParities(mesh, S, parities);
    Boundary b = findBoundary(mesh, S, parities, exactFirst);
    ManifoldCheck mc = checkBoundary(b, exactFirst);
    if (!mc.ok() && !exactFirst) {
        b = Boundary{};
        b = findBoundary(mesh, S, parities, true);
        mc = checkBoundary(b, true);
    }
    if (b.quads.size() == 0) throw Error("cannot pillow: the shrink set has no boundary");
    if (!mc.ok()) {
        std::string msg = "cannot pillow: the boundary of the shrink set is not a closed 2-manifold (" +
                          std::to_string(mc.badEdges.size()) + " non-manifold edges, " +
                          std::to_string(mc.badNodes.size()) + " nodes where parts touch";
        const Index v = mc.badNodes.empty() ? mc.badEdges[0][0] : mc.badNodes[0];
        msg += ", first at node " + std::to_string(v) + " " + at(mesh.nodes[v]) +
               "); repair the region's non-manifold edges and nodes first";
        throw Error(msg);
    }
    return b;
}

// ------------------------------------------------------------ the new nodes

// The split nodes: the slots on a boundary quad, numbered in increasing
// original index. copySlot[c] is copy c's slot; slotCopy (only filled when
// some slot has no copy) the way back.
struct Copies {
    BigVec<Index> copySlot;
    BigVec<Index> slotCopy;
    Index ofSlot(Index s) const { return slotCopy.empty() ? s : slotCopy[static_cast<std::size_t>(s)]; }
    std::size_t count() const { return copySlot.size(); }
};

Copies numberCopies(const Boundary& b, std::vector<Index>& copyOf) {
    Copies c;
    const std::size_t nCand = b.cand.count();
    c.copySlot = keepWhere(nCand, [&](std::size_t s) { return b.quads.around.size(s) != 0; });
    const std::size_t C = c.copySlot.size();
    if (C != nCand) {
        c.slotCopy.assign(nCand, kNone);
        for (std::size_t i = 0; i < C; ++i) c.slotCopy[c.copySlot[i]] = static_cast<Index>(i);
    }
    copyOf.resize(C);
    for (std::size_t i = 0; i < C; ++i) copyOf[i] = b.cand.node[c.copySlot[i]];
    return c;
}

// Per boundary quad, its area vector and edge lengths (edge j from corner j
// to j + 1; the same numbers as from either end, as -0 and 0 square alike).
struct QuadGeometry {
    Vec3 area;
    double edge[4];
};

BigVec<QuadGeometry> quadGeometries(const std::vector<Vec3>& P, const BoundaryQuads& quads) {
    const std::size_t Q = quads.size();
    BigVec<QuadGeometry> quadGeometry(Q);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, Q, 4096), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const auto& q = quads.nodes[i];
            quadGeometry[i].area = 0.5 * cross(P[q[2]] - P[q[0]], P[q[3]] - P[q[1]]);
            for (int k = 0; k < 4; ++k) quadGeometry[i].edge[k] = norm(P[q[(k + 1) % 4]] - P[q[k]]);
        }
    });
    return quadGeometry;
}

// Per hex of T, the sum of its corners, and in `bound` the largest absolute
// coordinate involved: enough to settle the centroid sign test of
// inwardStep without the exact centroid for all but a few nodes.
BigVec<Vec3> cornerSums(const std::vector<Vec3>& P, const CandidateHexes& t, double& bound) {
    BigVec<Vec3> cornerSum(t.size());
    tbb::enumerable_thread_specific<double> maxCoordinate(0.0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, t.size(), 4096), [&](const auto& r) {
        double& m = maxCoordinate.local();
        for (std::size_t k = r.begin(); k != r.end(); ++k) {
            Vec3 c{0, 0, 0};
            for (Index u : t.hex[k]) {
                c = c + P[u];
                m = std::max({m, std::abs(P[u][0]), std::abs(P[u][1]), std::abs(P[u][2])});
            }
            cornerSum[k] = c;
        }
    });
    bound = maxCoordinate.combine([](double a, double b) { return std::max(a, b); });
    return cornerSum;
}

// Where the averaged outward normal `n` (unit) makes an angle of more than
// acos(kCornerCone) with the corner normal of one of node v's boundary quads
// at v, the sheet hex on that quad starts inverted at v whatever the step's
// length (its corner Jacobian there is -step . corner normal times a positive
// factor). Then the direction is the one farthest from every corner normal's
// half-space boundary: the minimum-norm point of the convex hull of the unit
// corner normals (max over unit d of min_i d . u_i is its length, and it
// points along it; Gilbert's algorithm over at most a few dozen normals),
// taken as soon as it clears kCornerCone with every corner normal. Returns
// the outward direction and sets `clears` when it makes a positive angle
// with every corner normal; where none does (the hull holds 0: the surface
// folds at v) `n` stays.
constexpr double kCornerCone = 0.2;
constexpr int kMaxCorners = 24;

Vec3 clearCornerNormals(const std::vector<Vec3>& P, const BoundaryQuads& quads, const BigCsr& around, Index s, Index v,
                        const Vec3& n, bool& clears) {
    Vec3 u[kMaxCorners];
    int m = 0;
    double worst = 1;
    for (const Index* it = around.begin(s); it != around.end(s) && m < kMaxCorners; ++it) {
        const auto& q = quads.nodes[static_cast<std::size_t>(*it / 4)];
        const int k = *it % 4;
        const Vec3 c = cross(P[q[(k + 1) % 4]] - P[v], P[q[(k + 3) % 4]] - P[v]);
        const double l = norm(c);
        if (!(l > 0)) continue;
        u[m] = (1.0 / l) * c;
        worst = std::min(worst, dot(n, u[m]));
        ++m;
    }
    clears = m > 0 && worst > 0;
    if (m == 0 || worst >= kCornerCone) return n;
    Vec3 x = n;  // Gilbert's iteration from n (in the hull's span after the first step)
    for (int it = 0; it < 64; ++it) {
        int arg = 0;
        for (int i = 1; i < m; ++i)
            if (dot(x, u[i]) < dot(x, u[arg])) arg = i;
        const double xl = norm(x);
        if (it > 0 && xl > 0 && dot(x, u[arg]) >= kCornerCone * xl) break;
        const Vec3 e = x - u[arg];
        const double ee = dot(e, e);
        if (!(ee > 0)) break;
        const double t = std::clamp(dot(x, e) / ee, 0.0, 1.0);
        if (t == 0) break;  // x is the minimum-norm point
        x = x - t * e;
    }
    const double xl = norm(x);
    if (!(xl > 1e-9)) return n;
    double least = 1;
    for (int i = 0; i < m; ++i) least = std::min(least, dot(x, u[i]) / xl);
    if (!(least > worst)) return n;
    clears = least > 0;
    return (1.0 / xl) * x;
}

// The inward step of the copy of node v (slot s): `inset` times the mean
// length of its boundary quads' edges at v, along the averaged inward normal
// (area weighted, over the node's boundary quads in quad order) turned where
// needed to point inside every boundary quad's corner at v
// (clearCornerNormals). Where no direction does, and the normal points away
// from the centroid of the shrink-set hexes around the node, towards that
// centroid.
Vec3 inwardStep(const std::vector<Vec3>& P, const Boundary& b, const BigVec<QuadGeometry>& quadGeometry,
                const BigVec<Vec3>& cornerSum, double B, Index s, Index v, double inset, bool turn) {
    const BigCsr& around = b.quads.around;
    const BigCsr& nodeT = b.hexes.nodeT;
    Vec3 normal{0, 0, 0};
    double edgeSum = 0;
    int edgeCount = 0;
    for (const Index* it = around.begin(s); it != around.end(s); ++it) {
        const QuadGeometry& g = quadGeometry[static_cast<std::size_t>(*it / 4)];
        const int k = *it % 4;
        normal = normal + g.area;
        edgeSum += g.edge[k] + g.edge[(k + 3) % 4];
        edgeCount += 2;
    }
    const double len = norm(normal);
    bool clears = false;
    Vec3 dir = len > 0 ? (turn ? -1.0 * clearCornerNormals(P, b.quads, around, s, v, (1.0 / len) * normal, clears)
                              : (-1.0 / len) * normal)
                       : Vec3{0, 0, 0};
    const double step = inset * edgeSum / edgeCount;
    if (clears) return step * dir;
    // The centroid from the per-hex sums (another order of the same n terms)
    // is within about 2 n u B per coordinate of the one summed corner by
    // corner (u = 2^-53, B the largest coordinate), so where the sign test
    // passes by the margin 16 (n + 8) u B it passes with the corner-by-corner
    // sum too; elsewhere (a fraction of a percent of the copies) that sum is
    // made and decides.
    Vec3 c{0, 0, 0};
    int n = 0;
    for (const Index* it = nodeT.begin(s); it != nodeT.end(s); ++it) {
        c = c + cornerSum[static_cast<std::size_t>(*it)];
        n += 8;
    }
    const double margin = 16.0 * (n + 8.0) * std::ldexp(B, -53);
    if (!(dot(dir, (1.0 / n) * c - P[v]) > margin)) {
        c = Vec3{0, 0, 0};
        for (const Index* it = nodeT.begin(s); it != nodeT.end(s); ++it)
            for (Index u : b.hexes.hex[static_cast<std::size_t>(*it)]) c = c + P[u];
    }
    const Vec3 toCentre = (1.0 / n) * c - P[v];
    if (dot(dir, toCentre) <= 0) {
        const double l = norm(toCentre);
        dir = l > 0 ? (1.0 / l) * toCentre : Vec3{0, 0, 0};
    }
    return step * dir;
}

// Per copy, its inward step (inwardStep) from its node.
BigVec<Vec3> inwardSteps(const std::vector<Vec3>& P, const Boundary& b, const Copies& copies,
                         const std::vector<Index>& copyOf, double inset, bool turn) {
    BigVec<Vec3> push(copies.count());
    BigVec<QuadGeometry> quadGeometry = quadGeometries(P, b.quads);
    double B = 0;
    BigVec<Vec3> cornerSum = cornerSums(P, b.hexes, B);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, copies.count(), 1024), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i)
            push[i] = inwardStep(P, b, quadGeometry, cornerSum, B, copies.copySlot[i], copyOf[i], inset, turn);
    });
    release(quadGeometry);
    release(cornerSum);
    return push;
}

// Applies the split: copies appended at their node plus its step, the
// shrink-set hexes (only those of T can hold a split node) take the copies
// (b.hexes.hex follows: the step rounds read it), and one new hex per
// boundary quad is appended, copies below and the quad's nodes above.
void splitNodes(HexMesh& mesh, std::span<const Index> S, Boundary& b, const Copies& copies, const BigVec<Vec3>& push,
                const std::vector<Index>& copyOf) {
    const std::size_t H = mesh.hexCount(), N = mesh.nodeCount(), C = copies.count(), Q = b.quads.size();
    const Index NI = static_cast<Index>(N);
    reserveHuge(mesh.nodes, N + C);
    reserveHuge(mesh.nodeClass, N + C);
    mesh.nodes.resize(N + C);
    mesh.nodeClass.resize(N + C, NodeClass{});
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, C, 4096), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) mesh.nodes[N + i] = mesh.nodes[copyOf[i]] + push[i];
    });
    CandidateHexes& t = b.hexes;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, t.size(), 4096), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            for (int k = 0; k < 8; ++k) {
                const Index s = t.slot[i][k];
                const Index c = s == kNone ? kNone : copies.ofSlot(s);
                if (c != kNone) t.hex[i][k] = NI + c;
            }
            mesh.hexes[static_cast<std::size_t>(S[static_cast<std::size_t>(t.T[i])])] = t.hex[i];
        }
    });
    reserveHuge(mesh.hexes, H + Q);
    reserveHuge(mesh.material, H + Q);
    mesh.hexes.resize(H + Q);
    mesh.material.resize(H + Q);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, Q, 4096), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const auto& q = b.quads.nodes[i];
            const auto& qs = b.quads.slots[i];
            mesh.hexes[H + i] = {NI + copies.ofSlot(qs[0]), NI + copies.ofSlot(qs[1]), NI + copies.ofSlot(qs[2]),
                                 NI + copies.ofSlot(qs[3]), q[0], q[1], q[2], q[3]};
            mesh.material[H + i] = mesh.material[b.quads.faces[i].first];
        }
    });
}

// ------------------------------------------------------------ the step rounds

// Shortens the inward step of copies where a hex around them inverted. The
// hexes watched: position i < |T| is the shrink-set hex T[i] (when it holds a
// copy), position |T| + q the new hex of quad q. Each round, every inverted
// hex around a copy that moved asks how many more halvings of its copies'
// steps (all together, up to maxHalvings) make it valid; a copy takes the
// most any of its hexes asks for, and the hexes around the copies that moved
// are checked again. A hex that no step length can fix (a shrink-set hex
// inverted before the split, or a sheet hex on a surface quad that folds
// against its copies' steps) asks for the shortest step at once. This settles
// in a few rounds over the few hexes involved.
class StepSettler {
public:
    StepSettler(HexMesh& mesh, std::size_t firstNewHex, const Boundary& b, const Copies& copies,
                const std::vector<Index>& copyOf, const BigVec<Vec3>& push, int maxHalvings)
        : mesh_(mesh), H_(firstNewHex), NI_(static_cast<Index>(mesh.nodeCount() - copies.count())), b_(b),
          copies_(copies), copyOf_(copyOf), push_(push), maxK_(std::max(0, maxHalvings)),
          halvings_(copies.count(), 0), want_(copies.count(), 0),
          watch_(b.hexes.size() + (mesh.hexCount() - firstNewHex)) {}

    // Runs the rounds; returns the number of hexes still inverted when the
    // copies were first placed.
    std::size_t run() {
        const std::size_t W = watch_.size();
        for (int round = 0; round <= maxK_; ++round) {
            if (round > 0) active_ = keepWhere(W, [&](std::size_t i) { return watch_[i].next == round; });
            const std::size_t A = round == 0 ? W : active_.size();
            if (judgeAll(round, A) == 0 || round == maxK_) break;
            gatherWants(round, A);
            if (!takeWants(round)) break;
        }
        return static_cast<std::size_t>(
            std::count_if(watch_.begin(), watch_.end(), [](const Watch& w) { return w.bad == 1; }));
    }

    // The copies the rounds shortened, in increasing order.
    BigVec<Index> shortened() const {
        return keepWhere(copies_.count(), [&](std::size_t c) { return halvings_[c] > 0; });
    }

    // The watched hexes inverted now (after other moves of the copies).
    std::size_t invertedNow() const {
        return tbb::parallel_reduce(
            tbb::blocked_range<std::size_t>(0, watch_.size(), 4096), std::size_t{0},
            [&](const auto& r, std::size_t n) {
                for (std::size_t i = r.begin(); i != r.end(); ++i) {
                    const Hex& hx = watchHex(i);
                    if (std::none_of(hx.begin(), hx.end(), [&](Index v) { return v >= NI_; })) continue;
                    const Vec3* x[8];
                    for (int c = 0; c < 8; ++c) x[c] = &mesh_.nodes[static_cast<std::size_t>(hx[c])];
                    n += !jacobianPositive(x);
                }
                return n;
            },
            std::plus<>());
    }

private:
    struct Watch {
        std::uint8_t bad = 0, hopeless = 0, ask = 0;
        std::uint16_t next = 0;  // the round that checks it again (a copy of it moved): nothing to clear between rounds
    };

    const Hex& watchHex(std::size_t i) const {
        const std::size_t T = b_.hexes.size();
        return i < T ? b_.hexes.hex[i] : mesh_.hexes[H_ + (i - T)];
    }
    Vec3 place(std::size_t c, int k) const { return mesh_.nodes[copyOf_[c]] + std::ldexp(1.0, -k) * push_[c]; }
    // The j-th hex checked this round: every position in round 0, the dirty ones after.
    std::size_t position(int round, std::size_t j) const {
        return round == 0 ? j : static_cast<std::size_t>(active_[j]);
    }

    // Judges the A hexes of this round in parallel; returns how many ask.
    std::size_t judgeAll(int round, std::size_t A) {
        std::atomic<std::size_t> triggers{0};
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, A, 1024), [&](const auto& r) {
            std::size_t t = 0;
            for (std::size_t j = r.begin(); j != r.end(); ++j) {
                // The corners are scattered over the node array: fetch the
                // hex a few positions ahead and its corners a few less.
                if (j + 16 < r.end()) prefetch(&watchHex(position(round, j + 16)));
                if (j + 8 < r.end())
                    for (Index v : watchHex(position(round, j + 8)))
                        prefetch(&mesh_.nodes[static_cast<std::size_t>(v)]);
                t += judge(position(round, j), round);
            }
            triggers += t;
        });
        return triggers;
    }

    // Sets watch_[i].ask: 0 if hex i is valid (or holds no copy), else the
    // halvings its copies need (the most where none helps). Returns whether it asks.
    bool judge(std::size_t i, int round) {
        Watch& w = watch_[i];
        w.ask = 0;
        const Hex& hx = watchHex(i);
        if (round == 0 && std::none_of(hx.begin(), hx.end(), [&](Index v) { return v >= NI_; })) return false;
        const Vec3* x[8];
        for (int c = 0; c < 8; ++c) x[c] = &mesh_.nodes[static_cast<std::size_t>(hx[c])];
        w.bad = !jacobianPositive(x);
        if (!w.bad) return false;
        Vec3 moved[8];  // corners of a trial shape
        const Vec3* y[8];
        if (round == 0) {
            // Shrink-set hex: its shape with the copies back on their nodes.
            // Sheet hex: its shape with the copies a hair inside (each
            // corner's sign there is that of the surface quad's corner normal
            // against the copy's step, whatever the step's length, so halving
            // cannot help if it is not positive).
            const bool sheetHex = i >= b_.hexes.size();
            for (int c = 0; c < 8; ++c) {
                y[c] = x[c];
                if (hx[c] >= NI_) {
                    const std::size_t cc = static_cast<std::size_t>(hx[c] - NI_);
                    moved[c] = mesh_.nodes[copyOf_[cc]];
                    if (sheetHex) moved[c] = moved[c] + 1e-3 * push_[cc];
                    y[c] = &moved[c];
                }
            }
            w.hopeless = !jacobianPositive(y);
        }
        if (w.hopeless) {  // no length helps: the shortest at once
            w.ask = static_cast<std::uint8_t>(maxK_);
            return true;
        }
        int k = 1;
        for (; k < maxK_; ++k) {
            for (int c = 0; c < 8; ++c) {
                y[c] = x[c];
                if (hx[c] >= NI_) {
                    const std::size_t cc = static_cast<std::size_t>(hx[c] - NI_);
                    moved[c] = place(cc, std::min(maxK_, halvings_[cc] + k));
                    y[c] = &moved[c];
                }
            }
            if (jacobianPositive(y)) break;
        }
        w.ask = static_cast<std::uint8_t>(k);
        return true;
    }

    // A copy wants the most any of its asking hexes asks for (a maximum: the
    // same in any order).
    void gatherWants(int round, std::size_t A) {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, A, 4096), [&](const auto& r) {
            for (std::size_t j = r.begin(); j != r.end(); ++j)
                if (const std::size_t i = position(round, j); watch_[i].ask)
                    for (Index v : watchHex(i))
                        if (v >= NI_) {
                            std::atomic_ref<int> w(want_[static_cast<std::size_t>(v - NI_)]);
                            int cur = w.load(std::memory_order_relaxed);
                            while (cur < watch_[i].ask &&
                                   !w.compare_exchange_weak(cur, watch_[i].ask, std::memory_order_relaxed)) {
                            }
                        }
        });
    }

    // Each copy takes the halvings it wants and moves; the hexes around the
    // copies that moved are marked for the next round. False if none moved.
    bool takeWants(int round) {
        const std::size_t C = copies_.count(), N = static_cast<std::size_t>(NI_);
        const BigVec<Index> touched = keepWhere(C, [&](std::size_t c) { return want_[c] != 0; });
        BigVec<std::uint8_t> didMove(touched.size(), 0);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, touched.size(), 1024), [&](const auto& r) {
            for (std::size_t j = r.begin(); j != r.end(); ++j) {
                const std::size_t c = static_cast<std::size_t>(touched[j]);
                const int k = std::min(maxK_, halvings_[c] + want_[c]);
                want_[c] = 0;
                if (k != halvings_[c]) {
                    halvings_[c] = k;
                    mesh_.nodes[N + c] = place(c, k);
                    didMove[j] = 1;
                }
            }
        });
        const BigVec<Index> moved = keepWhere(touched.size(), [&](std::size_t j) { return didMove[j] != 0; });
        if (moved.empty()) return false;
        const auto next = static_cast<std::uint16_t>(round + 1);
        const std::size_t T = b_.hexes.size();
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, moved.size(), 1024), [&](const auto& r) {
            for (std::size_t j = r.begin(); j != r.end(); ++j) {
                const Index s = copies_.copySlot[static_cast<std::size_t>(touched[static_cast<std::size_t>(moved[j])])];
                for (const Index* it = b_.hexes.nodeT.begin(s); it != b_.hexes.nodeT.end(s); ++it)
                    std::atomic_ref<std::uint16_t>(watch_[static_cast<std::size_t>(*it)].next)
                        .store(next, std::memory_order_relaxed);
                for (const Index* it = b_.quads.around.begin(s); it != b_.quads.around.end(s); ++it)
                    std::atomic_ref<std::uint16_t>(watch_[T + static_cast<std::size_t>(*it / 4)].next)
                        .store(next, std::memory_order_relaxed);
            }
        });
        return true;
    }

    HexMesh& mesh_;
    const std::size_t H_;  // the first new hex
    const Index NI_;       // the first copy
    const Boundary& b_;
    const Copies& copies_;
    const std::vector<Index>& copyOf_;
    const BigVec<Vec3>& push_;
    const int maxK_;
    BigVec<int> halvings_, want_;  // per copy
    BigVec<Watch> watch_;
    BigVec<Index> active_;  // the positions checked this round (after round 0)
};

// The rounds shorten every copy of an inverted hex together, and a copy
// shortened stays short where the hexes beside it were inverted by its
// neighbours rather than by itself: most copies of a sheet on a sphere end
// within 1% of an edge of their node, and the optimiser then spends a dozen
// sweeps moving them in. Here each shortened copy (in index order, so the
// same for any thread count) goes on alone towards kAloneFraction of its
// full step, as far as every hex around it that is valid stays valid.
// Returns whether any moved.
//
// The fraction and the single pass are measured choices: the optimiser's
// node visits are within 3% of those with the full step or three passes
// (a copy moved gives its neighbours room), but the full step left ch2bet
// at 4 mm with four hexes at 0.26-0.28 that neither the boundary relaxation
// nor feature removal lifted to its certified 0.3 (0.308 with 70%), and three
// passes left a curve node of the two_materials phantom stuck beside a hex
// the untangler could not clear. The worst hexes after the optimiser hang
// on such details; bench/RESULTS.md has the certified minimum per input.
constexpr int kAlonePasses = 1;
constexpr double kAloneFraction = 0.7;

bool stepShortenedCopiesAlone(HexMesh& mesh, const BigVec<Index>& shortened, std::size_t firstCopy,
                              const std::vector<Index>& copyOf, const BigVec<Vec3>& push, int maxHalvings) {
    if (shortened.empty()) return false;
    std::vector<Index> nodes(shortened.size());
    std::vector<Vec3> targets(shortened.size());
    for (std::size_t i = 0; i < shortened.size(); ++i) {
        const auto c = static_cast<std::size_t>(shortened[i]);
        nodes[i] = static_cast<Index>(firstCopy + c);
        targets[i] = mesh.nodes[static_cast<std::size_t>(copyOf[c])] + kAloneFraction * push[c];
    }
    const TargetsResult r = moveTowardsTargets(mesh, nodes, targets, maxHalvings, kAlonePasses);
    return r.reached + r.partway > 0;
}

}  // namespace

PillowResult pillow(HexMesh& mesh, const std::vector<Index>& shrinkSet, const PillowOptions& opt) {
    if (shrinkSet.empty()) throw Error("cannot pillow: the shrink set is empty");
    const std::size_t H = mesh.hexCount(), N = mesh.nodeCount();
    BigVec<Index> sorted;
    const std::span<const Index> S = sortedShrinkSet(shrinkSet, H, sorted);
    Boundary b = findManifoldBoundary(mesh, S, opt.exactBoundary);
    release(b.cand.slot);  // the corners' slots are in b.hexes.slot from here on

    PillowResult res;
    res.firstNewHex = static_cast<Index>(H);
    res.firstNewNode = static_cast<Index>(N);
    const Copies copies = numberCopies(b, res.copyOf);
    const BigVec<Vec3> push = inwardSteps(mesh.nodes, b, copies, res.copyOf, opt.inset, opt.turnIntoCorners);
    splitNodes(mesh, S, b, copies, push, res.copyOf);
    release(b.hexes.slot);
    release(b.quads.faces);
    release(b.quads.nodes);
    release(b.quads.slots);
    StepSettler settler(mesh, H, b, copies, res.copyOf, push, opt.maxHalvings);
    res.invertedAtStart = settler.run();
    if (opt.stepOnAlone && stepShortenedCopiesAlone(mesh, settler.shortened(), N, res.copyOf, push, opt.maxHalvings))
        res.invertedAtStart = settler.invertedNow();
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
        reserveHuge(shrink, mesh.hexCount());
        if (mats.size() == 1) {  // every hex
            shrink.resize(mesh.hexCount());
            tbb::parallel_for(tbb::blocked_range<std::size_t>(0, shrink.size(), 1 << 16), [&](const auto& r) {
                for (std::size_t h = r.begin(); h != r.end(); ++h) shrink[h] = static_cast<Index>(h);
            });
        } else {
            for (std::size_t h = 0; h < mesh.hexCount(); ++h)
                if (mesh.material[h] == m) shrink.push_back(static_cast<Index>(h));
        }
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

}  // namespace isohex
