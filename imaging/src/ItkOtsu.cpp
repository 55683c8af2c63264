// Otsu's threshold through ITK's OtsuThresholdCalculator. The histogram is
// filled here (in parallel, with integer counts so the result does not depend
// on the thread count) and handed to ITK, which avoids copying the volume into
// an itk::Image.
#include <algorithm>
#include <cmath>
#include <vector>

#include <itkHistogram.h>
#include <itkOtsuThresholdCalculator.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include "RawVolume.hpp"
#include "isohex/core/Error.hpp"

namespace isohex::imaging::detail {

double otsuThresholdItk(const std::vector<float>& values) {
    constexpr int kBins = kOtsuBins;
    if (values.empty()) throw Error("Otsu threshold: no voxel values to choose a threshold from.");
    const auto [lo, hi] = std::minmax_element(values.begin(), values.end());
    const double vmin = *lo, vmax = *hi;
    if (!(vmax > vmin)) {
        throw Error("Otsu threshold: every voxel has the value " + std::to_string(vmin) +
                    ", so there is no surface to find; check the scan or give an iso value.");
    }
    const double scale = kBins / (vmax - vmin);
    using Counts = std::vector<std::uint64_t>;
    const Counts counts = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, values.size(), 1 << 16), Counts(kBins, 0),
        [&](const tbb::blocked_range<std::size_t>& r, Counts acc) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                const int b = std::min(kBins - 1, static_cast<int>((values[i] - vmin) * scale));
                ++acc[b];
            }
            return acc;
        },
        [](Counts a, const Counts& b) {
            for (int i = 0; i < kBins; ++i) a[i] += b[i];
            return a;
        });
    return otsuFromHistogramItk(counts, vmin, vmax);
}

double otsuFromHistogramItk(const std::vector<std::uint64_t>& counts, double vmin, double vmax) {
    constexpr int kBins = kOtsuBins;
    if (counts.size() != static_cast<std::size_t>(kBins))
        throw Error("Otsu threshold: a histogram of " + std::to_string(counts.size()) + " bins (please report this)");
    using Histogram = itk::Statistics::Histogram<double>;
    auto histogram = Histogram::New();
    histogram->SetMeasurementVectorSize(1);
    Histogram::SizeType size(1);
    size[0] = kBins;
    Histogram::MeasurementVectorType lower(1), upper(1);
    lower[0] = vmin;
    upper[0] = vmax;
    histogram->Initialize(size, lower, upper);
    for (int b = 0; b < kBins; ++b)
        histogram->SetFrequency(static_cast<Histogram::InstanceIdentifier>(b),
                                static_cast<Histogram::AbsoluteFrequencyType>(counts[b]));

    auto otsu = itk::OtsuThresholdCalculator<Histogram, double>::New();
    otsu->SetInput(histogram);
    otsu->SetReturnBinMidpoint(true);
    otsu->Update();
    return otsu->GetThreshold();
}

}  // namespace isohex::imaging::detail
