// select(): from a loaded volume to one implicit field per material.
#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <openvdb/tree/LeafManager.h>

#include "DenseGrid.hpp"
#include "RawVolume.hpp"
#include "ReaderPlugins.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/SettingError.hpp"
#include "isohex/imaging/Selection.hpp"

namespace isohex::imaging {
namespace {

std::int64_t countBelowZero(const std::vector<float>& v) {
    return tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, v.size(), 1 << 16), std::int64_t(0),
        [&](const tbb::blocked_range<std::size_t>& r, std::int64_t n) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) n += v[i] < 0.0f;
            return n;
        },
        std::plus<>());
}

std::string describeVolume(const Volume& v) {
    return v.source.empty() ? std::string("the volume") : v.source;
}

// How many values of a dense volume (LayoutXYZ, z fastest) fill regions: at
// least 64 voxels of the value, a quarter of them with the same value at their
// +x, +y and +z neighbours. Zero when a value is not a whole number.
struct ValueRegions {
    int filling = 0;  // values that fill regions
    int valuesAboveIso = 0, valuesBelowIso = 0;  // among those filling regions, 0 left out
    double restInRegions = 0;  // the share of voxels not of the commonest value whose value fills regions
};

ValueRegions valueRegions(const std::vector<float>& v, const openvdb::Coord& dim, double iso) {
    ValueRegions out;
    const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
    if (lo == v.end() || !(*hi - *lo < float(1 << 16))) return out;  // not a label map's range
    const std::size_t ny = std::size_t(dim.y()), nz = std::size_t(dim.z()), nx = std::size_t(dim.x());
    const float base = *lo;
    using Counts = std::vector<std::int64_t>;  // per value: voxels, then voxels like their neighbours
    const std::size_t span = std::size_t(*hi - base) + 1;
    auto counts = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, nx), Counts(),
        [&](const tbb::blocked_range<std::size_t>& r, Counts c) {
            if (c.empty()) c.assign(2 * span + 1, 0);
            for (std::size_t x = r.begin(); x != r.end(); ++x)
                for (std::size_t y = 0; y < ny; ++y)
                    for (std::size_t z = 0; z < nz; ++z) {
                        const std::size_t i = (x * ny + y) * nz + z;
                        const float a = v[i];
                        if (a != std::floor(a)) c[2 * span] = 1;  // not whole numbers
                        if (c[2 * span]) continue;
                        const std::size_t k = std::size_t(a - base);
                        ++c[2 * k];
                        c[2 * k + 1] += x + 1 < nx && y + 1 < ny && z + 1 < nz && v[i + ny * nz] == a &&
                                        v[i + nz] == a && v[i + 1] == a;
                    }
            return c;
        },
        [](Counts a, const Counts& b) {
            if (a.empty()) return b;
            if (b.empty()) return a;
            for (std::size_t k = 0; k < a.size(); ++k) a[k] += b[k];
            a.back() = a.back() || b.back();
            return a;
        });
    if (counts.empty() || counts.back()) return out;
    std::size_t commonest = 0;
    for (std::size_t k = 0; k < span; ++k)
        if (counts[2 * k] > counts[2 * commonest]) commonest = k;
    std::int64_t rest = 0, restInRegions = 0;  // voxels of values other than the commonest
    for (std::size_t k = 0; k < span; ++k) {
        const std::int64_t n = counts[2 * k], alike = counts[2 * k + 1];
        const bool fills = n >= 64 && 4 * alike >= n;
        if (k != commonest) {
            rest += n;
            restInRegions += fills ? n : 0;
        }
        if (!fills) continue;
        ++out.filling;
        if (double(base) + double(k) == 0.0) continue;  // the background
        const bool above = double(base) + double(k) > iso;
        (above ? out.valuesAboveIso : out.valuesBelowIso) += 1;
    }
    out.restInRegions = rest > 0 ? double(restInRegions) / double(rest) : 0.0;
    return out;
}

