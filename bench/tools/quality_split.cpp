// quality_split MESH [REPEATS]: times the parts of a mesh job's "quality"
// stage on a written mesh, as cli/Jobs.cpp runs them:
//   topology_all    buildTopology(mesh) (every part: the optimiser's and pillow's kind)
//   validate        validate(mesh) (node rows and surface quads only)
//   measures        computeQuality + summarize (per-hex measures, histogram)
// Prints one JSON object with the fastest repeat of each part, and the
// topology's counts and a hash of its arrays (quads, hexQuads, edges,
// hexEdges, quadHexesAll) so that two builds can be checked to agree.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "isohex/core/MeshIO.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/core/Validate.hpp"

namespace {
using Clock = std::chrono::steady_clock;

// FNV-1a over the bytes of a vector of trivially copyable values.
template <class T>
std::uint64_t hashOf(const std::vector<T>& v, std::uint64_t h = 1469598103934665603ull) {
    const auto* p = reinterpret_cast<const unsigned char*>(v.data());
    for (std::size_t i = 0; i < v.size() * sizeof(T); ++i) h = (h ^ p[i]) * 1099511628211ull;
    return h;
}

template <class F>
double fastest(int repeats, F&& f) {
    double best = 1e300;
    for (int r = 0; r < repeats; ++r) {
        const auto t0 = Clock::now();
        f();
        best = std::min(best, std::chrono::duration<double>(Clock::now() - t0).count());
    }
    return best;
}
}  // namespace

int main(int argc, char** argv) {
    if (argc < 2) {
        std::fprintf(stderr, "usage: quality_split MESH [REPEATS]\n");
        return 2;
    }
    const int repeats = argc > 2 ? std::max(1, std::atoi(argv[2])) : 3;
    const isohex::HexMesh mesh = isohex::io::read(argv[1]);
    std::size_t quads = 0, edges = 0, boundary = 0;
    std::uint64_t hash = 0;
    bool ok = false;
    const double topo = fastest(repeats, [&] {
        const isohex::Topology t = isohex::buildTopology(mesh);
        quads = t.quads.size();
        edges = t.edges.size();
        boundary = t.boundaryQuads.size();
        hash = hashOf(t.quadHexesAll.items,
                      hashOf(t.quadHexesAll.offsets,
                             hashOf(t.hexEdges, hashOf(t.edges, hashOf(t.hexQuads, hashOf(t.quads))))));
    });
    const double valid = fastest(repeats, [&] { ok = isohex::validate(mesh).ok(); });
    const double measures = fastest(repeats, [&] {
        const isohex::HexQuality q = isohex::computeQuality(mesh);
        (void)isohex::summarize(mesh, q);
    });
    std::printf("{\"hexes\": %zu, \"quads\": %zu, \"edges\": %zu, \"boundary_quads\": %zu, \"valid\": %s, "
                "\"topology_hash\": \"%016llx\", \"topology_all_s\": %.4f, \"validate_s\": %.4f, \"measures_s\": %.4f}\n",
                mesh.hexes.size(), quads, edges, boundary, ok ? "true" : "false", static_cast<unsigned long long>(hash), topo, valid, measures);
    return 0;
}
