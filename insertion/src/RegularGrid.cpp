#include "isohex/insertion/RegularGrid.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include "isohex/core/Error.hpp"
#include "isohex/core/SettingError.hpp"

namespace isohex::insertion {

HexMesh regularGrid(const Vec3& lo, const Vec3& hi, double size, double margin) {
    if (!(size > 0)) throw Error("the element size must be positive");
    std::array<long long, 3> n{};
    Vec3 origin{};
    for (int i = 0; i < 3; ++i) {
        const double ext = (hi[i] - lo[i]) * (1.0 + 2.0 * margin);
        n[i] = std::max<long long>(1, static_cast<long long>(std::ceil(ext / size)));
        origin[i] = 0.5 * (lo[i] + hi[i]) - 0.5 * static_cast<double>(n[i]) * size;
    }
    const long long nodes = (n[0] + 1) * (n[1] + 1) * (n[2] + 1);
    if (nodes > std::numeric_limits<Index>::max() / 4)
        throw SettingError({"a grid of " + std::to_string(n[0]) + " x " + std::to_string(n[1]) + " x " +
                                std::to_string(n[2]) + " elements is too large; choose a larger ",
                            Setting::Size});
    HexMesh m;
    m.nodes.reserve(static_cast<std::size_t>(nodes));
    for (long long k = 0; k <= n[2]; ++k)
        for (long long j = 0; j <= n[1]; ++j)
            for (long long i = 0; i <= n[0]; ++i)
                m.addNode({origin[0] + static_cast<double>(i) * size, origin[1] + static_cast<double>(j) * size,
                           origin[2] + static_cast<double>(k) * size});
    auto id = [&](long long i, long long j, long long k) {
        return static_cast<Index>(i + (n[0] + 1) * (j + (n[1] + 1) * k));
    };
    for (long long k = 0; k < n[2]; ++k)
        for (long long j = 0; j < n[1]; ++j)
            for (long long i = 0; i < n[0]; ++i)
                m.addHex({id(i, j, k), id(i + 1, j, k), id(i + 1, j + 1, k), id(i, j + 1, k), id(i, j, k + 1),
                          id(i + 1, j, k + 1), id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)},
                         1);
    return m;
}

}  // namespace isohex::insertion
