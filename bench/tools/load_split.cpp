// load_split VOLUME [REPEATS] [--labels]: times isohex's own loadVolume() and
// splits it with the stage marks the loader reports through LoadOptions::progress:
//   header  start -> "read" 0   (opening, header and size checks)
//   read    "read" 0 -> 1       (ITK's ImageFileReader::Update: decompression, decoding)
//   convert "read" 1 -> "grid" 0 (ITK image -> dense buffer, value range)
//   grid    "grid" 0 -> 1       (dense buffer -> sparse OpenVDB grid with its transform)
// Prints one JSON object: every repeat, and the fastest repeat of each part.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "isohex/imaging/Volume.hpp"

namespace {
using Clock = std::chrono::steady_clock;
double secs(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double>(b - a).count(); }
}  // namespace

int main(int argc, char** argv) {
    if (argc < 2) {
        std::fprintf(stderr, "usage: load_split VOLUME [REPEATS] [--labels]\n");
        return 2;
    }
    const std::string path = argv[1];
    int repeats = 3;
    bool labels = false;
    for (int i = 2; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--labels") labels = true;
        else repeats = std::max(1, std::atoi(argv[i]));
    }
    struct Run { double header, read, convert, grid, total; };
    std::vector<Run> runs;
    long long active = 0;
    for (int r = 0; r < repeats; ++r) {
        Clock::time_point t0 = Clock::now(), read0 = t0, read1 = t0, grid0 = t0, grid1 = t0;
        isohex::imaging::LoadOptions opt;
        opt.labels = labels;
        opt.progress = [&](std::string_view stage, double f) {
            const auto now = Clock::now();
            if (stage == "read" && f == 0.0) read0 = now;
            if (stage == "read" && f == 1.0) read1 = now;
            if (stage == "grid" && f == 0.0) grid0 = now;
            if (stage == "grid" && f == 1.0) grid1 = now;
        };
        isohex::imaging::Volume v = isohex::imaging::loadVolume(path, opt);
        const auto t1 = Clock::now();
        active = v.intensity ? static_cast<long long>(v.intensity->activeVoxelCount())
                             : static_cast<long long>(v.labels->activeVoxelCount());
        runs.push_back({secs(t0, read0), secs(read0, read1), secs(read1, grid0), secs(grid0, grid1), secs(t0, t1)});
    }
    auto best = [&](double Run::*m) {
        double b = runs[0].*m;
        for (const auto& r : runs) b = std::min(b, r.*m);
        return b;
    };
    std::printf("{\"file\": \"%s\", \"repeats\": %d, \"active_voxels\": %lld,\n \"runs\": [", path.c_str(), repeats, active);
    for (std::size_t i = 0; i < runs.size(); ++i)
        std::printf("%s{\"header\": %.4f, \"read\": %.4f, \"convert\": %.4f, \"grid\": %.4f, \"total\": %.4f}",
                    i ? ", " : "", runs[i].header, runs[i].read, runs[i].convert, runs[i].grid, runs[i].total);
    std::printf("],\n \"best\": {\"header\": %.4f, \"read\": %.4f, \"convert\": %.4f, \"grid\": %.4f, \"total\": %.4f}}\n",
                best(&Run::header), best(&Run::read), best(&Run::convert), best(&Run::grid), best(&Run::total));
    return 0;
}
