#pragma once
// A closed triangle surface meshed like a scan: recognising a surface file,
// the surface's own element size, and its signed-distance level set as a
// Volume whose iso value is 0.
#include <string>

#include "isohex/imaging/Surface.hpp"
#include "isohex/imaging/Volume.hpp"

namespace isohex::imaging {

// Whether the path names a triangle surface: .stl, .obj, .ply or .off, in any case.
bool isSurfaceFile(const std::string& path);

// Mean length of the triangles' edges (each triangle's three, shared edges
// counted once per triangle); the default element size for a surface.
// Throws isohex::Error when the surface has no triangles.
double meanEdgeLength(const TriangleSurface& surface);

// The surface's signed-distance level set (surfaceToLevelSet with
// `options`) as an intensity Volume, negative inside, its box the active
// voxels grown by 2, its range the level set's band; `source` names it.
Volume surfaceToVolume(TriangleSurface surface, const LevelSetOptions& options, const std::string& source);

}  // namespace isohex::imaging
