#include "isohex/pipeline/SelectionDomain.hpp"

#include <array>
#include <cmath>
#include <string>

#include "isohex/core/Error.hpp"

namespace isohex::pipeline {

SelectionDomain::SelectionDomain(std::shared_ptr<const imaging::Volume> v, std::shared_ptr<const imaging::Selection> s)
    : volume_(std::move(v)), selection_(std::move(s)) {
    for (std::size_t i = 0; i < selection_->materials.size(); ++i) slot_[selection_->materials[i].id] = i;
    // A flag per label from the smallest selected id to the largest, for
    // the per-voxel "is this label selected" of unionValue and labelAt
    // (8 map lookups per call were 7% of a label mesh's time).
    if (!slot_.empty()) {
        const std::int64_t lo = slot_.begin()->first, hi = slot_.rbegin()->first;
        if (hi - lo < (std::int64_t{1} << 20)) {
            firstLabel_ = static_cast<std::int32_t>(lo);
            selectedFlag_.assign(static_cast<std::size_t>(hi - lo + 1), 0);
            for (const auto& [id, i] : slot_) selectedFlag_[static_cast<std::size_t>(id - lo)] = 1;
        }
    }
}

std::int32_t SelectionDomain::materialAt(const Vec3& x) const {
    if (volume_->kind == imaging::VolumeKind::Labels) return labelAt(x);
    const auto& m = selection_->materials.front();
    return m.field.value(x) < 0 ? m.id : 0;
}

double SelectionDomain::value(std::int32_t material, const Vec3& x, Vec3* gradient) const {
    const imaging::ImplicitField& f = field(material);
    if (!gradient) return f.value(x);
    return f.valueAndGradient(x, *gradient);
}

double SelectionDomain::unionValue(const Vec3& x, Vec3* gradient) const {
    if (volume_->kind != imaging::VolumeKind::Labels) return value(selection_->materials.front().id, x, gradient);
    const auto [c0, t] = voxelCell(x);
    openvdb::tree::ValueAccessor<const openvdb::Int32Tree, false> acc(volume_->labels->tree());
    double in = 0;
    openvdb::Vec3d d(0, 0, 0);  // derivative of `in` in index space
    for (int c = 0; c < 8; ++c) {
        const int o[3] = {c & 1, c >> 1 & 1, c >> 2 & 1};
        if (!isSelected(acc.getValue(c0.offsetBy(o[0], o[1], o[2])))) continue;
        double w[3], dw[3];
        for (int a = 0; a < 3; ++a) {
            w[a] = o[a] ? t[a] : 1.0 - t[a];
            dw[a] = o[a] ? 1.0 : -1.0;
        }
        in += w[0] * w[1] * w[2];
        d[0] += dw[0] * w[1] * w[2];
        d[1] += w[0] * dw[1] * w[2];
        d[2] += w[0] * w[1] * dw[2];
    }
    if (gradient) {
        const openvdb::Vec3d gw = volume_->labels->transform().baseMap()->applyIJT(-d);
        *gradient = {gw[0], gw[1], gw[2]};
    }
    return 0.5 - in;
}

std::int32_t SelectionDomain::materialOtherThan(std::int32_t material, const Vec3& x) const {
    std::int32_t best = 0;
    double bestValue = 0;
    for (const auto& m : selection_->materials) {
        if (m.id == material) continue;
        const double v = m.field.value(x);
        if (v < bestValue) {
            bestValue = v;
            best = m.id;
        }
    }
    return best;
}

const imaging::ImplicitField& SelectionDomain::field(std::int32_t material) const {
    // the octree asks for every sample: skip the map for a single material
    if (selection_->materials.size() == 1 && selection_->materials.front().id == material)
        return selection_->materials.front().field;
    const auto it = slot_.find(material);
    if (it == slot_.end()) throw Error("internal: no field for material " + std::to_string(material));
    return selection_->materials[it->second].field;
}

SelectionDomain::VoxelCell SelectionDomain::voxelCell(const Vec3& x) const {
    const openvdb::Vec3d u = volume_->labels->transform().worldToIndex(openvdb::Vec3d(x[0], x[1], x[2]));
    const openvdb::Coord c0(static_cast<int>(std::floor(u[0])), static_cast<int>(std::floor(u[1])),
                            static_cast<int>(std::floor(u[2])));
    return {c0, u - c0.asVec3d()};
}

// At a voxel centre the largest weight is the voxel's own label; between
// voxels it agrees with the fields (0.5 minus the indicator), so every grid
// edge between two materials has the surface between them on it (or at an
// end). The nearest voxel alone can disagree: at a corner shared by eight
// voxels it picks one of them even where most of the eight are another
// label, and the edges from there had no crossing.
std::int32_t SelectionDomain::labelAt(const Vec3& x) const {
    const auto [c0, t] = voxelCell(x);
    openvdb::tree::ValueAccessor<const openvdb::Int32Tree, false> acc(volume_->labels->tree());
    auto selected = [&](std::int32_t label) { return isSelected(label) ? label : 0; };
    std::array<std::int32_t, 8> label{};
    std::array<double, 8> weight{};
    int n = 0;
    for (int c = 0; c < 8; ++c) {
        const int o[3] = {c & 1, c >> 1 & 1, c >> 2 & 1};
        const double w = (o[0] ? t[0] : 1.0 - t[0]) * (o[1] ? t[1] : 1.0 - t[1]) * (o[2] ? t[2] : 1.0 - t[2]);
        const std::int32_t l = selected(acc.getValue(c0.offsetBy(o[0], o[1], o[2])));
        int s = 0;
        while (s < n && label[s] != l) ++s;
        if (s == n) {
            label[n] = l;
            weight[n++] = 0;
        }
        weight[s] += w;
    }
    const std::int32_t nearest = selected(
        acc.getValue(volume_->labels->transform().worldToIndexCellCentered(openvdb::Vec3d(x[0], x[1], x[2]))));
    int best = 0;
    for (int s = 1; s < n; ++s)
        if (weight[s] > weight[best] || (weight[s] == weight[best] && label[s] == nearest)) best = s;
    return label[best];
}

bool SelectionDomain::isSelected(std::int32_t label) const {
    if (selectedFlag_.empty()) return slot_.count(label) != 0;
    const std::int64_t i = std::int64_t{label} - firstLabel_;
    return i >= 0 && i < static_cast<std::int64_t>(selectedFlag_.size()) && selectedFlag_[static_cast<std::size_t>(i)];
}

}  // namespace isohex::pipeline
