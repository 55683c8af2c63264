#pragma once
// An error the user can get past by changing a setting (a larger element
// size, another iso value, permission to overwrite). The libraries name the
// setting by what it is, not by how a front end spells it: the command line
// renders it as a flag (--size), a batch manifest row as its column (size).
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include "isohex/core/Error.hpp"

namespace isohex {

// The settings library errors can name.
enum class Setting : std::uint8_t {
    Force,               // overwrite existing output files
    Iso,                 // the surface's intensity
    Labels,              // read the image as a label map
    Label,               // the labels to mesh
    SliceSpacing,        // the voxel spacing of a folder of 2-D slices
    Size,                // the element edge length
    Level,               // the element size as a grid level (2^level voxels)
    MaxMemory,           // the memory budget
    Method,              // dual contouring, voxel hexes or sheet insertion
    SurfaceTolerance,    // how far the worst-hex pass may leave the surface
    IsosurfaceTopology,  // keep the isosurface's topology on the element grid
    AllowDataOutside,    // read data files a header names outside its folder
    Part,                // mesh one part of a scan split into parts
    KeepLargest,         // keep only the largest region of each material
    MeshExterior,        // mesh the background out to a box too
    BoundaryLayers,      // layers of hexes in the boundary sheet
    Adaptive,            // the adaptive 27-tree instead of the uniform grid
    SizeImage,           // the adaptive mesher's image of element sizes
};

// A plain name for `s`, for a message read outside any front end.
inline std::string_view settingName(Setting s) {
    switch (s) {
        case Setting::Force: return "force";
        case Setting::Iso: return "iso";
        case Setting::Labels: return "labels";
        case Setting::Label: return "label";
        case Setting::SliceSpacing: return "slice spacing";
        case Setting::Size: return "size";
        case Setting::Level: return "level";
        case Setting::MaxMemory: return "memory budget";
        case Setting::Method: return "method";
        case Setting::SurfaceTolerance: return "surface tolerance";
        case Setting::IsosurfaceTopology: return "isosurface topology";
        case Setting::AllowDataOutside: return "allow data outside";
        case Setting::Part: return "part";
        case Setting::KeepLargest: return "keep-largest";
        case Setting::MeshExterior: return "mesh-exterior";
        case Setting::BoundaryLayers: return "boundary layers";
        case Setting::Adaptive: return "adaptive";
        case Setting::SizeImage: return "size image";
    }
    return "setting";
}

// A message in parts: text, and the settings it names between the texts.
using MessagePart = std::variant<std::string, Setting>;

class SettingError : public Error {
public:
    // e.g. SettingError({path + ": too large; choose a larger ", Setting::Size})
    explicit SettingError(std::vector<MessagePart> parts)
        : Error(render(parts, [](Setting s) { return std::string(settingName(s)); })), parts_(std::move(parts)) {}

    const std::vector<MessagePart>& parts() const { return parts_; }
    // The message with each setting named by `name(Setting) -> std::string`.
    template <class Name>
    std::string render(Name&& name) const {
        return render(parts_, name);
    }

private:
    template <class Name>
    static std::string render(const std::vector<MessagePart>& parts, Name&& name) {
        std::string out;
        for (const MessagePart& p : parts)
            out += std::holds_alternative<Setting>(p) ? name(std::get<Setting>(p)) : std::get<std::string>(p);
        return out;
    }

    std::vector<MessagePart> parts_;
};

}  // namespace isohex