// Refuses a label map read as a scan with Otsu's threshold, which splits its
// labels by their numbers (the JHU white-matter atlas at 13.97: labels 14-48
// one solid, 1-13 left out). In a segmentation every label fills a region
// (JHU: 41 of its 49 values); in a scan noise and smooth edges make
// neighbours differ, so only the background and a saturated value do
// (ch2bet: 1; the phantoms' clipped ramps: 2). A threshold between two
// values is a label map's, with one label and the background, and stands.
// A CT can have three (padding outside the field of view, air clipped at
// -1024, metal clipped at the top), but its tissue is noise: so nearly all
// voxels off the background must hold values that fill regions, as every
// voxel of a segmentation does (JHU: 99%).
void refuseLabelsAsIntensity(const std::string& src, const std::vector<float>& values, const openvdb::Coord& dim,
                             double iso) {
    const ValueRegions r = valueRegions(values, dim, iso);
    if (r.filling < 3 || r.restInRegions < 0.9) return;
    std::ostringstream m;
    m.precision(7);
    m << src << ": this looks like a label map, not a scan: its values are whole numbers and " << r.filling
      << " of them fill regions (in a scan, noise and smooth edges make neighbouring voxels differ). Otsu's "
         "threshold "
      << iso << " would mesh the " << r.valuesAboveIso << " label(s) above it as one solid and leave out the "
      << r.valuesBelowIso << " below it. Mesh its labels with ";
    throw SettingError({m.str(), Setting::Labels, " (or choose some with ", Setting::Label, "), or give ",
                        Setting::Iso, " to threshold it on purpose."});
}

Selection selectIntensity(const Volume& vol, const SelectOptions& o) {
    Selection sel;
    const std::string src = describeVolume(vol);
    if (o.progress) o.progress("select", 0.0);
    std::vector<float> values = detail::gridToDense(*vol.intensity, vol.box);
    bool insideBelow = o.insideBelow;

    std::optional<double> iso = o.iso;
    if (iso && o.isoFromOtsu) refuseLabelsAsIntensity(src, values, vol.box.dim(), *iso);
    if (iso) {
        if (!std::isfinite(*iso) || !(*iso > vol.minValue && *iso < vol.maxValue)) {
            std::ostringstream m;
            m.precision(7);
            if (vol.levelSet) {  // a triangle surface's signed distance, not intensities
                m << src << ": iso value " << *iso << " is outside the signed distance's range [" << vol.minValue
                  << ", " << vol.maxValue << "] around the surface, so no level crosses it. Omit ";
                throw SettingError({m.str(), Setting::Iso,
                                    " to mesh the surface itself (distance 0), or give an offset strictly inside that "
                                    "range."});
            }
            m << src << ": iso value " << *iso << " is outside the data range [" << vol.minValue << ", "
              << vol.maxValue << "], so no surface crosses it. Choose an iso value "
              << "strictly inside that range, or omit it to let Otsu's method choose.";
            throw Error(m.str());
        }
    } else if (vol.levelSet) {
        iso = 0.0;  // a signed distance: the zero set, negative inside
        insideBelow = true;
    } else {
        try {
            if (vol.nonFiniteVoxels > 0) {
                std::vector<float> finite;
                finite.reserve(values.size());
                for (float v : values)
                    if (std::isfinite(v)) finite.push_back(v);
                iso = detail::itkReaders().otsuThreshold(finite);
            } else {
                iso = detail::itkReaders().otsuThreshold(values);
            }
        } catch (const Error& e) {
            throw Error(src + ": " + e.what());  // which scan, in a batch
        }
        // ITK's calculator gives NaN for values near the float limits (+-3e38)
        if (!std::isfinite(*iso)) {
            std::ostringstream m;
            m << src << ": Otsu's method found no threshold for values from " << vol.minValue << " to "
              << vol.maxValue << "; give the iso value yourself.";
            throw Error(m.str());
        }
        refuseLabelsAsIntensity(src, values, vol.box.dim(), *iso);
        sel.isoFromOtsu = true;
    }

    // NaN / Inf voxels (kept only with nanAsOutside) become the most outside
    // value so that neither smoothing nor interpolation turns them inside.
    const float outsideValue = float(insideBelow ? vol.maxValue : vol.minValue);
    if (vol.nonFiniteVoxels > 0) {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, values.size()), [&](const auto& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i)
                if (!std::isfinite(values[i])) values[i] = outsideValue;
        });
    }
    if (o.smoothSigma > 0.0) gaussianSmooth(values, vol.box.dim(), vol.spacing, o.smoothSigma);

    const float isoF = float(*iso);
    const float sign = insideBelow ? 1.0f : -1.0f;  // field = sign * (v - iso) < 0 inside
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, values.size()), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) values[i] = sign * (values[i] - isoF);
    });
    const std::int64_t inside = countBelowZero(values);
    if (inside == 0) {
        std::ostringstream m;
        m << src << ": no voxel is " << (insideBelow ? "below" : "above") << " the iso value "
          << *iso << (o.smoothSigma > 0 ? " after smoothing" : "")
          << ", so the selection is empty. Choose another iso value"
          << (o.smoothSigma > 0 ? " or less smoothing." : ".");
        throw Error(m.str());
    }
    // Outside the scanned box the field keeps the value of the most outside voxel.
    const float background = std::max(sign * (outsideValue - isoF), 1e-6f);
    auto grid = detail::denseToGrid(values.data(), vol.box, background,
                                    vol.intensity->transform().copy());
    grid->setName("material_1");
    sel.materials.push_back({1, inside, ImplicitField(grid, o.interpolation)});
    sel.iso = iso;
    sel.insideBelow = insideBelow;
    if (o.progress) o.progress("select", 1.0);
    return sel;
}

