#include "isohex/core/Sheets.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <new>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <span>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#if defined(__linux__)
#include <sys/mman.h>
#endif

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

int cornerAt(int x, int y, int z) {
    for (int c = 0; c < 8; ++c)
        if (kRef[c][0] == x && kRef[c][1] == y && kRef[c][2] == z) return c;
    return -1;
}

// Fresh anonymous memory is mapped page by page on first write, and in a
// virtual machine each 4 KiB fault is dear (3 ms per MB on the bench machine,
// against 0.1 ms per MB for 2 MiB pages): large buffers that are about to be
// written ask for transparent huge pages where the kernel grants them on
// request. Only whole aligned 2 MiB pieces of the range qualify; a hint, so
// nothing changes where it is not honoured.
void adviseHugePages(const void* p, std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    constexpr std::uintptr_t kHuge = std::uintptr_t{1} << 21;
    const auto begin = (reinterpret_cast<std::uintptr_t>(p) + kHuge - 1) & ~(kHuge - 1);
    const auto end = (reinterpret_cast<std::uintptr_t>(p) + bytes) & ~(kHuge - 1);
    if (end > begin) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
#else
    (void)p;
    (void)bytes;
#endif
}

// Room for n elements, with the part not yet written advised as above.
template <class T>
void reserveHuge(std::vector<T>& v, std::size_t n) {
    if (v.capacity() < n) v.reserve(n);
    adviseHugePages(v.data() + v.size(), (v.capacity() - v.size()) * sizeof(T));
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

// An allocator for pillow's own large temporaries: whole 2 MiB pages,
// aligned and advised as above, so a buffer costs a few faults instead of one
// per 4 KiB, mapped for it alone and unmapped when it goes (so its memory
// returns to the system at once, and malloc's own thresholds are left
// alone). Small ones come from operator new as usual.
constexpr std::size_t kHugePage = std::size_t{1} << 21;
constexpr std::size_t kHugeFrom = std::size_t{1} << 20;  // bytes

template <class T>
struct HugeAlloc {
    using value_type = T;
    HugeAlloc() = default;
    template <class U>
    HugeAlloc(const HugeAlloc<U>&) {}
    static std::size_t rounded(std::size_t bytes) { return (bytes + kHugePage - 1) & ~(kHugePage - 1); }
    T* allocate(std::size_t n) {
        const std::size_t bytes = n * sizeof(T);
#if defined(__linux__) && defined(MADV_HUGEPAGE)
        if (bytes >= kHugeFrom) {
            const std::size_t size = rounded(bytes);
            void* m = mmap(nullptr, size + kHugePage, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
            if (m == MAP_FAILED) throw std::bad_alloc();
            const auto start = reinterpret_cast<std::uintptr_t>(m);
            const auto begin = (start + kHugePage - 1) & ~(kHugePage - 1);
            if (begin > start) munmap(m, begin - start);
            if (begin - start < kHugePage) munmap(reinterpret_cast<void*>(begin + size), kHugePage - (begin - start));
            adviseHugePages(reinterpret_cast<void*>(begin), size);
            return reinterpret_cast<T*>(begin);
        }
#endif
        return static_cast<T*>(::operator new(bytes));
    }
    void deallocate(T* p, std::size_t n) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
        if (n * sizeof(T) >= kHugeFrom) {
            munmap(p, rounded(n * sizeof(T)));
            return;
        }
#endif
        ::operator delete(p);
    }
    template <class U>
    bool operator==(const HugeAlloc<U>&) const { return true; }
};
template <class T>
using BigVec = std::vector<T, HugeAlloc<T>>;

// Gives a buffer's memory back at once (the large ones go back to the system).
template <class V>
void release(V& v) {
    V().swap(v);
}

// Rows of items (a CSR) in BigVecs.
struct Rows {
    BigVec<Index> offsets, items;
    std::size_t rows() const { return offsets.empty() ? 0 : offsets.size() - 1; }
    std::size_t size(std::size_t r) const { return static_cast<std::size_t>(offsets[r + 1] - offsets[r]); }
    const Index* begin(std::size_t r) const { return items.data() + offsets[r]; }
    const Index* end(std::size_t r) const { return items.data() + offsets[r + 1]; }
};

inline void prefetch(const void* p) {
#if defined(__GNUC__)
    __builtin_prefetch(p);
#else
    (void)p;
#endif
}

// Positions i in [0, n) where flag(i) holds, in increasing order, found in
// parallel over fixed blocks (so the same for any thread count); flag is
// evaluated once per position, onCount(kept) is called once the number kept
// is known, then onKept(i, rank) for each kept one.
template <class Flag, class OnCount, class OnKept>
BigVec<Index> keepWhere(std::size_t n, Flag flag, OnCount onCount, OnKept onKept) {
    constexpr std::size_t B = std::size_t{1} << 14;
    const std::size_t blocks = (n + B - 1) / B;
    BigVec<std::uint8_t> f(n);
    std::vector<Index> count(blocks + 1, 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks, 1), [&](const auto& r) {
        for (std::size_t b = r.begin(); b != r.end(); ++b) {
            Index k = 0;
            for (std::size_t i = b * B, e = std::min(n, i + B); i < e; ++i) k += f[i] = flag(i) ? 1 : 0;
            count[b + 1] = k;
        }
    });
    for (std::size_t b = 0; b < blocks; ++b) count[b + 1] += count[b];
    onCount(static_cast<std::size_t>(count[blocks]));
    BigVec<Index> out(static_cast<std::size_t>(count[blocks]));
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks, 1), [&](const auto& r) {
        for (std::size_t b = r.begin(); b != r.end(); ++b) {
            Index k = count[b];
            for (std::size_t i = b * B, e = std::min(n, i + B); i < e; ++i)
                if (f[i]) {
                    out[static_cast<std::size_t>(k)] = static_cast<Index>(i);
                    onKept(i, k++);
                }
        }
    });
    return out;
}

