#include "Svg.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "isohex/core/AtomicFile.hpp"

namespace isohex::cli {

namespace {
std::string escape(const std::string& s) {
    std::string o;
    for (char c : s) {
        if (c == '&') o += "&amp;";
        else if (c == '<') o += "&lt;";
        else if (c == '>') o += "&gt;";
        else if (c == '"') o += "&quot;";
        else o += c;
    }
    return o;
}
constexpr const char* kColours[] = {"#222222", "#e8e8e8", "#4477aa", "#ee6677", "#228833", "#ccbb44"};
}  // namespace

std::string histogramSvg(const std::string& title, const std::vector<HistogramSeries>& series) {
    const int bins = 11;
    const double W = 900, H = 500, left = 80, right = 20, top = 60, bottom = 110;
    const double plotW = W - left - right, plotH = H - top - bottom;
    std::size_t maxCount = 1;
    for (const auto& s : series)
        for (auto c : s.counts) maxCount = std::max(maxCount, c);
    // a log scale keeps a few bad hexes visible next to hundreds of thousands of good ones
    const double logMax = std::log10(static_cast<double>(maxCount) + 1);
    auto y = [&](std::size_t c) { return top + plotH - plotH * std::log10(static_cast<double>(c) + 1) / logMax; };
    std::ostringstream o;
    o << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << W << "\" height=\"" << H << "\" viewBox=\"0 0 " << W
      << " " << H << "\" font-family=\"sans-serif\">\n";
    o << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
    o << "<text x=\"" << W / 2 << "\" y=\"28\" text-anchor=\"middle\" font-size=\"18\">" << escape(title) << "</text>\n";
    // axes and log gridlines
    o << "<line x1=\"" << left << "\" y1=\"" << top + plotH << "\" x2=\"" << left + plotW << "\" y2=\"" << top + plotH
      << "\" stroke=\"black\"/>\n";
    o << "<line x1=\"" << left << "\" y1=\"" << top << "\" x2=\"" << left << "\" y2=\"" << top + plotH
      << "\" stroke=\"black\"/>\n";
    for (std::size_t tick = 1; tick <= maxCount * 10; tick *= 10) {
        if (tick > maxCount && tick != 1) break;
        const double ty = y(tick);
        o << "<line x1=\"" << left - 4 << "\" y1=\"" << ty << "\" x2=\"" << left + plotW << "\" y2=\"" << ty
          << "\" stroke=\"#dddddd\"/>\n";
        o << "<text x=\"" << left - 8 << "\" y=\"" << ty + 4 << "\" text-anchor=\"end\" font-size=\"11\">" << tick
          << "</text>\n";
    }
    o << "<text x=\"18\" y=\"" << top + plotH / 2 << "\" transform=\"rotate(-90 18 " << top + plotH / 2
      << ")\" text-anchor=\"middle\" font-size=\"13\">hexahedra (log scale)</text>\n";
    const double groupW = plotW / bins;
    const double barW = std::min(40.0, (groupW - 8) / std::max<std::size_t>(1, series.size()));
    for (int b = 0; b < bins; ++b) {
        const double gx = left + b * groupW;
        char label[32];
        std::snprintf(label, sizeof label, "%.1f..%.1f", kScaledJacobianBins[b], kScaledJacobianBins[b + 1]);
        o << "<text x=\"" << gx + groupW / 2 << "\" y=\"" << top + plotH + 18
          << "\" text-anchor=\"middle\" font-size=\"11\">" << label << "</text>\n";
        const double x0 = gx + (groupW - barW * series.size()) / 2;
        for (std::size_t s = 0; s < series.size(); ++s) {
            const std::size_t c = series[s].counts[b];
            const double by = y(c);
            const double bx = x0 + s * barW;
            o << "<rect x=\"" << bx << "\" y=\"" << by << "\" width=\"" << barW - 1 << "\" height=\""
              << top + plotH - by << "\" fill=\"" << kColours[s % 6] << "\" stroke=\"black\" stroke-width=\"0.5\">"
              << "<title>" << escape(series[s].label) << ": " << c << "</title></rect>\n";
            // counts stand upright above their bar so neighbours never overlap
            o << "<text x=\"" << bx + barW / 2 + 3 << "\" y=\"" << by - 3 << "\" transform=\"rotate(-90 "
              << bx + barW / 2 + 3 << " " << by - 3 << ")\" font-size=\"9\">" << c << "</text>\n";
        }
    }
    o << "<text x=\"" << left + plotW / 2 << "\" y=\"" << top + plotH + 40
      << "\" text-anchor=\"middle\" font-size=\"13\">scaled Jacobian (below 0.2: questionable or unacceptable; below 0: inverted)</text>\n";
    // legend
    double lx = left, ly = H - 40;
    for (std::size_t s = 0; s < series.size(); ++s) {
        std::string text = series[s].label;
        if (series[s].degenerate) text += " (" + std::to_string(series[s].degenerate) + " degenerate, not shown)";
        const double width = 30 + 6.5 * text.size();
        if (lx > left && lx + width > W - right) {  // wrap the legend
            lx = left;
            ly += 18;
        }
        o << "<rect x=\"" << lx << "\" y=\"" << ly << "\" width=\"14\" height=\"14\" fill=\"" << kColours[s % 6]
          << "\" stroke=\"black\" stroke-width=\"0.5\"/>\n";
        o << "<text x=\"" << lx + 20 << "\" y=\"" << ly + 12 << "\" font-size=\"12\">" << escape(text) << "</text>\n";
        lx += width;
    }
    o << "</svg>\n";
    return o.str();
}

void writeHistogramSvg(const std::string& path, bool overwrite, const std::string& title,
                       const std::vector<HistogramSeries>& series) {
    const std::string svg = histogramSvg(title, series);
    io::writeTextAtomically(path, overwrite, svg);
}

}  // namespace isohex::cli