struct LabelStat {
    std::int64_t voxels = 0;
    openvdb::CoordBBox box;  // default-constructed = empty
};
using LabelStatMap = std::map<std::int32_t, LabelStat>;
struct LabelStats {
    LabelStatMap perLabel;
    // Face-neighbour voxel pairs with both labels non-zero, and how many of
    // them hold different labels: in a segmentation most neighbours share
    // their label, in an intensity scan most differ.
    std::int64_t pairs = 0;
    std::int64_t differing = 0;
};

LabelStats labelStatistics(const openvdb::Int32Grid& grid) {
    using TreeT = openvdb::Int32Tree;
    openvdb::tree::LeafManager<const TreeT> leaves(grid.tree());
    // Counts and boxes merge the same way in any order: thread-count independent.
    struct Op {
        const TreeT* tree;
        LabelStatMap stats;
        std::int64_t pairs = 0, differing = 0;
        explicit Op(const TreeT& t) : tree(&t) {}
        Op(const Op& o, tbb::split) : tree(o.tree) {}
        void operator()(const TreeT::LeafNodeType& leaf, std::size_t) {
            openvdb::tree::ValueAccessor<const TreeT, false> acc(*tree);
            for (auto it = leaf.cbeginValueOn(); it; ++it) {
                const std::int32_t l = *it;
                auto& s = stats[l];
                ++s.voxels;
                const openvdb::Coord c = it.getCoord();
                s.box.expand(c);
                if (l == 0) continue;
                for (int a = 0; a < 3; ++a) {
                    openvdb::Coord n = c;
                    n[a] += 1;
                    const std::int32_t m = acc.getValue(n);
                    if (m == 0) continue;
                    ++pairs;
                    differing += m != l;
                }
            }
        }
        void join(const Op& other) {
            for (const auto& [label, s] : other.stats) {
                auto& mine = stats[label];
                mine.voxels += s.voxels;
                mine.box.expand(s.box);
            }
            pairs += other.pairs;
            differing += other.differing;
        }
    } op(grid.tree());
    leaves.reduce(op);
    // Active tiles (possible in a .vdb label grid) are counted whole.
    for (auto it = grid.tree().cbeginValueOn(); it; ++it) {
        if (it.isVoxelValue()) continue;
        auto& s = op.stats[*it];
        s.voxels += static_cast<std::int64_t>(it.getVoxelCount());
        openvdb::CoordBBox b;
        it.getBoundingBox(b);
        s.box.expand(b);
    }
    return {std::move(op.stats), op.pairs, op.differing};
}

