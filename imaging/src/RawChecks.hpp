#pragma once
// Internal: the checks every reader runs on the RawVolume it made, whatever
// the file format: a geometry OpenVDB's grid transform accepts, and label
// values a float carries exactly. No ITK here.
#include <array>
#include <string>

#include "RawVolume.hpp"

namespace isohex::imaging::detail {

// Throws unless spacing and origin are finite and within the ranges OpenVDB's
// transform takes, the direction cosines are perpendicular and not singular and the voxel volume
// is above OpenVDB's tolerance. `file` names the input in the message.
void checkGeometry(const RawVolume& raw, const std::string& file);

// Throws unless the direction cosines' columns (the image axes) are
// perpendicular within 1e-4; throwSheared gives the message, for readers that
// learn of a shear otherwise (ITK's NIfTI reader refuses one).
void checkAxesPerpendicular(const std::array<double, 9>& direction, const std::string& file);
[[noreturn]] void throwSheared(const std::string& file, const std::string& detail);

// Moves `raw.values` into `raw.labels`; throws if any value is not an integer
// float holds exactly (|v| <= 2^24). `integerFile`: the file stores integers
// (the message then says the values exceed 2^24, not that they are real).
void convertToLabels(RawVolume& raw, const std::string& file, bool integerFile);

}  // namespace isohex::imaging::detail
