#include "isohex/pipeline/MemoryEstimate.hpp"

#include <cmath>
#include <sstream>

#include <sys/resource.h>
#include <unistd.h>

#include "Format.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/SettingError.hpp"
#include "isohex/octree/Grid.hpp"

namespace isohex::pipeline {

double meshPeakBytes(double already, double hexes, double gridPoints) {
    constexpr double bytesPerHex = 220.0;  // the fitted 199 (bench/RESULTS.md) plus 10%
    constexpr double fixedBytes = 16.0 * 1024 * 1024;  // the stages' own working set on inputs of a few thousand hexes
    return already + fixedBytes + hexes * bytesPerHex + gridPoints * 8.0;
}

MeshMemoryEstimate estimateMeshMemory(const imaging::Volume& vol, const imaging::Selection& sel,
                                      const octree::Grid& g, const MeshSettings& settings) {
    MeshMemoryEstimate e;
    const auto sp = g.spacing();
    const double element = sp[0] * sp[1] * sp[2];
    const double voxel = vol.spacing[0] * vol.spacing[1] * vol.spacing[2];
    double voxels = 0;
    for (const auto& m : sel.materials) voxels += double(m.voxels);
    e.hexes = voxels * voxel / element;
    if (settings.meshExterior) e.hexes = double(g.size());
    if (settings.pillow) e.hexes *= 7.0 / 6.0;
    struct rusage ru {};
    getrusage(RUSAGE_SELF, &ru);
    e.already = double(ru.ru_maxrss) * 1024.0;
    e.need = meshPeakBytes(e.already, e.hexes, double(g.size()));
    e.budget = settings.load.maxMemoryMB * 1024.0 * 1024.0;
    e.budgetGiven = settings.load.maxMemoryMB > 0.0;
    if (!e.budgetGiven) e.budget = 0.8 * double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGE_SIZE));
    return e;
}

void checkMeshMemory(const std::string& input, const imaging::Volume& vol, const imaging::Selection& sel,
                     const octree::Grid& g, const MeshSettings& settings) {
    const MeshMemoryEstimate e = estimateMeshMemory(vol, sel, g, settings);
    if (e.need <= e.budget) return;
    const auto sp = g.spacing();
    const double element = sp[0] * sp[1] * sp[2];
    std::ostringstream m;
    m.precision(3);
    m << input << ": at this element size (" << shortNumber(sp[0]) << " x " << shortNumber(sp[1]) << " x "
      << shortNumber(sp[2]) << " world units; the input's voxels are " << shortNumber(vol.spacing[0]) << " x "
      << shortNumber(vol.spacing[1]) << " x " << shortNumber(vol.spacing[2]) << ") the mesh would have about "
      << e.hexes / 1e6 << " million hexes and need about " << e.need / double(1 << 30) << " GiB (estimate), more than ";
    std::vector<MessagePart> parts{m.str()};
    if (e.budgetGiven) parts.insert(parts.end(), {"the ", Setting::MaxMemory, " budget"});
    else parts.push_back("80% of this machine's memory");
    std::ostringstream b;
    b.precision(3);
    b << " (" << e.budget / double(1 << 30) << " GiB). ";
    parts.push_back(b.str());
    // The element size whose mesh would fit, rounded up to two digits (none
    // when what is loaded already takes most of the budget).
    if (e.already < 0.9 * e.budget) {
        double fit = std::cbrt((e.need - e.already) / (e.budget - e.already)) * std::cbrt(element);
        const double unit = std::pow(10.0, std::floor(std::log10(fit)) - 1);
        parts.insert(parts.end(), {"Use a ", Setting::Size,
                                   " of at least " + shortNumber(std::ceil(fit / unit) * unit) + ", or raise"});
    } else {
        std::ostringstream a;
        a.precision(3);
        a << "The input alone takes " << e.already / double(1 << 30) << " GiB; raise";
        parts.push_back(a.str());
    }
    parts.insert(parts.end(), {" ", Setting::MaxMemory, " if the machine has the memory."});
    throw SettingError(std::move(parts));
}

}  // namespace isohex::pipeline
