// Sampling the material labels of a grid from a Domain.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "isohex/octree/Grid.hpp"
#include "isohex/octree/Labels.hpp"

namespace isohex::octree {

Labels sampleLabels(const Domain& domain, const Grid& grid, bool keepBorder) {
    Labels l;
    l.grid = grid;
    l.material.assign(grid.size(), 0);
    const auto [nx, ny, nz] = grid.dims;
    tbb::parallel_for(tbb::blocked_range<int>(0, nz), [&](const auto& r) {
        for (int k = r.begin(); k != r.end(); ++k)
            for (int j = 0; j < ny; ++j)
                for (int i = 0; i < nx; ++i) {
                    const bool border = i == 0 || j == 0 || k == 0 || i == nx - 1 || j == ny - 1 || k == nz - 1;
                    if (border && !keepBorder) continue;
                    l.material[grid.index(i, j, k)] = domain.materialAt(grid.point(i, j, k));
                }
    });
    return l;
}

}  // namespace isohex::octree