template <class Flag>
BigVec<Index> keepWhere(std::size_t n, Flag flag) {
    return keepWhere(n, flag, [](std::size_t) {}, [](std::size_t, Index) {});
}

// Rows 0..rows-1 of the pairs (row, item) that forEachIn(lo, hi, emit)
// produces for the elements lo..hi-1 of [0, n), in the order it produces
// them (so rows come out sorted when items are produced in increasing order).
// A counting sort over a few contiguous blocks of [0, n), in parallel: each
// block counts its own, then writes after the blocks before it, so the rows
// are those of one serial pass for any number of blocks.
template <class ForEachIn>
Rows rowsInOrder(std::size_t rows, std::size_t n, ForEachIn forEachIn) {
    const std::size_t P = std::clamp<std::size_t>(static_cast<std::size_t>(tbb::this_task_arena::max_concurrency()), 1, 4);
    BigVec<Index> at(P * rows, 0);  // per block and row: its count, then where it writes
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, P, 1), [&](const auto& r) {
        for (std::size_t b = r.begin(); b != r.end(); ++b) {
            Index* count = at.data() + b * rows;
            forEachIn(n * b / P, n * (b + 1) / P, [&](Index row, Index) { ++count[static_cast<std::size_t>(row)]; });
        }
    });
    Rows c;
    c.offsets.resize(rows + 1);
    Index next = 0;
    for (std::size_t row = 0; row < rows; ++row) {
        c.offsets[row] = next;
        for (std::size_t b = 0; b < P; ++b) {
            const Index k = at[b * rows + row];
            at[b * rows + row] = next;
            next += k;
        }
    }
    c.offsets[rows] = next;
    c.items.resize(static_cast<std::size_t>(next));
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, P, 1), [&](const auto& r) {
        for (std::size_t b = r.begin(); b != r.end(); ++b) {
            Index* cursor = at.data() + b * rows;
            forEachIn(n * b / P, n * (b + 1) / P, [&](Index row, Index item) {
                c.items[static_cast<std::size_t>(cursor[static_cast<std::size_t>(row)]++)] = item;
            });
        }
    });
    return c;
}

}  // namespace

