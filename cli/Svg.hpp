#pragma once
// Scaled-Jacobian histograms as SVG, in the style of the seed's quality
// distribution figures: one group of bars per bin, one bar per mesh variant,
// counts written above the bars.
#include <string>
#include <vector>

#include "isohex/core/Quality.hpp"

namespace isohex::cli {

struct HistogramSeries {
    std::string label;                       // legend text, e.g. "with fundamental sheet"
    std::array<std::size_t, 11> counts{};    // over kScaledJacobianBins
    std::size_t degenerate = 0;
};

std::string histogramSvg(const std::string& title, const std::vector<HistogramSeries>& series);
void writeHistogramSvg(const std::string& path, bool overwrite, const std::string& title,
                       const std::vector<HistogramSeries>& series);

}  // namespace isohex::cli