// Refuses an intensity scan read as a label map. One stored as integers (an
// 8-bit MRI, say) makes every grey value a material of scattered single
// voxels: the repair then spends minutes and fails, or the mesh is hundreds
// of specks. In a segmentation only voxels on a label's boundary differ from
// a neighbour (a brain atlas: 5.5% of pairs; an 8-bit MRI: 88%); the
// threshold leaves room for labels a few voxels wide.
void refuseIntensityAsLabels(const std::string& src, const LabelStats& all) {
    if (!(all.pairs >= 1000 && 2 * all.differing > all.pairs)) return;
    const LabelStatMap& stats = all.perLabel;
    std::ostringstream m;
    m << src << ": this does not look like a label map: " << (stats.size() - stats.count(0))
      << " non-zero values, and " << std::lround(100.0 * double(all.differing) / double(all.pairs))
      << "% of neighbouring non-zero voxels hold different values (in a segmentation most "
         "neighbours share their label). Read as labels, every value would become a material "
         "of scattered voxels. Mesh it as a scan (without ";
    throw SettingError({m.str(), Setting::Labels, " or ", Setting::Label, "; choose the surface with ", Setting::Iso,
                        "), or give the segmentation's label map instead."});
}

// The non-zero labels present with their voxel counts (the first 40), for
// the message about labels that are not.
std::string presentLabels(const LabelStatMap& stats) {
    std::ostringstream m;
    int shown = 0;
    for (const auto& [label, s] : stats) {
        if (label == 0) continue;
        if (shown++ == 40) {
            m << " ...";
            break;
        }
        m << (shown > 1 ? ", " : "") << label << " (" << s.voxels << " voxels)";
    }
    return shown ? m.str() : std::string("none");
}

// Each label meshed becomes the material id of its hexes, and a negative
// material id means the outside (surfaces are named by material pairs): a
// negative label would be written as ids isohex's own readers refuse. So
// negative labels are refused when they would be meshed; voxels of a
// negative label not selected are background like any other unselected one.
void refuseNegativeLabels(const std::string& src, const LabelStatMap& stats, const std::vector<std::int32_t>& wanted,
                          bool listed) {
    std::ostringstream m;
    int shown = 0;
    for (std::int32_t l : wanted) {
        if (l >= 0) break;  // ascending
        m << (shown++ ? ", " : "") << l << " (" << stats.at(l).voxels << " voxels)";
    }
    if (shown == 0) return;
    throw SettingError({src + ": label" + (shown > 1 ? "s " : " ") + m.str() + (shown > 1 ? " are" : " is") +
                            " negative, and each meshed label becomes a material id, which must be 0 or more "
                            "(negative ids mean the outside). " +
                            (listed ? std::string("Remove the negative labels from ") : std::string("Select the labels to mesh with ")),
                        Setting::Label, listed ? std::string(", or renumber the label map.") : std::string(" (positive ones), or renumber the label map.")});
}

