// summarizeScan(): the whole-scan facts of a split scan's part, read slab by
// slab through ITK's region reads (LoadOptions::region).
#include "isohex/imaging/ScanSummary.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <functional>
#include <limits>

#include "FormatChecks.hpp"
#include "RawVolume.hpp"
#include "ReaderPlugins.hpp"

namespace isohex::imaging {
namespace {

namespace fs = std::filesystem;

// A file ITK's reader may stream, by its name (uncompressed NIfTI-1 and
// MetaImage; ITK's NRRD reader reads the whole file for any region); the
// reads say whether it did (a compressed MetaImage does not). Not .nii.gz:
// ITK reads a region of it by decompressing from the file's start, so the
// passes would decompress the file once per slab.
bool mayStream(const fs::path& path) {
    std::string name = path.filename().string();
    for (auto& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    auto endsWith = [&](const std::string& e) {
        return name.size() >= e.size() && name.compare(name.size() - e.size(), e.size(), e) == 0;
    };
    std::error_code ec;
    if (fs::is_directory(path, ec) || detail::niftiFileVersion(path) == 2) return false;  // ITK reads no NIfTI-2
    return endsWith(".nii") || endsWith(".mha") || endsWith(".mhd");
}

// Slab by slab along z through the file; false when a read was not a
// streamed region read (the reader read the whole file).
class SlabReader {
public:
    SlabReader(const fs::path& path, const LoadOptions& load, std::int64_t voxelsPerRead)
        : path_(path), load_(load), perRead_(voxelsPerRead) {
        load_.progress = {};
        load_.labels = false;
    }

    // Calls visit(raw) for every slab; false (and stops) at a read that was not streamed.
    bool forEach(ScanSummary& sum, const std::function<void(const detail::RawVolume&)>& visit) {
        int z = 0, slices = 1;
        do {
            load_.region = openvdb::CoordBBox(openvdb::Coord(0, 0, z),
                                              openvdb::Coord(kWide, kWide, z + slices - 1));
            const detail::RawVolume raw = detail::itkReaders().readImageFile(path_, load_);
            ++sum.slabReads;
            if (!raw.streamed) return false;
            if (z == 0) {
                sum.dims = openvdb::Coord(int(raw.fileDims[0]), int(raw.fileDims[1]), int(raw.fileDims[2]));
                sum.format = raw.format;
                sum.pixelType = raw.pixelType;
                sum.origin = raw.origin;
                sum.spacing = raw.spacing;
                sum.direction = raw.direction;
            }
            visit(raw);
            z += slices;
            const std::int64_t slice = std::max<std::int64_t>(raw.dims[0] * raw.dims[1], 1);
            slices = static_cast<int>(std::clamp<std::int64_t>(perRead_ / slice, 1, sum.dims.z()));
        } while (z < sum.dims.z());
        ++sum.passes;
        return true;
    }

private:
    static constexpr int kWide = std::numeric_limits<int>::max() / 2;  // clipped to the file
    fs::path path_;
    LoadOptions load_;
    std::int64_t perRead_;
};

// Pass: the finite value range; false at a non-finite voxel.
bool valueRange(SlabReader& slabs, ScanSummary& sum) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    bool finite = true;
    if (!slabs.forEach(sum, [&](const detail::RawVolume& raw) {
            for (float v : raw.values) {
                if (!std::isfinite(v)) finite = false;
                lo = std::min(lo, double(v));
                hi = std::max(hi, double(v));
            }
        }))
        return false;
    sum.minValue = lo;
    sum.maxValue = hi;
    return finite && hi > lo;
}

// Pass: Otsu's threshold from the histogram otsuThresholdItk fills.
bool otsuIso(SlabReader& slabs, ScanSummary& sum) {
    const double vmin = sum.minValue, vmax = sum.maxValue;
    const double scale = detail::kOtsuBins / (vmax - vmin);
    std::vector<std::uint64_t> counts(detail::kOtsuBins, 0);
    if (!slabs.forEach(sum, [&](const detail::RawVolume& raw) {
            for (float v : raw.values) ++counts[std::min(detail::kOtsuBins - 1, static_cast<int>((v - vmin) * scale))];
        }))
        return false;
    sum.iso = detail::itkReaders().otsuFromHistogram(counts, vmin, vmax);
    sum.isoFromOtsu = true;
    return std::isfinite(sum.iso);
}

// Pass: the selected voxels' box and counts per layer.
bool selectedVoxels(SlabReader& slabs, ScanSummary& sum) {
    const float isoF = float(sum.iso);
    const float sign = sum.insideBelow ? 1.0f : -1.0f;
    for (int a = 0; a < 3; ++a) sum.perLayer[a].assign(static_cast<std::size_t>(std::max(sum.dims[a], 0)), 0);
    if (!slabs.forEach(sum, [&](const detail::RawVolume& raw) {
            if (sum.perLayer[0].empty())  // dims known after the first read
                for (int a = 0; a < 3; ++a) sum.perLayer[a].assign(static_cast<std::size_t>(sum.dims[a]), 0);
            std::size_t i = 0;
            for (std::int64_t z = 0; z < raw.dims[2]; ++z)
                for (std::int64_t y = 0; y < raw.dims[1]; ++y)
                    for (std::int64_t x = 0; x < raw.dims[0]; ++x, ++i) {
                        if (!(sign * (raw.values[i] - isoF) < 0.0f)) continue;
                        const openvdb::Coord c(int(x + raw.start[0]), int(y + raw.start[1]), int(z + raw.start[2]));
                        sum.solid.expand(c);
                        ++sum.selectedVoxels;
                        for (int a = 0; a < 3; ++a) ++sum.perLayer[a][static_cast<std::size_t>(c[a])];
                    }
        }))
        return false;
    return sum.selectedVoxels > 0;
}

}  // namespace

std::optional<ScanSummary> summarizeScan(const fs::path& path, const LoadOptions& load, const SelectOptions& select,
                                         std::int64_t voxelsPerRead) {
    if (load.labels || load.nanAsOutside || select.smoothSigma != 0.0 || !select.labels.empty() || !mayStream(path))
        return std::nullopt;
    // ITK's NIfTI reader zeroes non-finite voxels in a region read: such a
    // scan is read whole, which refuses it as every run does.
    if (detail::niftiHasNonFinite(path.string())) return std::nullopt;
    ScanSummary sum;
    sum.insideBelow = select.insideBelow;
    SlabReader slabs(path, load, voxelsPerRead);
    if (!valueRange(slabs, sum)) return std::nullopt;
    if (select.iso) {
        if (!(std::isfinite(*select.iso) && *select.iso > sum.minValue && *select.iso < sum.maxValue))
            return std::nullopt;
        sum.iso = *select.iso;
    } else if (!otsuIso(slabs, sum)) {
        return std::nullopt;
    }
    if (!selectedVoxels(slabs, sum)) return std::nullopt;
    return sum;
}

}  // namespace isohex::imaging
