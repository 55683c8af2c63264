// A folder of single-channel OpenEXR slices (e.g. a micro-CT reconstruction
// exported slice by slice) read into one dense float volume.
#include <exception>
#include <sstream>

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <tbb/parallel_for.h>

#include "RawVolume.hpp"
#include "isohex/core/Error.hpp"

namespace isohex::imaging::detail {
namespace {

struct SliceInfo {
    int width = 0, height = 0;
    std::string channel;
};

SliceInfo inspect(const std::filesystem::path& file) {
    try {
        Imf::InputFile in(file.string().c_str());
        const Imath::Box2i dw = in.header().dataWindow();
        SliceInfo info{dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1, {}};
        int channels = 0;
        for (auto c = in.header().channels().begin(); c != in.header().channels().end(); ++c) {
            if (channels++ == 0) info.channel = c.name();
        }
        if (channels != 1) {
            throw Error(file.string() + ": has " + std::to_string(channels) +
                        " channels; isohex reads single-channel EXR slices. Save one channel "
                        "(e.g. Y or R) per slice.");
        }
        return info;
    } catch (const Error&) {
        throw;
    } catch (const std::exception& e) {
        throw Error(file.string() + ": not a readable OpenEXR file (" + e.what() +
                    "); it is damaged or truncated, export it again.");
    }
}

}  // namespace

RawVolume readExrSlices(const std::vector<std::filesystem::path>& files, const LoadOptions& options) {
    const std::string folder = files.front().parent_path().string();
    if (files.size() < 2) {
        throw Error(folder + ": holds a single .exr slice; isohex needs a stack of at least two.");
    }
    const SliceInfo first = inspect(files.front());
    RawHeader header;
    header.size = {first.width, first.height, static_cast<std::int64_t>(files.size()), 1};
    checkMemoryBudget(folder, header, options.maxMemoryMB);

    RawVolume raw;
    raw.format = "OpenEXR";
    raw.pixelType = "float32";
    raw.dims = {first.width, first.height, static_cast<std::int64_t>(files.size())};
    raw.spacing = options.sliceSpacing;
    raw.origin = options.sliceOrigin;
    raw.values.resize(static_cast<std::size_t>(raw.count()));
    const std::size_t sliceSize = static_cast<std::size_t>(first.width) * first.height;

    // Slices are independent files, so each is decoded by one task straight
    // into its own part of the buffer.
    tbb::parallel_for(std::size_t(0), files.size(), [&](std::size_t z) {
        const SliceInfo info = inspect(files[z]);
        if (info.width != first.width || info.height != first.height) {
            std::ostringstream m;
            m << files[z].string() << ": slice is " << info.width << "x" << info.height
              << " but the first slice (" << files.front().filename().string() << ") is "
              << first.width << "x" << first.height << "; all slices must have the same size.";
            throw Error(m.str());
        }
        try {
            Imf::InputFile in(files[z].string().c_str());
            const Imath::Box2i dw = in.header().dataWindow();
            float* slice = raw.values.data() + z * sliceSize;
            // The frame buffer is addressed by absolute pixel coordinates, so
            // shift the base pointer by the data window's corner.
            char* base = reinterpret_cast<char*>(slice - dw.min.x - std::ptrdiff_t(dw.min.y) * first.width);
            Imf::FrameBuffer fb;
            fb.insert(info.channel, Imf::Slice(Imf::FLOAT, base, sizeof(float),
                                               sizeof(float) * std::size_t(first.width)));
            in.setFrameBuffer(fb);
            in.readPixels(dw.min.y, dw.max.y);
        } catch (const std::exception& e) {
            throw Error(files[z].string() + ": reading the pixels failed (" + e.what() +
                        "); the slice is damaged or truncated, export it again.");
        }
    });
    return raw;
}

}  // namespace isohex::imaging::detail
