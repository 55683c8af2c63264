#include "isohex/imaging/SurfaceVolume.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>

#include "isohex/core/Error.hpp"

namespace isohex::imaging {

bool isSurfaceFile(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    return ext == ".stl" || ext == ".obj" || ext == ".ply" || ext == ".off";
}

double meanEdgeLength(const TriangleSurface& s) {
    double sum = 0;
    std::size_t n = 0;
    for (const auto& t : s.triangles)
        for (int i = 0; i < 3; ++i) {
            const Vec3& a = s.vertices[t[i]];
            const Vec3& b = s.vertices[t[(i + 1) % 3]];
            sum += std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
            ++n;
        }
    if (n == 0) throw Error(s.source + ": the surface has no triangles");
    return sum / static_cast<double>(n);
}

Volume surfaceToVolume(TriangleSurface surface, const LevelSetOptions& options, const std::string& source) {
    SurfaceLevelSet ls = surfaceToLevelSet(std::move(surface), options);
    Volume vol;
    vol.kind = VolumeKind::Intensity;
    vol.intensity = ls.grid;
    vol.box = ls.grid->evalActiveVoxelBoundingBox();
    vol.box.expand(2);
    vol.spacing = {ls.voxelSize, ls.voxelSize, ls.voxelSize};
    const openvdb::Vec3d o = ls.grid->transform().indexToWorld(openvdb::Vec3d(0, 0, 0));
    vol.origin = {o[0], o[1], o[2]};
    vol.minValue = -ls.grid->background();
    vol.maxValue = ls.grid->background();
    vol.levelSet = true;
    vol.source = source;
    vol.format = "triangle surface";
    vol.pixelType = "float32 (signed distance)";
    return vol;
}

}  // namespace isohex::imaging
