#include "isohex/pipeline/SizeImage.hpp"

#include <cmath>
#include <limits>

#include <Eigen/Dense>

#include "isohex/core/SettingError.hpp"

namespace isohex::pipeline {

namespace {

bool isSize(float v) { return std::isfinite(v) && v > 0; }

}  // namespace

imaging::Volume loadSizeImage(const std::string& path, const imaging::LoadOptions& base) {
    imaging::LoadOptions o;
    o.nanAsOutside = true;  // NaN voxels ask for nothing
    o.maxMemoryMB = base.maxMemoryMB;
    o.allowDataOutside = base.allowDataOutside;
    imaging::Volume v;
    try {
        v = imaging::loadVolume(path, o);
    } catch (const Error& e) {
        throw SettingError({Setting::SizeImage, std::string(" could not be read: ") + e.what()});
    }
    if (!(v.maxValue > 0))
        throw SettingError({Setting::SizeImage, " " + path +
                                                    " holds no positive size (element sizes in mm, 0 or NaN where "
                                                    "nothing is asked); give an image of sizes"});
    return v;
}

octree::CellSizeLimits sizeImageLimits(const imaging::Volume& sizes, const octree::Grid& grid) {
    octree::CellSizeLimits out = octree::noSizeLimits(grid.dims);
    const auto& d = out.dims;
    const auto& xf = sizes.transform();
    auto acc = sizes.intensity->getConstAccessor();
    auto lower = [&](std::size_t c, float v) {
        if (isSize(v) && v < out.limit[c]) out.limit[c] = v;
    };
    // the voxel holding each level-1 cell's centre (grid point 3m + 1)
    for (int k = 0; k < d[2]; ++k)
        for (int j = 0; j < d[1]; ++j)
            for (int i = 0; i < d[0]; ++i) {
                const Vec3 x = grid.point(3 * i + 1, 3 * j + 1, 3 * k + 1);
                const openvdb::Coord ijk = xf.worldToIndexCellCentered(openvdb::Vec3d(x[0], x[1], x[2]));
                if (sizes.box.isInside(ijk)) lower(out.index(i, j, k), acc.getValue(ijk));
            }
    // every voxel, in the cell its centre falls in (points [3m, 3m + 3) cover grid coordinates [3m - 1/2, 3m + 5/2))
    Eigen::Matrix3d axes;
    for (int c = 0; c < 3; ++c) axes.col(c) = Eigen::Vector3d(grid.axes[c][0], grid.axes[c][1], grid.axes[c][2]);
    const Eigen::Matrix3d toGrid = axes.inverse();
    for (auto it = sizes.intensity->cbeginValueOn(); it; ++it) {
        if (!isSize(*it)) continue;
        openvdb::CoordBBox b;
        it.getBoundingBox(b);
        for (auto v = b.begin(); v; ++v) {
            const openvdb::Vec3d w = xf.indexToWorld(*v);
            const Eigen::Vector3d u =
                toGrid * Eigen::Vector3d(w[0] - grid.origin[0], w[1] - grid.origin[1], w[2] - grid.origin[2]);
            std::array<int, 3> cell;
            bool inside = true;
            for (int c = 0; c < 3; ++c) {
                cell[c] = static_cast<int>(std::floor((u[c] + 0.5) / 3));
                inside = inside && cell[c] >= 0 && cell[c] < d[c];
            }
            if (inside) lower(out.index(cell[0], cell[1], cell[2]), *it);
        }
    }
    return out;
}

}  // namespace isohex::pipeline
