#pragma once
// The sizing image of the adaptive mesher (--size-image): a scalar image of
// element sizes in world units (mm), on any grid, read by imaging's readers.
//
// A level-1 cell's limit is the smallest size over the cell: the image's
// voxels whose centres fall inside it and the voxel holding its centre (so a
// cell smaller than a voxel still sees one); coarser cells take the minimum
// of their level-1 cells (SizeLimits.hpp). The minimum, not the value at the
// centre, because a size asked for anywhere in a cell must not be hidden by
// a coarse cell whose centre misses it. Outside the image, and at voxels
// that are not a positive finite number (a map's background), nothing is
// asked.
#include <string>

#include "isohex/imaging/Volume.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/SizeLimits.hpp"

namespace isohex::pipeline {

// The image at `path` as an intensity volume; throws a SettingError naming
// the size image and the file when it cannot be read or holds no size.
imaging::Volume loadSizeImage(const std::string& path, const imaging::LoadOptions& base);

// The limits of the level-1 cells of a tree over `grid` from `sizes`.
octree::CellSizeLimits sizeImageLimits(const imaging::Volume& sizes, const octree::Grid& grid);

}  // namespace isohex::pipeline