// The labels to mesh, ascending and each once: those asked for, or every
// non-zero label present. Throws on label 0, on negative labels, on labels
// not present, and when there is nothing to mesh.
std::vector<std::int32_t> wantedLabels(const std::string& src, const LabelStatMap& stats, const SelectOptions& o) {
    std::vector<std::int32_t> wanted;
    if (o.labels.empty()) {
        for (const auto& [label, s] : stats)
            if (label != 0) wanted.push_back(label);
        refuseNegativeLabels(src, stats, wanted, false);
        if (wanted.empty()) {
            throw Error(src + ": every voxel is label 0 (background), so there is nothing to mesh. "
                        "Check that this is the right label map.");
        }
        return wanted;
    }
    std::vector<std::int32_t> missing;
    for (std::int32_t l : o.labels) {
        if (l == 0) {
            throw Error(src + ": label 0 is the background and cannot be meshed as a material; "
                        "remove it from the label list.");
        }
        if (!stats.count(l))
            missing.push_back(l);
        else if (std::find(wanted.begin(), wanted.end(), l) == wanted.end())
            wanted.push_back(l);
    }
    if (!missing.empty()) {
        std::ostringstream m;
        m << src << ": label" << (missing.size() > 1 ? "s " : " ");
        for (std::size_t i = 0; i < missing.size(); ++i) m << (i ? ", " : "") << missing[i];
        m << (missing.size() > 1 ? " are" : " is") << " not in the label map"
          << (wanted.empty() ? ", so the selection is empty" : "")
          << ". Labels present: " << presentLabels(stats) << ".";
        throw Error(m.str());
    }
    std::sort(wanted.begin(), wanted.end());
    refuseNegativeLabels(src, stats, wanted, true);
    return wanted;
}

// The wanted labels with at least the min-label-voxels option's voxels; the
// others go to `dropped`. Throws when none is left.
std::vector<std::int32_t> keptLabels(const std::string& src, const LabelStatMap& stats,
                                     const std::vector<std::int32_t>& wanted, const SelectOptions& o,
                                     std::vector<DroppedLabel>& dropped) {
    std::vector<std::int32_t> kept;
    for (std::int32_t l : wanted) {
        const auto& s = stats.at(l);
        if (s.voxels < o.minLabelVoxels)
            dropped.push_back({l, s.voxels});
        else
            kept.push_back(l);
    }
    if (kept.empty()) {
        std::ostringstream m;
        m << src << ": every selected label has fewer than " << o.minLabelVoxels
          << " voxels (the min-label-voxels option), so the selection is empty:";
        for (const auto& d : dropped) m << " " << d.label << " (" << d.voxels << ")";
        m << ". Lower min-label-voxels or select larger labels.";
        throw Error(m.str());
    }
    return kept;
}

// One label's field over its box padded for the blur and the zero crossing:
// 0.5 minus its (smoothed) indicator, negative inside. Throws if smoothing
// leaves no voxel inside.
openvdb::FloatGrid::Ptr labelField(const Volume& vol, std::int32_t label, const openvdb::CoordBBox& box,
                                   const SelectOptions& o, const std::string& src) {
    const Vec3& sp = vol.spacing;
    openvdb::CoordBBox region = box;
    openvdb::Coord pad;
    for (int a = 0; a < 3; ++a) pad[a] = 2 + (o.smoothSigma > 0 ? int(std::ceil(3.0 * o.smoothSigma / sp[a])) : 0);
    region.min() -= pad;
    region.max() += pad;
    const openvdb::Coord d = region.dim();
    std::vector<float> indicator(static_cast<std::size_t>(region.volume()), 0.0f);
    tbb::parallel_for(tbb::blocked_range<int>(0, d.z()), [&](const tbb::blocked_range<int>& r) {
        // One read-only accessor per task; nothing is written through it.
        openvdb::tree::ValueAccessor<const openvdb::Int32Tree, false> acc(vol.labels->tree());
        for (int z = r.begin(); z != r.end(); ++z)
            for (int y = 0; y < d.y(); ++y) {
                std::size_t i = static_cast<std::size_t>(d.x()) * (y + std::size_t(d.y()) * z);
                for (int x = 0; x < d.x(); ++x, ++i) {
                    const openvdb::Coord c = region.min().offsetBy(x, y, z);
                    indicator[i] = acc.getValue(c) == label ? 1.0f : 0.0f;
                }
            }
    });
    if (o.smoothSigma > 0.0) gaussianSmooth(indicator, d, sp, o.smoothSigma);
    for (auto& v : indicator) v = 0.5f - v;
    if (countBelowZero(indicator) == 0) {
        throw Error(src + ": label " + std::to_string(label) + " vanishes after Gaussian smoothing with sigma " +
                    std::to_string(o.smoothSigma) + "; use less smoothing or drop the label.");
    }
    auto grid = detail::denseToGrid(indicator.data(), region, 0.5f, vol.labels->transform().copy());
    grid->setName("label_" + std::to_string(label));
    return grid;
}

