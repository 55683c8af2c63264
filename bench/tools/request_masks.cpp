// request_masks INPUT OUTDIR [--size S] [--level L] [--iso V] [--labels] [--keep-largest] [--no-thickness]:
// the adaptive mesher's requests before the tree is closed (issue 37's lower bounds), as
// pipeline/src/AdaptiveContour.cpp and octree/src/AdaptiveSurface.cpp make them, for tools/request-bound.py:
// prepare() (load, select, grid, labels, repair), the top level (sizingTopLevel, then topLevelFor),
// the sizing requests (sizingRequests: thickness, the only one without sizing options) and the
// surface criterion (surfaceRequests). No criterion is re-implemented here.
//
// Writes OUTDIR/l1.mask in closure-cascade.py's read_level format: three int32 (level-1 cells per axis),
// then one byte per cell (x fastest): bit 0 surface request, bit 1 thickness request; then one byte per
// cell: its labelled grid points (0..27); then one byte per cell: 1 where its centre point is labelled
// (the label a coarse leaf's hex takes, AdaptiveHexes.hpp). OUTDIR/l2.mask: level-2 dims, then the
// level-2 request bits the same way (no other arrays). Prints one JSON object of counts.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "isohex/octree/RefinementTree.hpp"
#include "isohex/octree/RequestMasks.hpp"
#include "isohex/octree/SurfaceCoarsening.hpp"
#include "isohex/pipeline/Prepare.hpp"
#include "isohex/pipeline/Sizing.hpp"

namespace {

struct Quiet : isohex::pipeline::StageSink {
    void begin(std::string_view) override {}
    void progress(double) override {}
    void end(std::string_view s, double secs) override { std::fprintf(stderr, "  %.*s %.1f s\n", int(s.size()), s.data(), secs); }
    void note(std::string_view, const std::string& t) override { std::fprintf(stderr, "  note: %s\n", t.c_str()); }
};

void writeMask(const std::string& path, const std::array<int, 3>& dims, const std::vector<std::vector<std::uint8_t>>& arrays) {
    std::ofstream f(path, std::ios::binary);
    f.write(reinterpret_cast<const char*>(dims.data()), 12);
    for (const auto& a : arrays) f.write(reinterpret_cast<const char*>(a.data()), static_cast<std::streamsize>(a.size()));
    f.close();
    if (!f) throw std::runtime_error(path + ": cannot write (does its folder exist?)");
}

}  // namespace

namespace {

// The number an option takes, or an error naming the option.
double number(const std::string& option, const char* text) {
    char* end = nullptr;
    const double v = std::strtod(text, &end);
    if (end == text || *end != '\0' || !std::isfinite(v))
        throw std::runtime_error(option + " takes a number, not '" + text + "'");
    return v;
}

int run(int argc, char** argv);

}  // namespace

int main(int argc, char** argv) {
    try {
        return run(argc, argv);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "request_masks: %s\n", e.what());
        return 1;
    }
}

