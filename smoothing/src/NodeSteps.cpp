// The moves of one node the smoother makes: Newton on the inverse mean ratio
// (interior nodes), centroidal-area smoothing on a surface and sliding along
// a curve, and Newton on Knupp's untangling measure.
#include <cmath>

#include "Smoother.hpp"

namespace isohex::smoothing::detail {

namespace {

// A surface node this close to its projection (in local edge lengths) is on
// its surface.
constexpr double kOnSurface = 1e-3;

// With `terms` describing the node moved by `applied` from its original
// position: true if moving it by `trial` (from the original) instead leaves
// every corner that was positive at the original position positive.
bool keepsValidCornersValid(const CornerTerm* terms, std::size_t n, const Vector3& applied, const Vector3& trial) {
    for (std::size_t i = 0; i < n; ++i) {
        Matrix3 original = terms[i].A, moved = terms[i].A;
        displaceFrame(original, terms[i].role, -applied);
        displaceFrame(moved, terms[i].role, trial - applied);
        if (cornerDeterminant(original) > 0 && !(cornerDeterminant(moved) > 0)) return false;
    }
    return true;
}

}  // namespace

Smoother::Visit Smoother::interiorStep(Index v, std::vector<CornerTerm>& buf) const {
    Visit r;
    const std::size_t n = gatherTerms(v, buf, r);
    NodeObjective<InverseMeanRatio> objective(InverseMeanRatio{}, buf.data(), n);
    r.move = newtonDescent(objective, r.length, opt_.gradientTolerance * static_cast<double>(n) / r.length, opt_.newton);
    r.position = displaced(mesh_.nodes[static_cast<std::size_t>(v)], r.move.displacement);
    return r;
}

Smoother::Visit Smoother::untangleStep(Index v, std::vector<CornerTerm>& buf) const {
    Visit r;
    const std::size_t n = gatherTerms(v, buf, r);
    const double L = r.length;
    const double beta = opt_.untangleBeta * L * L * L;
    UntangleBeta metric{beta, 0.5 * beta};
    NodeObjective<UntangleBeta> objective(metric, buf.data(), n);
    // Nothing to do where Knupp's measure is already zero.
    if (objective.minDeterminant(Vector3::Zero()) >= beta) return r;
    NewtonOptions newton = opt_.newton;
    newton.maxIterations = 4;
    r.move = newtonDescent(objective, L, 1e-9 * static_cast<double>(n) * beta / L, newton);
    if (r.move.steps == 0) return r;
    // Knupp's measure may trade a deep inversion for a new shallow one; do not
    // let it: shorten the move until every corner that was valid stays valid.
    if (!guarded_) {
        r.position = displaced(mesh_.nodes[static_cast<std::size_t>(v)], r.move.displacement);
        return r;
    }
    const Vector3 full = r.move.displacement;
    Vector3 d = full;
    for (int k = 0; k < 8 && !keepsValidCornersValid(buf.data(), n, full, d); ++k) d *= 0.5;
    if (!keepsValidCornersValid(buf.data(), n, full, d)) {
        r.move.steps = 0;
        return r;
    }
    r.move.displacement = d;
    r.position = displaced(mesh_.nodes[static_cast<std::size_t>(v)], d);
    return r;
}

bool Smoother::surfaceFrame(std::size_t sv, Vector3& centroid, Vector3& normal) const {
    centroid.setZero();
    normal.setZero();
    Vector3 firstNormal = Vector3::Zero();
    double area = 0;
    for (const Index* q = nodeSurfaceQuads_.begin(sv); q != nodeSurfaceQuads_.end(sv); ++q) {
        const auto& qn = surfaceQuadNodes_[static_cast<std::size_t>(*q)];
        Vector3 p[4];
        for (int i = 0; i < 4; ++i) {
            const Vec3& y = mesh_.nodes[static_cast<std::size_t>(qn[i])];
            p[i] = Vector3(y[0], y[1], y[2]);
        }
        Vector3 an = (p[2] - p[0]).cross(p[3] - p[1]);  // twice the area vector of the quad
        const double a = 0.5 * an.norm();
        if (firstNormal.isZero()) firstNormal = an;
        else if (an.dot(firstNormal) < 0) an = -an;  // interface quads may face either way
        centroid += a * 0.25 * (p[0] + p[1] + p[2] + p[3]);
        normal += an;
        area += a;
    }
    if (!(area > 0) || !(normal.norm() > 0)) return false;
    centroid /= area;
    normal.normalize();
    return true;
}

// Untangling a surface node: Newton on Knupp's measure within the tangent
// plane, then back onto the surface; kept only if the measure went down.
Smoother::Visit Smoother::untangleSurfaceStep(Index v, std::vector<CornerTerm>& buf) const {
    Visit r;
    const auto sv = static_cast<std::size_t>(v);
    const std::size_t n = gatherTerms(v, buf, r);
    const double L = r.length;
    const double beta = opt_.untangleBeta * L * L * L;
    NodeObjective<UntangleBeta> objective(UntangleBeta{beta, 0.5 * beta}, buf.data(), n);
    if (objective.minDeterminant(Vector3::Zero()) >= beta) return r;
    Vector3 centroid, normal;
    if (!surfaceFrame(sv, centroid, normal)) return r;
    const double f0 = objective.value(Vector3::Zero());
    TangentPlaneObjective<NodeObjective<UntangleBeta>> tangent(objective, normal);
    NewtonOptions newton = opt_.newton;
    newton.maxIterations = 4;
    const NodeMove m = newtonDescent(tangent, L, 1e-9 * static_cast<double>(n) * beta / L, newton);
    if (m.steps == 0) return r;
    const Matrix3 P = Matrix3::Identity() - normal * normal.transpose();
    const Vector3 moved = P * m.displacement;  // what `objective` is now shifted by
    const Vec3& xv = mesh_.nodes[sv];
    const Vec3 y = projector_->project(mesh_.nodeClass[sv].id, displaced(xv, moved));
    const Vector3 d = offset(y, xv);
    if (!d.allFinite()) return r;
    const double f = objective.value(d - moved);
    if (!(f < f0) || (guarded_ && !keepsValidCornersValid(buf.data(), n, moved, d))) return r;
    r.move.before = f0;
    accept(r, d, f, y);
    return r;
}

// Centroidal-area smoothing restricted to the tangent plane, then projection
// back onto the surface; a move is taken only if every adjacent corner stays
// positive (and, by default, the node's mean-ratio objective does not rise).
Smoother::Visit Smoother::surfaceStep(Index v, std::vector<CornerTerm>& buf) const {
    Visit r;
    NodeMove& move = r.move;
    const std::size_t n = gatherTerms(v, buf, r);
    const double L = r.length;
    NodeObjective<InverseMeanRatio> objective(InverseMeanRatio{}, buf.data(), n);
    const double f0 = objective.value(Vector3::Zero());
    move.before = move.after = f0;
    if (!std::isfinite(f0)) return r;

    const auto sv = static_cast<std::size_t>(v);
    const Vec3& xv = mesh_.nodes[sv];
    const Vector3 x(xv[0], xv[1], xv[2]);
    Vector3 centroid, normal;
    if (!surfaceFrame(sv, centroid, normal)) return r;
    Vector3 delta = centroid - x;
    delta -= delta.dot(normal) * normal;
    const std::int32_t surface = mesh_.nodeClass[sv].id;
    // A node off its surface (a vertex contouring held back so that no hex
    // starts inverted) takes a valid move onto it even where its hexes get
    // worse: the surface comes first, as for curve nodes. Asked only when a
    // move is refused for that reason; once on the surface a node stays on it.
    int off = -1;  // unknown
    auto offSurface = [&] {
        if (!opt_.offSurfaceNodesOntoSurface) off = 0;
        if (off < 0) off = !(offset(projector_->project(surface, xv), xv).norm() <= kOnSurface * L);
        return off == 1;
    };
    if (delta.norm() > opt_.moveTolerance * L) {
        double omega = opt_.surfaceRelaxation;
        for (int k = 0; k <= opt_.surfaceHalvings; ++k, omega *= 0.5) {
            const Vector3 trial = x + omega * delta;
            const Vec3 y = projector_->project(surface, Vec3{trial[0], trial[1], trial[2]});
            const Vector3 d = offset(y, xv);
            if (!d.allFinite()) continue;
            const double f = objective.value(d);
            if (!std::isfinite(f) || (opt_.surfaceMustNotWorsen && f > f0 && !offSurface())) continue;
            accept(r, d, f, y);  // exactly the projector's point
            return r;
        }
    }
    if (off == 1) {  // every trial refused, all the while off the surface: straight onto it, if valid
        const Vec3 y = projector_->project(surface, xv);
        const Vector3 d = offset(y, xv);
        const double f = d.allFinite() ? objective.value(d) : f0;
        if (d.allFinite() && std::isfinite(f)) {
            accept(r, d, f, y);
            return r;
        }
    }
    if (!opt_.surfaceNewtonFallback) return r;
    // The centroid is reached or would make the hexes worse: minimise the
    // hexes' mean ratio within the tangent plane instead, then project.
    TangentPlaneObjective<NodeObjective<InverseMeanRatio>> tangent(objective, normal);
    const NodeMove m = newtonDescent(tangent, L, opt_.gradientTolerance * static_cast<double>(n) / L, opt_.newton);
    if (m.steps == 0) return r;
    const Matrix3 P = Matrix3::Identity() - normal * normal.transpose();
    const Vector3 moved = P * m.displacement;  // what `objective` is now shifted by
    acceptProjected(r, objective, xv, moved, projector_->project(surface, displaced(xv, moved)), f0);
    return r;
}

Smoother::Visit Smoother::curveStep(Index v, std::vector<CornerTerm>& buf) const {
    Visit r = curveSlide(v, buf);
    if (r.move.steps > 0 || !std::isfinite(r.move.before)) return r;
    // At rest but off the curve (a chain that started beside it, evenly
    // spaced, has nothing to slide towards): onto the curve, as long as the
    // hexes stay valid; the curve comes before a slightly better mean ratio.
    const auto sv = static_cast<std::size_t>(v);
    const Vec3& xv = mesh_.nodes[sv];
    const Vec3 y = projector_->projectToCurve(mesh_.nodeClass[sv].id, xv);
    const Vector3 d = offset(y, xv);
    if (!d.allFinite() || !(d.norm() > opt_.moveTolerance * r.length)) return r;
    // gathered again: curveSlide's Newton step leaves the terms shifted
    const std::size_t n = gatherCornerTerms(mesh_, topo_.nodeHexes, v, buf.data());
    const double f = NodeObjective<InverseMeanRatio>(InverseMeanRatio{}, buf.data(), n).value(d);
    if (!std::isfinite(f)) return r;
    accept(r, d, f, y);
    return r;
}

Smoother::Visit Smoother::curveSlide(Index v, std::vector<CornerTerm>& buf) const {
    Visit r;
    const auto sv = static_cast<std::size_t>(v);
    const std::size_t n = gatherTerms(v, buf, r);
    NodeObjective<InverseMeanRatio> objective(InverseMeanRatio{}, buf.data(), n);
    const double L = r.length;
    const double f0 = objective.value(Vector3::Zero());
    r.move.before = r.move.after = f0;
    const std::size_t k = nodeCurveNeighbours_.size(sv);
    if (!std::isfinite(f0) || k == 0) return r;
    const Vec3& xv = mesh_.nodes[sv];
    const Vector3 x(xv[0], xv[1], xv[2]);
    Vector3 target = Vector3::Zero();
    for (const Index* u = nodeCurveNeighbours_.begin(sv); u != nodeCurveNeighbours_.end(sv); ++u) {
        const Vec3& p = mesh_.nodes[static_cast<std::size_t>(*u)];
        target += Vector3(p[0], p[1], p[2]);
    }
    const Vector3 delta = target / static_cast<double>(k) - x;
    if (delta.norm() > opt_.moveTolerance * L) {
        double omega = opt_.surfaceRelaxation;
        for (int i = 0; i <= opt_.surfaceHalvings; ++i, omega *= 0.5) {
            const Vec3 y = projector_->projectToCurve(mesh_.nodeClass[sv].id, displaced(xv, omega * delta));
            const Vector3 d = offset(y, xv);
            if (!d.allFinite()) continue;
            const double f = objective.value(d);
            if (!std::isfinite(f) || (opt_.surfaceMustNotWorsen && f > f0)) continue;
            accept(r, d, f, y);
            return r;
        }
    }
    if (!opt_.surfaceNewtonFallback) return r;
    // As for surface nodes: Newton on the hexes' mean ratio along the curve's
    // tangent (the direction between the two curve neighbours of a chain's
    // inner node, towards the one of its end), then back onto the curve.
    const Index* nb = nodeCurveNeighbours_.begin(sv);
    const Vec3& a = mesh_.nodes[static_cast<std::size_t>(nb[0])];
    const Vec3& b = k >= 2 ? mesh_.nodes[static_cast<std::size_t>(nb[1])] : xv;
    Vector3 t(b[0] - a[0], b[1] - a[1], b[2] - a[2]);
    if (!(t.norm() > 0)) return r;
    t.normalize();
    TangentLineObjective<NodeObjective<InverseMeanRatio>> line(objective, t);
    const NodeMove m = newtonDescent(line, L, opt_.gradientTolerance * static_cast<double>(n) / L, opt_.newton);
    if (m.steps == 0) return r;
    const Vector3 moved = t * t.dot(m.displacement);  // what `objective` is now shifted by
    acceptProjected(r, objective, xv, moved, projector_->projectToCurve(mesh_.nodeClass[sv].id, displaced(xv, moved)),
                    f0);
    return r;
}

}  // namespace isohex::smoothing::detail
