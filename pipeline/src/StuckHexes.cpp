#include "isohex/pipeline/StuckHexes.hpp"

#include <algorithm>
#include <utility>

#include "Format.hpp"
#include "isohex/core/Parallel.hpp"
#include "isohex/core/Quality.hpp"

namespace isohex::pipeline {

std::vector<Index> invertedHexes(const HexMesh& mesh) {
    return parallel::collectSorted<Index>(mesh.hexCount(), 1 << 14, [&](const auto& range, std::vector<Index>& out) {
        for (std::size_t h = range.begin(); h != range.end(); ++h)
            if (!(minJacobianDeterminant(hexCoords(mesh, static_cast<Index>(h))) > 0)) out.push_back(static_cast<Index>(h));
    });
}

bool Stuck::betterThan(const Stuck& o, double floor) const {
    if (inverted.size() != o.inverted.size()) return inverted.size() < o.inverted.size();
    if (!(floor > 0)) return false;
    if (flat.size() != o.flat.size()) return flat.size() < o.flat.size() && minValid >= o.minValid;
    return minValid > o.minValid;
}

Stuck stuckHexes(const HexMesh& mesh, double floor) {
    Stuck s;
    s.inverted = invertedHexes(mesh);
    const std::vector<double> sj = scaledJacobians(mesh);
    std::vector<char> inv(sj.size(), 0);
    for (Index h : s.inverted) inv[static_cast<std::size_t>(h)] = 1;
    std::vector<std::pair<double, Index>> low;
    for (std::size_t h = 0; h < sj.size(); ++h) {
        // scaledJacobian's value above 1 marks a degenerate hex: as flat as can be
        const double v = scaledJacobianCollapsed(sj[h]) ? 0.0 : sj[h];
        s.min = std::min(s.min, v);
        if (inv[h]) continue;
        s.minValid = std::min(s.minValid, v);
        if (v < floor) low.emplace_back(v, static_cast<Index>(h));
    }
    std::sort(low.begin(), low.end());
    for (const auto& [v, h] : low) s.flat.push_back(h);
    return s;
}

std::string warnInverted(StageSink& sink, const HexMesh& mesh, const std::vector<Index>& left,
                         std::size_t afterUntangling, const std::string& more, bool fixedBoundary, bool byCompare) {
    if (left.empty()) return {};
    const Vec3 c = hexCentre(mesh, left.front());
    std::string msg = std::to_string(left.size()) + " hex(es) stay inverted after optimisation";
    if (left.size() != afterUntangling) msg += " (" + std::to_string(afterUntangling) + " after untangling)";
    msg += "; first at (" + std::to_string(c[0]) + ", " + std::to_string(c[1]) + ", " + std::to_string(c[2]) + ")" +
           more +
           (!fixedBoundary ? "; another --size may avoid them"
            : byCompare ? "; compare fixes every surface node once the surface quads are smoothed (the seed's "
                          "protocol), and hexes on a folded surface can only be untangled by moving those: "
                          "--move-boundary lets them move"
                        : "; --fix-boundary keeps every surface node where extraction put it, and hexes on a folded "
                          "surface can only be untangled by moving those: drop it, or try another --size");
    sink.note("warning", msg);
    return msg;
}

// Not inverted, but nearly flat: a solver accepts them and its accuracy
// suffers there, so they are named rather than left silently.
std::string warnFlat(StageSink& sink, const HexMesh& mesh, const Stuck& stuck, double floor, std::size_t meshedAgain,
                     int maxRetries) {
    if (stuck.flat.empty()) return {};
    const Vec3 c = hexCentre(mesh, stuck.flat.front());
    std::string msg = std::to_string(stuck.flat.size()) + " hex(es) stay nearly flat (scaled Jacobian below " +
                      shortNumber(floor) + ", lowest " + shortNumber(stuck.minValid) + " at (" + shortNumber(c[0]) +
                      ", " + shortNumber(c[1]) + ", " + shortNumber(c[2]) + "))" +
                      (meshedAgain == 0 ? "" : " after meshing again " + std::to_string(meshedAgain) + " time(s)") +
                      (maxRetries == 0 ? "; --retries would try grid edits there, or another --size may avoid them"
                                       : "; another --size may avoid them");
    sink.note("warning", msg);
    return msg;
}

}  // namespace isohex::pipeline