Selection selectLabels(const Volume& vol, const SelectOptions& o) {
    Selection sel;
    const std::string src = describeVolume(vol);
    const LabelStats all = labelStatistics(*vol.labels);
    const LabelStatMap& stats = all.perLabel;
    refuseIntensityAsLabels(src, all);
    const std::vector<std::int32_t> kept = keptLabels(src, stats, wantedLabels(src, stats, o), o, sel.dropped);
    for (std::size_t n = 0; n < kept.size(); ++n) {
        const std::int32_t label = kept[n];
        if (o.progress) o.progress("select", double(n) / double(kept.size()));
        const LabelStat& s = stats.at(label);
        sel.materials.push_back({label, s.voxels, ImplicitField(labelField(vol, label, s.box, o, src), o.interpolation)});
    }
    if (o.progress) o.progress("select", 1.0);
    return sel;
}

}  // namespace

Selection select(const Volume& volume, const SelectOptions& options) {
    if (options.smoothSigma < 0.0 || !std::isfinite(options.smoothSigma)) {
        throw Error("smoothing sigma " + std::to_string(options.smoothSigma) +
                    " is not valid; give a non-negative value in millimetres (0 = no smoothing).");
    }
    if (volume.kind == VolumeKind::Labels) {
        if (options.iso) {
            throw Error(describeVolume(volume) + ": an iso value was given but the volume was "
                        "loaded as a label map; select labels instead, or load it without the "
                        "labels option to threshold intensities.");
        }
        return selectLabels(volume, options);
    }
    if (!options.labels.empty()) {
        throw Error(describeVolume(volume) + ": labels were selected but the volume was loaded "
                    "as intensities; load it with the labels option.");
    }
    return selectIntensity(volume, options);
}

void gaussianSmooth(std::vector<float>& values, const openvdb::Coord& dims, const Vec3& spacing,
                    double sigma) {
    if (!(sigma > 0.0)) return;
    const std::size_t n[3] = {std::size_t(dims.x()), std::size_t(dims.y()), std::size_t(dims.z())};
    const std::size_t stride[3] = {1, n[0], n[0] * n[1]};
    for (int axis = 0; axis < 3; ++axis) {
        const double s = sigma / spacing[axis];  // in voxels along this axis
        if (s < 0.05 || n[axis] < 2) continue;
        const int radius = std::max(1, int(std::ceil(3.0 * s)));
        std::vector<double> kernel(2 * radius + 1);
        double sum = 0.0;
        for (int k = -radius; k <= radius; ++k) sum += kernel[k + radius] = std::exp(-0.5 * k * k / (s * s));
        for (auto& w : kernel) w /= sum;

        const int other1 = (axis + 1) % 3, other2 = (axis + 2) % 3;
        const std::size_t lines = n[other1] * n[other2];
        const std::size_t len = n[axis];
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, lines), [&](const auto& r) {
            std::vector<float> line(len);
            for (std::size_t l = r.begin(); l != r.end(); ++l) {
                const std::size_t a = l % n[other1], b = l / n[other1];
                const std::size_t base = a * stride[other1] + b * stride[other2];
                for (std::size_t i = 0; i < len; ++i) line[i] = values[base + i * stride[axis]];
                for (std::size_t i = 0; i < len; ++i) {
                    double acc = 0.0;
                    for (int k = -radius; k <= radius; ++k) {
                        const std::ptrdiff_t j = std::clamp<std::ptrdiff_t>(
                            std::ptrdiff_t(i) + k, 0, std::ptrdiff_t(len) - 1);
                        acc += kernel[k + radius] * line[j];
                    }
                    values[base + i * stride[axis]] = float(acc);
                }
            }
        });
    }
}

}  // namespace isohex::imaging