PillowResult pillow(HexMesh& mesh, const std::vector<Index>& shrinkSet, const PillowOptions& opt) {
    if (shrinkSet.empty()) throw Error("cannot pillow: the shrink set is empty");
    const std::size_t H = mesh.hexCount(), N = mesh.nodeCount();
    const Index NI = static_cast<Index>(N);
    bool increasing = true;
    for (std::size_t i = 0; i < shrinkSet.size(); ++i) {
        const Index h = shrinkSet[i];
        if (h < 0 || static_cast<std::size_t>(h) >= H)
            throw Error("cannot pillow: shrink set names hex " + std::to_string(h) + " but the mesh has " +
                        std::to_string(H) + " hexes");
        increasing = increasing && (i == 0 || shrinkSet[i - 1] < h);
    }
    BigVec<Index> sorted;  // the shrink set, sorted and without repeats (unless it already is)
    if (!increasing) {
        BigVec<std::uint8_t> inS(H, 0);
        for (Index h : shrinkSet) inS[h] = 1;
        sorted = keepWhere(H, [&](std::size_t h) { return inS[h] != 0; });
    }
    const std::span<const Index> S = increasing ? std::span<const Index>(shrinkSet) : std::span<const Index>(sorted);

    // Nodes on the boundary of the shrink set, by parity: each face of a
    // shrink-set hex XORs a 32-bit hash of its four nodes (the sum of one
    // hash per node, so the same in any order) into each of them. A
    // face two shrink-set hexes share cancels, so a node stays 0 unless a
    // boundary face meets it (or, with chance 2^-32 per node, its boundary
    // faces' hashes cancel: then the sheet misses faces, the checks below
    // fail and the exact pass over the whole shrink set is used). Each thread
    // XORs into its own array (XOR commutes: the same result for any thread
    // count, without an atomic per corner). 32 bits rather than 64 halve
    // the arrays these scattered writes land in; a miss only costs the exact
    // pass.
    tbb::enumerable_thread_specific<BigVec<std::uint32_t>> parities([N] { return BigVec<std::uint32_t>(N, 0); });
    if (!opt.exactBoundary)
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

    // Everything below works on the candidate nodes only (the boundary nodes
    // by parity, or every node for the exact pass), numbered in increasing
    // node order ("slots"), and on the hexes of S that hold one (T). Only
    // those hexes need the node -> hex adjacency.
    // Per node, its slot or kNoSlot (in fast mode the storage of the first
    // parity array, so no further N-sized array is written), and one bit per
    // node for "is a candidate" (small enough to stay in cache while every
    // hex of S is tested against it).
    constexpr std::uint32_t kNoSlot = ~std::uint32_t{0};
    BigVec<std::uint32_t> slot;
    BigVec<std::uint64_t> isCand;
    auto slotOf = [&](Index v) { return static_cast<Index>(slot[static_cast<std::size_t>(v)]); };  // kNoSlot: kNone
    auto candidate = [&](Index v) { return (isCand[static_cast<std::size_t>(v) >> 6] >> (v & 63) & 1) != 0; };
    BigVec<Index> candNode;      // per slot, its node
    BigVec<Index> T;             // positions in S of the hexes that hold a candidate node
    Rows nodeT;                  // slot -> positions in T of the hexes holding it, increasing
    BigVec<std::pair<Index, int>> faces;
    BigVec<std::array<Index, 4>> quadNodes;
    BigVec<std::array<Index, 4>> quadSlots;
    Rows around;                 // slot -> 4 * quad + corner, increasing
    // The hexes of T and their corners' slots, copied out in order: the
    // passes below read them in sequence instead of scattered over the mesh.
    BigVec<Hex> tHex;
    BigVec<std::array<Index, 8>> tSlot;
    auto hexAtT = [&](Index t) -> const Hex& { return tHex[static_cast<std::size_t>(t)]; };
    auto findBoundary = [&](bool exact) {
        if (exact) {
            slot.assign(N, 0);
            std::iota(slot.begin(), slot.end(), 0);
            candNode.resize(N);
            std::iota(candNode.begin(), candNode.end(), 0);
            isCand.assign((N + 63) / 64, ~std::uint64_t{0});
        } else {
            // XOR the threads' arrays into the first, then number the nodes
            // whose parity is not 0 in increasing order, in fixed blocks.
            std::vector<BigVec<std::uint32_t>*> locals;
            for (auto& local : parities) locals.push_back(&local);
            slot = std::move(*locals[0]);
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
            candNode.resize(static_cast<std::size_t>(count[blocks]));
            isCand.assign((N + 63) / 64, 0);  // B is a multiple of 64: each block owns whole words
            tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks, 1), [&](const auto& r) {
                for (std::size_t b = r.begin(); b != r.end(); ++b) {
                    Index k = count[b];
                    for (std::size_t v = b * B, e = std::min(N, v + B); v < e; ++v)
                        if (slot[v] != 0) {
                            candNode[static_cast<std::size_t>(k)] = static_cast<Index>(v);
                            slot[v] = static_cast<std::uint32_t>(k++);
                            isCand[v >> 6] |= std::uint64_t{1} << (v & 63);
                        } else {
                            slot[v] = kNoSlot;
                        }
                }
            });
            parities.clear();
        }
        const std::size_t nCand = candNode.size();
        // T, with each kept hex and its corners' slots copied out as it is
        // written (one pass over S instead of a second, scattered one).
        T = keepWhere(
            S.size(),
            [&](std::size_t i) {
                for (Index v : mesh.hexes[S[i]])
                    if (candidate(v)) return true;
                return false;
            },
            [&](std::size_t kept) {
                tHex.resize(kept);
                tSlot.resize(kept);
            },
            [&](std::size_t i, Index t) {
                const Hex& hx = mesh.hexes[S[i]];
                tHex[static_cast<std::size_t>(t)] = hx;
                for (int c = 0; c < 8; ++c) tSlot[static_cast<std::size_t>(t)][c] = slotOf(hx[c]);
            });
        release(isCand);
        nodeT = rowsInOrder(nCand, T.size(), [&](std::size_t lo, std::size_t hi, auto emit) {
            for (std::size_t t = lo; t < hi; ++t)
                for (Index s : tSlot[t])
                    if (s != kNone) emit(s, static_cast<Index>(t));
        });

        // Faces of shrink-set hexes that no other shrink-set hex shares: the
        // boundary of the shrink set, seen from inside (outward normals), in
        // (hex, face) order for any thread count.
        BigVec<std::uint8_t> faceMask(T.size(), 0);
        std::atomic<Index> overfull{kNone};
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, T.size(), 1024), [&](const auto& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                const Index self = S[static_cast<std::size_t>(T[i])];
                const Hex& hx = tHex[i];
                const auto& sl = tSlot[i];
                std::uint8_t mask = 0;
                for (int f = 0; f < 6; ++f) {
                    const auto& lf = hexcell::kFaces[f];
                    if (sl[lf[0]] == kNone || sl[lf[1]] == kNone || sl[lf[2]] == kNone || sl[lf[3]] == kNone)
                        continue;  // a node of the face is interior: the face is shared
                    // Another hex holding the face holds both ends of its diagonal
                    // lf[0]-lf[2]: walk the two (sorted) rows together, then check
                    // the other diagonal only for the hexes they share.
                    int sharers = 0;
                    const Index* a = nodeT.begin(sl[lf[0]]);
                    const Index* ae = nodeT.end(sl[lf[0]]);
                    const Index* b = nodeT.begin(sl[lf[2]]);
                    const Index* be = nodeT.end(sl[lf[2]]);
                    while (a != ae && b != be) {
                        if (*a < *b) {
                            ++a;
                        } else if (*b < *a) {
                            ++b;
                        } else {
                            if (*a != static_cast<Index>(i)) {
                                const Hex& ho = hexAtT(*a);
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
        BigVec<Index> first(T.size() + 1, 0);  // first face of each hex of T
        for (std::size_t i = 0; i < T.size(); ++i) first[i + 1] = first[i] + std::popcount(faceMask[i]);
        const std::size_t Q = static_cast<std::size_t>(first[T.size()]);
        faces.resize(Q);
        quadNodes.resize(Q);
        quadSlots.resize(Q);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, T.size(), 4096), [&](const auto& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                std::size_t q = static_cast<std::size_t>(first[i]);
                const Index h = S[static_cast<std::size_t>(T[i])];
                const Hex& hx = tHex[i];
                const auto& sl = tSlot[i];
                for (int f = 0; f < 6; ++f)
                    if (faceMask[i] >> f & 1) {
                        const auto& lf = hexcell::kFaces[f];
                        faces[q] = {h, f};
                        quadNodes[q] = {hx[lf[0]], hx[lf[1]], hx[lf[2]], hx[lf[3]]};
                        quadSlots[q] = {sl[lf[0]], sl[lf[1]], sl[lf[2]], sl[lf[3]]};
                        ++q;
                    }
            }
        });
        around = rowsInOrder(nCand, Q, [&](std::size_t lo, std::size_t hi, auto emit) {
            for (std::size_t q = lo; q < hi; ++q)
                for (int c = 0; c < 4; ++c) emit(quadSlots[q][c], static_cast<Index>(4 * q + c));
        });
    };
    auto check = [&](bool exact) {
        ManifoldCheck mc = checkManifold(quadSlots.data(), around.offsets.data(), around.items.data(), around.rows(), true);
        for (auto& e : mc.badEdges) e = {candNode[e[0]], candNode[e[1]]};
        for (auto& v : mc.badNodes) v = candNode[v];
        // Every boundary node by parity lies on a boundary face unless a
        // node of that face was missed: use the exact pass then.
        if (!exact && mc.ok())
            for (std::size_t s = 0; s < around.rows(); ++s)
                if (around.size(s) == 0) {
                    mc.badNodes.push_back(candNode[s]);
                    break;
                }
        return mc;
    };
    findBoundary(opt.exactBoundary);
    ManifoldCheck mc = check(opt.exactBoundary);
    if (!mc.ok() && !opt.exactBoundary) {
        findBoundary(true);
        mc = check(true);
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

    release(slot);  // the corners' slots are in tSlot from here on

    // Split nodes (the slots on the boundary faces), numbered in increasing
    // original index.
    PillowResult res;
    res.firstNewHex = static_cast<Index>(H);
    res.firstNewNode = static_cast<Index>(N);
    const std::size_t nCand = candNode.size();
    BigVec<Index> copySlot = keepWhere(nCand, [&](std::size_t s) { return around.size(s) != 0; });
    const std::size_t C = copySlot.size();
    BigVec<Index> slotCopy; // per slot, its copy (only when some slot has none)
    if (C != nCand) {
        slotCopy.assign(nCand, kNone);
        for (std::size_t c = 0; c < C; ++c) slotCopy[copySlot[c]] = static_cast<Index>(c);
    }
    auto copyOfSlot = [&](Index s) { return slotCopy.empty() ? s : slotCopy[static_cast<std::size_t>(s)]; };
    res.copyOf.resize(C);
    for (std::size_t c = 0; c < C; ++c) res.copyOf[c] = candNode[copySlot[c]];

    // Each copy starts at its node plus `push`, an inward step of `inset`
    // local edge lengths that the loop below halves where it inverts a hex.
    // Inward is the averaged inward normal (area weighted, over the node's
    // boundary quads in quad order), or towards the centroid of the
    // shrink-set hexes around the node where the normal points away from them.
    const std::size_t Q = faces.size();
    BigVec<Vec3> push(C);
    const std::vector<Vec3>& P = mesh.nodes;
    // Per quad, its area vector and edge lengths (edge j from corner j to
    // j + 1; the same numbers as from either end, as -0 and 0 square alike).
    struct QuadGeometry {
        Vec3 area;
        double edge[4];
    };
    BigVec<QuadGeometry> quadGeometry(Q);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, Q, 4096), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const auto& q = quadNodes[i];
            quadGeometry[i].area = 0.5 * cross(P[q[2]] - P[q[0]], P[q[3]] - P[q[1]]);
            for (int k = 0; k < 4; ++k) quadGeometry[i].edge[k] = norm(P[q[(k + 1) % 4]] - P[q[k]]);
        }
    });
    // Per hex of T, the sum of its corners, and a bound on every coordinate
    // involved: enough to settle the sign test below without the exact
    // centroid for all but a few nodes.
    BigVec<Vec3> cornerSum(T.size());
    tbb::enumerable_thread_specific<double> maxCoordinate(0.0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, T.size(), 4096), [&](const auto& r) {
        double& m = maxCoordinate.local();
        for (std::size_t t = r.begin(); t != r.end(); ++t) {
            Vec3 c{0, 0, 0};
            for (Index u : hexAtT(static_cast<Index>(t))) {
                c = c + P[u];
                m = std::max({m, std::abs(P[u][0]), std::abs(P[u][1]), std::abs(P[u][2])});
            }
            cornerSum[t] = c;
        }
    });
    const double B = maxCoordinate.combine([](double a, double b) { return std::max(a, b); });
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, C, 1024), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const Index s = copySlot[i];
            const Index v = res.copyOf[i];
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
            Vec3 dir = len > 0 ? (-1.0 / len) * normal : Vec3{0, 0, 0};
            // The centroid from the per-hex sums (another order of the same
            // n terms) is within about 2 n u B per coordinate of the one
            // summed corner by corner (u = 2^-53, B the largest coordinate),
            // so where the sign test passes by the margin 16 (n + 8) u B it
            // passes with the corner-by-corner sum too; elsewhere (about
            // 0.5% of the copies of ch2bet) that sum is made and decides.
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
                    for (Index u : hexAtT(*it)) c = c + P[u];
            }
            const Vec3 toCentre = (1.0 / n) * c - P[v];
            if (dot(dir, toCentre) <= 0) {
                const double l = norm(toCentre);
                dir = l > 0 ? (1.0 / l) * toCentre : Vec3{0, 0, 0};
            }
            push[i] = (opt.inset * edgeSum / edgeCount) * dir;
        }
    });

    release(quadGeometry);
    release(cornerSum);

    // Apply: copies, shrink-set hexes take them, one new hex per boundary quad.
    reserveHuge(mesh.nodes, N + C);
    reserveHuge(mesh.nodeClass, N + C);
    mesh.nodes.resize(N + C);
    mesh.nodeClass.resize(N + C, NodeClass{});
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, C, 4096), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) mesh.nodes[N + i] = mesh.nodes[res.copyOf[i]] + push[i];
    });
    // Only the hexes of T hold candidate nodes, so only they can hold a
    // split node (tHex follows: the copy-step rounds read it).
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, T.size(), 4096), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            for (int k = 0; k < 8; ++k) {
                const Index s = tSlot[i][k];
                const Index c = s == kNone ? kNone : copyOfSlot(s);
                if (c != kNone) tHex[i][k] = NI + c;
            }
            mesh.hexes[static_cast<std::size_t>(S[static_cast<std::size_t>(T[i])])] = tHex[i];
        }
    });
    reserveHuge(mesh.hexes, H + Q);
    reserveHuge(mesh.material, H + Q);
    mesh.hexes.resize(H + Q);
    mesh.material.resize(H + Q);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, Q, 4096), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const auto& q = quadNodes[i];
            const auto& qs = quadSlots[i];
            mesh.hexes[H + i] = {NI + copyOfSlot(qs[0]), NI + copyOfSlot(qs[1]), NI + copyOfSlot(qs[2]),
                                 NI + copyOfSlot(qs[3]), q[0], q[1], q[2], q[3]};
            mesh.material[H + i] = mesh.material[faces[i].first];
        }
    });
    release(tSlot);
    release(faces);
    release(quadNodes);
    release(quadSlots);

    // Shorten the inward step of copies where a hex around them inverted.
    // The hexes watched: position i < |T| is the shrink-set hex T[i] (when
    // it holds a copy), position |T| + q the new hex of quad q.
    const std::size_t W = T.size() + Q;
    auto watchHex = [&](std::size_t i) -> const Hex& {
        return i < T.size() ? tHex[i] : mesh.hexes[H + (i - T.size())];
    };
    // Each round, every inverted hex around a copy that moved asks how many
    // more halvings of its copies' steps (all together, up to maxHalvings) make
    // it valid; a copy takes the most any of its hexes asks for, and the hexes
    // around the copies that moved are checked again. A hex that no step length
    // can fix (a shrink-set hex inverted before the split, or a sheet hex on a
    // surface quad that folds against its copies' steps) asks for the shortest
    // step at once. This settles in a few rounds over the few hexes involved,
    // where halving once per round re-checked every hex maxHalvings times.
    const int maxK = std::max(0, opt.maxHalvings);
    BigVec<int> halvings(C, 0), want(C, 0);
    struct Watch {
        std::uint8_t bad = 0, hopeless = 0, ask = 0;
        std::uint16_t next = 0;  // the round that checks it again (a copy of it moved): nothing to clear between rounds
    };
    BigVec<Watch> watch(W);
    auto place = [&](std::size_t c, int k) {
        return mesh.nodes[res.copyOf[c]] + std::ldexp(1.0, -k) * push[c];
    };
    BigVec<Index> active;  // the dirty positions (round 0 checks every hex with a copy)
    for (int round = 0; round <= maxK; ++round) {
        if (round > 0) active = keepWhere(W, [&](std::size_t i) { return watch[i].next == round; });
        const std::size_t A = round == 0 ? W : active.size();
        auto position = [&](std::size_t j) { return round == 0 ? j : static_cast<std::size_t>(active[j]); };
        std::atomic<std::size_t> triggers{0};
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, A, 1024), [&](const auto& r) {
            std::size_t t = 0;
            for (std::size_t j = r.begin(); j != r.end(); ++j) {
                // The corners are scattered over the node array: fetch the
                // hex a few positions ahead and its corners a few less.
                if (j + 16 < r.end()) prefetch(&watchHex(position(j + 16)));
                if (j + 8 < r.end())
                    for (Index v : watchHex(position(j + 8)))
                        prefetch(&mesh.nodes[static_cast<std::size_t>(v)]);
                const std::size_t i = position(j);
                watch[i].ask = 0;
                const Hex& hx = watchHex(i);
                if (round == 0 && std::none_of(hx.begin(), hx.end(), [&](Index v) { return v >= NI; })) continue;
                const Vec3* x[8];
                for (int c = 0; c < 8; ++c) x[c] = &mesh.nodes[static_cast<std::size_t>(hx[c])];
                watch[i].bad = !jacobianPositive(x);
                if (!watch[i].bad) continue;
                Vec3 moved[8];  // corners of a trial shape
                const Vec3* y[8];
                if (round == 0) {
                    // Shrink-set hex: its shape with the copies back on their
                    // nodes. Sheet hex: its shape with the copies a hair inside
                    // (each corner's sign there is that of the surface quad's
                    // corner normal against the copy's step, whatever the step's
                    // length, so halving cannot help if it is not positive).
                    const bool sheetHex = i >= T.size();
                    for (int c = 0; c < 8; ++c) {
                        y[c] = x[c];
                        if (hx[c] >= NI) {
                            const std::size_t cc = static_cast<std::size_t>(hx[c] - NI);
                            moved[c] = mesh.nodes[res.copyOf[cc]];
                            if (sheetHex) moved[c] = moved[c] + 1e-3 * push[cc];
                            y[c] = &moved[c];
                        }
                    }
                    watch[i].hopeless = !jacobianPositive(y);
                }
                if (watch[i].hopeless) {  // no length helps: the shortest at once
                    watch[i].ask = static_cast<std::uint8_t>(maxK);
                    ++t;
                    continue;
                }
                int k = 1;
                for (; k < maxK; ++k) {
                    for (int c = 0; c < 8; ++c) {
                        y[c] = x[c];
                        if (hx[c] >= NI) {
                            const std::size_t cc = static_cast<std::size_t>(hx[c] - NI);
                            moved[c] = place(cc, std::min(maxK, halvings[cc] + k));
                            y[c] = &moved[c];
                        }
                    }
                    if (jacobianPositive(y)) break;
                }
                watch[i].ask = static_cast<std::uint8_t>(k);
                ++t;
            }
            triggers += t;
        });
        if (triggers == 0 || round == maxK) break;
        // A copy wants the most any of its asking hexes asks for (a
        // maximum: the same in any order), then takes it.
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, A, 4096), [&](const auto& r) {
            for (std::size_t j = r.begin(); j != r.end(); ++j)
                if (const std::size_t i = position(j); watch[i].ask)
                    for (Index v : watchHex(i))
                        if (v >= NI) {
                            std::atomic_ref<int> w(want[static_cast<std::size_t>(v - NI)]);
                            int cur = w.load(std::memory_order_relaxed);
                            while (cur < watch[i].ask && !w.compare_exchange_weak(cur, watch[i].ask, std::memory_order_relaxed)) {
                            }
                        }
        });
        const BigVec<Index> touched = keepWhere(C, [&](std::size_t c) { return want[c] != 0; });
        BigVec<std::uint8_t> didMove(touched.size(), 0);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, touched.size(), 1024), [&](const auto& r) {
            for (std::size_t j = r.begin(); j != r.end(); ++j) {
                const std::size_t c = static_cast<std::size_t>(touched[j]);
                const int k = std::min(maxK, halvings[c] + want[c]);
                want[c] = 0;
                if (k != halvings[c]) {
                    halvings[c] = k;
                    mesh.nodes[N + c] = place(c, k);
                    didMove[j] = 1;
                }
            }
        });
        const BigVec<Index> moved = keepWhere(touched.size(), [&](std::size_t j) { return didMove[j] != 0; });
        if (moved.empty()) break;
        // The hexes around the copies that moved are checked next round.
        const auto next = static_cast<std::uint16_t>(round + 1);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, moved.size(), 1024), [&](const auto& r) {
            for (std::size_t j = r.begin(); j != r.end(); ++j) {
                const Index s = copySlot[static_cast<std::size_t>(touched[static_cast<std::size_t>(moved[j])])];
                for (const Index* it = nodeT.begin(s); it != nodeT.end(s); ++it)
                    std::atomic_ref<std::uint16_t>(watch[static_cast<std::size_t>(*it)].next).store(next, std::memory_order_relaxed);
                for (const Index* it = around.begin(s); it != around.end(s); ++it)
                    std::atomic_ref<std::uint16_t>(watch[T.size() + static_cast<std::size_t>(*it / 4)].next)
                        .store(next, std::memory_order_relaxed);
            }
        });
    }
    res.invertedAtStart = static_cast<std::size_t>(
        std::count_if(watch.begin(), watch.end(), [](const Watch& w) { return w.bad == 1; }));
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
