#include "Report.hpp"

#include <cstdio>
#include <cstdlib>
#include <sstream>

#include <sys/resource.h>

#include <nlohmann/json.hpp>

#include "isohex/core/AtomicFile.hpp"

namespace isohex::cli {

double peakMemoryMb() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return static_cast<double>(u.ru_maxrss) / 1024.0;  // Linux reports KiB
}

bool hugePagesRequested() {
    const char* t = std::getenv("GLIBC_TUNABLES");
    return t && std::string(t).find("glibc.malloc.hugetlb=1") != std::string::npos;
}

namespace {
std::string num(double v, int prec = 4) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*g", prec, v);
    return buf;
}
std::string statsLine(const char* name, const Stats& s) {
    if (s.count == 0) return std::string(name) + ": n/a\n";
    return std::string(name) + ": min " + num(s.min) + "  mean " + num(s.mean) + "  max " + num(s.max) + "\n";
}
}  // namespace

std::string formatQuality(const QualitySummary& q, const ValidityReport& v) {
    std::ostringstream o;
    o << "hexes " << q.hexes << ", nodes " << q.nodes << "\n";
    std::string sj = statsLine("scaled Jacobian", q.scaledJacobian);
    // A degenerate hex (a zero-length edge at a corner) has no scaled
    // Jacobian (VTK gives it 1e30); the statistics leave it out, so say so
    // next to them rather than let a minimum of 1 read as a perfect mesh.
    if (q.degenerate > 0 && q.scaledJacobian.count > 0)
        sj.insert(sj.size() - 1, "  (of the " + std::to_string(q.scaledJacobian.count) +
                                     " hexes that are not degenerate)");
    o << sj;
    o << "  below 0.2: " << q.below02 << "   inverted (< 0): " << q.inverted << "   degenerate: " << q.degenerate
      << "\n";
    o << "  histogram:";
    for (std::size_t i = 0; i < q.histogram.size(); ++i) {
        if (i % 4 == 0) o << "\n   ";
        char buf[64];
        std::snprintf(buf, sizeof buf, " [%4.1f,%4.1f%c %9zu", kScaledJacobianBins[i], kScaledJacobianBins[i + 1],
                      i + 1 == q.histogram.size() ? ']' : ')', q.histogram[i]);
        o << buf;
    }
    o << "\n";
    o << statsLine("inverse mean ratio", q.inverseMeanRatio);
    o << statsLine("condition number", q.condition);
    o << statsLine("edge ratio", q.edgeRatio);
    o << statsLine("hex volume", q.volume);
    o << "total volume: " << num(q.totalVolume, 10) << "\n";
    if (v.ok()) {
        o << "validity: ok (no defect found)\n";
    } else {
        o << "validity: " << v.defects.size() << " kind(s) of defect\n";
        for (const auto& [key, d] : v.defects) {
            o << "  " << key << " (constraint " << d.constraint << "): " << d.count << " " << d.entity
              << (d.count == 1 ? "" : "s") << " - " << d.description;
            if (!d.examples.empty()) {
                o << "; e.g. " << d.entity << " " << d.examples[0];
                if (!d.where.empty())
                    o << " at (" << num(d.where[0][0], 6) << ", " << num(d.where[0][1], 6) << ", "
                      << num(d.where[0][2], 6) << ")";
            }
            o << "\n";
        }
    }
    return o.str();
}

std::string describeDefects(const ValidityReport& v) {
    std::string m = "validity defects:";
    bool first = true;
    for (const auto& [key, d] : v.defects) {
        m += std::string(first ? " " : "; ") + key + " x" + std::to_string(d.count) + " (" + d.description;
        if (!d.where.empty()) {
            char at[96];
            std::snprintf(at, sizeof at, ", first at (%.4g, %.4g, %.4g)", d.where[0][0], d.where[0][1], d.where[0][2]);
            m += at;
        }
        m += ")";
        first = false;
    }
    return m;
}

void writeJsonFile(const nlohmann::json& j, const std::string& path, bool overwrite) {
    io::writeTextAtomically(path, overwrite, j.dump(2) + "\n");
}

}  // namespace isohex::cli