namespace {

int run(int argc, char** argv) {
    using namespace isohex;
    if (argc < 3) {
        std::fprintf(stderr, "usage: request_masks INPUT OUTDIR [--size S] [--level L] [--iso V] [--labels] [--keep-largest] [--no-thickness]\n");
        return 2;
    }
    const std::string input = argv[1], out = argv[2];
    pipeline::MeshSettings s;
    s.adaptive = true;
    for (int i = 3; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--size" && i + 1 < argc) s.size = number(a, argv[++i]);
        else if (a == "--level" && i + 1 < argc) s.level = static_cast<int>(number(a, argv[++i]));
        else if (a == "--iso" && i + 1 < argc) s.select.iso = number(a, argv[++i]);
        else if (a == "--labels") s.load.labels = true;
        else if (a == "--keep-largest") s.keepLargest = true;
        else if (a == "--no-thickness") s.thicknessRefinement = false;
        else { std::fprintf(stderr, "unknown argument %s\n", a.c_str()); return 2; }
    }
    std::filesystem::create_directories(out);
    const auto t0 = std::chrono::steady_clock::now();
    Quiet sink;
    const pipeline::Prepared p = pipeline::prepare(input, s, sink);
    const auto t1 = std::chrono::steady_clock::now();

    // As coarsenContour and contourAdaptive.
    pipeline::SizingFacts sf;
    const int maxLevel = pipeline::sizingTopLevel(p, s, sf);
    const octree::RequestMasks sizing = pipeline::sizingRequests(p, s, maxLevel, sf);
    const auto& points = p.labels.grid.dims;
    const int top = octree::topLevelFor(points, maxLevel);
    const octree::RequestMasks surface = octree::surfaceRequests(p.labels, top);
    const auto t2 = std::chrono::steady_clock::now();

    auto level = [](const octree::RequestMasks& m, int l) -> const std::vector<std::uint8_t>* {
        return static_cast<int>(m.size()) > l && !m[static_cast<std::size_t>(l)].empty() ? &m[static_cast<std::size_t>(l)] : nullptr;
    };
    std::size_t labelled = 0;
    for (const auto v : p.labels.material) labelled += v != 0;
    long long counts[3][3] = {};  // level 1..2: surface, thickness, union
    if (top < 2)
        std::fprintf(stderr, "request_masks: the tree has %d level(s) above the finest: %s not written\n", top,
                     top < 1 ? "l1.mask and l2.mask" : "l2.mask");
    for (int l = 1; l <= std::min(top, 2); ++l) {
        const auto dims = octree::levelDims(points, l);
        const std::size_t n = static_cast<std::size_t>(dims[0]) * dims[1] * dims[2];
        std::vector<std::uint8_t> bits(n, 0), count, centre;
        const auto* su = level(surface, l);
        const auto* th = level(sizing, l);
        for (std::size_t c = 0; c < n; ++c) {
            bits[c] = static_cast<std::uint8_t>((su && (*su)[c] ? 1 : 0) | (th && (*th)[c] ? 2 : 0));
            counts[l][0] += bits[c] & 1;
            counts[l][1] += (bits[c] >> 1) & 1;
            counts[l][2] += bits[c] != 0;
        }
        if (l == 1) {
            count.assign(n, 0);
            centre.assign(n, 0);
            for (int ck = 0; ck < dims[2]; ++ck)
                for (int cj = 0; cj < dims[1]; ++cj)
                    for (int ci = 0; ci < dims[0]; ++ci) {
                        const std::size_t c = (static_cast<std::size_t>(ck) * dims[1] + cj) * dims[0] + ci;
                        int k = 0;
                        for (int z = 0; z < 3; ++z)
                            for (int y = 0; y < 3; ++y)
                                for (int x = 0; x < 3; ++x) k += p.labels.at(3 * ci + x, 3 * cj + y, 3 * ck + z) != 0;
                        count[c] = static_cast<std::uint8_t>(k);
                        centre[c] = p.labels.at(3 * ci + 1, 3 * cj + 1, 3 * ck + 1) != 0;
                    }
            writeMask(out + "/l1.mask", dims, {bits, count, centre});
        } else {
            writeMask(out + "/l2.mask", dims, {bits});
        }
    }
    std::printf("{\"input\": \"%s\", \"points\": [%d, %d, %d], \"top\": %d, \"uniform_hexes\": %zu, "
                "\"step\": %.6g, \"l1\": {\"surface\": %lld, \"thickness\": %lld, \"union\": %lld}, "
                "\"l2\": {\"surface\": %lld, \"thickness\": %lld, \"union\": %lld}, "
                "\"facts_thickness_all_levels\": %zu, \"prepare_s\": %.1f, \"requests_s\": %.1f}\n",
                input.c_str(), points[0], points[1], points[2], top, labelled, pipeline::finestWidth(p.labels.grid),
                counts[1][0], counts[1][1], counts[1][2], counts[2][0], counts[2][1], counts[2][2], sf.thickness,
                std::chrono::duration<double>(t1 - t0).count(), std::chrono::duration<double>(t2 - t1).count());
    return 0;
}

}  // namespace
