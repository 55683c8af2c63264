// loadVolume: picks the reader from the path, checks the voxels, and builds
// the OpenVDB grid with the image's affine transform.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <initializer_list>
#include <sstream>

#include <cerrno>
#include <cstring>

#include <fcntl.h>
#include <unistd.h>

#include <openvdb/io/File.h>
#include <openvdb/tools/Count.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include "DenseGrid.hpp"
#include "RawVolume.hpp"
#include "ReaderPlugins.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/imaging/Volume.hpp"

namespace fs = std::filesystem;

namespace isohex::imaging {
namespace detail {

bool naturalLess(const std::string& a, const std::string& b) {
    std::size_t i = 0, j = 0;
    while (i < a.size() && j < b.size()) {
        if (std::isdigit(static_cast<unsigned char>(a[i])) &&
            std::isdigit(static_cast<unsigned char>(b[j]))) {
            std::size_t ie = i, je = j;
            while (ie < a.size() && std::isdigit(static_cast<unsigned char>(a[ie]))) ++ie;
            while (je < b.size() && std::isdigit(static_cast<unsigned char>(b[je]))) ++je;
            // Compare digit runs by value: strip leading zeros, then length, then text.
            std::size_t is = i, js = j;
            while (is + 1 < ie && a[is] == '0') ++is;
            while (js + 1 < je && b[js] == '0') ++js;
            if (ie - is != je - js) return ie - is < je - js;
            const int c = a.compare(is, ie - is, b, js, je - js);
            if (c != 0) return c < 0;
            i = ie;
            j = je;
        } else {
            if (a[i] != b[j]) return a[i] < b[j];
            ++i;
            ++j;
        }
    }
    return a.size() - i < b.size() - j;
}

double estimatePeakBytes(const RawHeader& h) {
    const double voxels = double(h.size[0]) * double(h.size[1]) * double(h.size[2]);
    // Readers convert to float32: the whole file (all volumes and components),
    // then the extracted dense copy, then the grid (4 bytes + leaf overhead).
    const double fileBuffer = voxels * double(h.size[3]) * h.components * 4.0;
    return fileBuffer + voxels * 4.0 + voxels * 4.3;
}

void checkMemoryBudget(const std::string& file, const RawHeader& h, double maxMemoryMB) {
    double budget = maxMemoryMB * 1024.0 * 1024.0;
    std::string what = "the max-memory budget";
    if (!(maxMemoryMB > 0.0)) {
        const double physical = double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGE_SIZE));
        budget = 0.8 * physical;
        what = "80% of this machine's memory";
    }
    const double need = estimatePeakBytes(h);
    if (need > budget) {
        std::ostringstream m;
        m.precision(3);
        m << file << ": loading this " << h.size[0] << "x" << h.size[1] << "x" << h.size[2];
        if (h.size[3] > 1) m << "x" << h.size[3];
        m << " volume needs about " << need / (1024.0 * 1024.0) << " MiB (estimate), more than "
          << what << " (" << budget / (1024.0 * 1024.0)
          << " MiB). Raise the max-memory option if the machine has the memory, or crop or "
             "downsample the scan first.";
        throw Error(m.str());
    }
}

}  // namespace detail

openvdb::math::Transform::Ptr makeTransform(const Vec3& origin, const Vec3& spacing,
                                            const std::array<double, 9>& direction) {
    // OpenVDB multiplies row vectors: world = [i j k 1] * M, so M holds
    // (D * diag(spacing)) transposed, and the origin in its last row.
    openvdb::math::Mat4d m = openvdb::math::Mat4d::identity();
    for (int row = 0; row < 3; ++row)       // index axis
        for (int col = 0; col < 3; ++col)   // world axis
            m(row, col) = direction[3 * col + row] * spacing[row];
    for (int col = 0; col < 3; ++col) m(3, col) = origin[col];
    return openvdb::math::Transform::createLinearTransform(m);
}

namespace {

std::string lower(std::string s) {
    for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

struct Range {
    double lo = std::numeric_limits<double>::infinity();
    double hi = -std::numeric_limits<double>::infinity();
    std::int64_t nonFinite = 0;
    std::int64_t firstBad = -1;  // smallest linear index of a non-finite voxel
};

Range scanValues(const std::vector<float>& v) {
    return tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, v.size(), 1 << 16), Range{},
        [&](const tbb::blocked_range<std::size_t>& r, Range acc) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                const float x = v[i];
                if (!std::isfinite(x)) {
                    if (acc.nonFinite++ == 0 || std::int64_t(i) < acc.firstBad) acc.firstBad = std::int64_t(i);
                    continue;
                }
                acc.lo = std::min(acc.lo, double(x));
                acc.hi = std::max(acc.hi, double(x));
            }
            return acc;
        },
        [](Range a, const Range& b) {
            a.lo = std::min(a.lo, b.lo);
            a.hi = std::max(a.hi, b.hi);
            if (b.nonFinite > 0 && (a.nonFinite == 0 || b.firstBad < a.firstBad)) a.firstBad = b.firstBad;
            a.nonFinite += b.nonFinite;
            return a;
        });
}

// With a region asked for, the voxels of `raw` outside it dropped (a reader
// that read more than the region: the whole file, or ITK's reader of a format
// that does not stream); notes the file's dimensions.
void cropToRegion(detail::RawVolume& raw, const openvdb::CoordBBox& region) {
    if (raw.fileDims == std::array<std::int64_t, 3>{0, 0, 0} && raw.start == std::array<std::int64_t, 3>{0, 0, 0})
        raw.fileDims = raw.dims;
    if (region.empty()) return;
    std::array<std::int64_t, 3> lo{}, hi{};
    for (int a = 0; a < 3; ++a) {
        lo[a] = std::max<std::int64_t>(region.min()[a], raw.start[a]);
        hi[a] = std::min<std::int64_t>(region.max()[a], raw.start[a] + raw.dims[a] - 1);
        if (hi[a] < lo[a]) throw Error("the voxel region asked for lies outside the image (please report this)");
    }
    if (lo == raw.start && hi[0] - lo[0] + 1 == raw.dims[0] && hi[1] - lo[1] + 1 == raw.dims[1] &&
        hi[2] - lo[2] + 1 == raw.dims[2])
        return;
    const std::array<std::int64_t, 3> d{hi[0] - lo[0] + 1, hi[1] - lo[1] + 1, hi[2] - lo[2] + 1};
    auto crop = [&](auto& values) {
        using T = typename std::decay_t<decltype(values)>::value_type;
        std::vector<T> out(static_cast<std::size_t>(d[0] * d[1] * d[2]));
        for (std::int64_t z = 0; z < d[2]; ++z)
            for (std::int64_t y = 0; y < d[1]; ++y) {
                const std::int64_t from = (lo[0] - raw.start[0]) +
                                          raw.dims[0] * ((y + lo[1] - raw.start[1]) + raw.dims[1] * (z + lo[2] - raw.start[2]));
                std::copy_n(values.begin() + from, d[0], out.begin() + d[0] * (y + d[1] * z));
            }
        values = std::move(out);
    };
    if (!raw.values.empty()) crop(raw.values);
    if (!raw.labels.empty()) crop(raw.labels);
    raw.start = lo;
    raw.dims = d;
    raw.streamed = false;
}

Volume fromRaw(detail::RawVolume&& raw, const std::string& file, const LoadOptions& options) {
    cropToRegion(raw, options.region);
    Volume vol;
    vol.fileDims = openvdb::Coord(int(raw.fileDims[0]), int(raw.fileDims[1]), int(raw.fileDims[2]));
    vol.regionStreamed = raw.streamed;
    vol.source = file;
    vol.format = raw.format;
    vol.pixelType = raw.pixelType;
    vol.seriesUid = raw.seriesUid;
    vol.origin = raw.origin;
    vol.spacing = raw.spacing;
    vol.direction = raw.direction;
    const openvdb::Coord first(int(raw.start[0]), int(raw.start[1]), int(raw.start[2]));
    vol.box = openvdb::CoordBBox(first, first.offsetBy(int(raw.dims[0]) - 1, int(raw.dims[1]) - 1,
                                                       int(raw.dims[2]) - 1));
    auto transform = makeTransform(raw.origin, raw.spacing, raw.direction);
    if (options.progress) options.progress("grid", 0.0);
    if (!raw.labels.empty()) {
        vol.kind = VolumeKind::Labels;
        const auto [lo, hi] = std::minmax_element(raw.labels.begin(), raw.labels.end());
        vol.minValue = *lo;
        vol.maxValue = *hi;
        vol.labels = detail::denseToGrid(raw.labels.data(), vol.box, 0, transform);
        vol.labels->setName("labels");
    } else {
        vol.kind = VolumeKind::Intensity;
        const Range r = scanValues(raw.values);
        if (r.nonFinite == std::int64_t(raw.values.size())) {
            throw Error(file + ": every voxel is NaN or infinite; there is nothing to mesh. "
                        "Check the export of the scan.");
        }
        if (r.nonFinite > 0 && !options.nanAsOutside) {
            const std::int64_t i = r.firstBad, nx = raw.dims[0], ny = raw.dims[1];
            std::ostringstream m;
            m << file << ": " << r.nonFinite << " of " << raw.values.size()
              << " voxels are NaN or infinite (the first at voxel (" << i % nx << ","
              << (i / nx) % ny << "," << i / (nx * ny)
              << ")). Pass the nan-as-outside option to treat them as outside the object, or "
                 "repair the scan.";
            throw Error(m.str());
        }
        vol.minValue = r.lo;
        vol.maxValue = r.hi;
        vol.nonFiniteVoxels = r.nonFinite;
        // The background is the smallest value: outside for the usual
        // "inside = brighter" selection, and never a surface crossing.
        vol.intensity = detail::denseToGrid(raw.values.data(), vol.box, float(r.lo), transform);
        vol.intensity->setName("intensity");
        vol.intensity->setGridClass(openvdb::GRID_FOG_VOLUME);
    }
    if (options.progress) options.progress("grid", 1.0);
    return vol;
}

// A .vdb file cut short or with damaged lengths made OpenVDB's reader
// allocate strings of the garbage lengths (16.1 GiB peak and 65 s for a 37 kB file
// cut from a 41 kB one) before it threw. The layout OpenVDB 10 writes (file
// format 222 and later, with grid offsets) is walked first: the header, the
// file metadata (length-prefixed strings and values) and each grid's
// descriptor, whose grid, block and end offsets must lie within the file.
// Only lengths and offsets are checked; OpenVDB still reads the file. Other
// format versions are left to OpenVDB.
void checkVdbLayout(const std::string& file) {
    std::ifstream in(file, std::ios::binary);
    const auto size = static_cast<std::uint64_t>(fs::file_size(file));
    auto fail = [&](const std::string& what) {
        throw Error(file + ": the OpenVDB file is damaged or truncated (" + what + ", the file has " +
                    std::to_string(size) + " bytes); write it again.");
    };
    auto read = [&](void* to, std::size_t n) {
        in.read(static_cast<char*>(to), static_cast<std::streamsize>(n));
        return static_cast<std::size_t>(in.gcount()) == n;
    };
    auto pos = [&] { return static_cast<std::uint64_t>(in.tellg()); };
    auto skipString = [&](const char* what) {  // uint32 length, then the bytes
        std::uint32_t n = 0;
        if (!read(&n, 4)) fail(std::string("it ends in ") + what);
        if (n > size - pos()) fail(std::string(what) + " of " + std::to_string(n) + " bytes at byte " + std::to_string(pos()));
        in.seekg(static_cast<std::streamoff>(n), std::ios::cur);
    };
    std::int64_t magic = 0;
    std::uint32_t version = 0, major = 0, minor = 0;
    char offsets = 0;
    if (!read(&magic, 8) || magic != openvdb::OPENVDB_MAGIC) return;  // OpenVDB says "not a VDB file"
    if (!read(&version, 4) || !read(&major, 4) || !read(&minor, 4) || !read(&offsets, 1)) fail("it ends in its header");
    if (version < 222 || offsets == 0) return;
    char uuid[36];
    if (!read(uuid, 36)) fail("it ends in its header");
    auto readCount = [&](const char* what) {  // int32, not negative
        std::int32_t n = 0;
        if (!read(&n, 4) || n < 0) fail(std::string("its ") + what + " count is unreadable");
        return n;
    };
    const std::int32_t metas = readCount("metadata");
    for (std::int32_t m = 0; m < metas; ++m)
        for (const char* what : {"a metadata name", "a metadata type", "a metadata value"}) skipString(what);
    const std::int32_t grids = readCount("grid");
    for (std::int32_t g = 0; g < grids; ++g) {
        for (const char* what : {"a grid name", "a grid type", "an instance parent name"}) skipString(what);
        std::int64_t gridPos = 0, blockPos = 0, endPos = 0;
        if (!read(&gridPos, 8) || !read(&blockPos, 8) || !read(&endPos, 8)) fail("it ends in a grid descriptor");
        const auto here = static_cast<std::int64_t>(pos());
        if (gridPos < here || blockPos < gridPos || endPos < blockPos || static_cast<std::uint64_t>(endPos) > size)
            fail("grid " + std::to_string(g + 1) + " of " + std::to_string(grids) + " is said to end at byte " +
                 std::to_string(endPos));
        in.seekg(endPos);
    }
}

Volume loadVdb(const fs::path& path, const LoadOptions& options) {
    const std::string file = path.string();
    openvdb::initialize();
    openvdb::GridBase::Ptr base;
    checkVdbLayout(file);
    try {
        openvdb::io::File vdb(file);
        vdb.open();
        auto metas = vdb.readAllGridMetadata();
        std::string names;
        for (const auto& g : *metas) names += "\n  " + g->getName() + " (" + g->valueType() + ")";
        std::string pick = options.gridName;
        if (pick.empty()) {
            const std::string want = options.labels ? "int32" : "float";
            for (const auto& g : *metas)
                if (g->valueType() == want) {
                    pick = g->getName();
                    break;
                }
            if (pick.empty()) {
                throw Error(file + ": holds no " + want + " grid; its grids are:" + names +
                            "\nName one with the grid option" +
                            (options.labels ? "." : ", or use the labels option for an int32 grid."));
            }
        } else if (!vdb.hasGrid(pick)) {
            throw Error(file + ": has no grid named '" + pick + "'; its grids are:" + names);
        }
        if (auto it = std::find_if(metas->begin(), metas->end(),
                                   [&](const auto& g) { return g->getName() == pick; });
            it != metas->end()) {
            if (auto bytes = (*it)->getMetadata<openvdb::Int64Metadata>("file_mem_bytes")) {
                // The grid's in-memory size, expressed as voxels for the estimate.
                detail::RawHeader h;
                h.size = {std::max<std::int64_t>(1, bytes->value() / 8), 1, 1, 1};
                detail::checkMemoryBudget(file, h, options.maxMemoryMB);
            }
        }
        base = vdb.readGrid(pick);
        vdb.close();
    } catch (const openvdb::Exception& e) {
        throw Error(file + ": cannot be read as an OpenVDB file (" + boundedMessage(e.what()) +
                    "). The file is damaged or truncated; write it again.");
    }

    Volume vol;
    vol.source = file;
    vol.format = "OpenVDB";
    vol.levelSet = base->getGridClass() == openvdb::GRID_LEVEL_SET;
    const openvdb::math::Mat4d m = base->transform().baseMap()->getAffineMap()->getMat4();
    for (int a = 0; a < 3; ++a) {
        const openvdb::Vec3d axis(m(a, 0), m(a, 1), m(a, 2));
        vol.spacing[a] = axis.length();
        for (int w = 0; w < 3; ++w) vol.direction[3 * w + a] = axis[w] / vol.spacing[a];
        vol.origin[a] = m(3, a);
    }
    if (auto f = openvdb::gridPtrCast<openvdb::FloatGrid>(base)) {
        if (options.labels) throw Error(file + ": grid '" + f->getName() + "' holds floats, not labels.");
        vol.kind = VolumeKind::Intensity;
        vol.pixelType = "float32";
        vol.box = f->evalActiveVoxelBoundingBox();
        std::int64_t bad = 0;
        double lo = std::numeric_limits<double>::infinity(), hi = -lo;
        for (auto it = f->cbeginValueOn(); it; ++it) {
            const float v = *it;
            if (!std::isfinite(v)) {
                bad += static_cast<std::int64_t>(it.getVoxelCount());
                continue;
            }
            lo = std::min(lo, double(v));
            hi = std::max(hi, double(v));
        }
        if (bad > 0 && !options.nanAsOutside) {
            throw Error(file + ": " + std::to_string(bad) + " active voxels of grid '" + f->getName() +
                        "' are NaN or infinite. Pass the nan-as-outside option to treat them as "
                        "outside, or repair the grid.");
        }
        if (!std::isfinite(lo)) throw Error(file + ": grid '" + f->getName() + "' has no finite active voxels.");
        vol.minValue = lo;
        vol.maxValue = hi;
        vol.nonFiniteVoxels = bad;
        vol.intensity = f;
    } else if (auto l = openvdb::gridPtrCast<openvdb::Int32Grid>(base)) {
        vol.kind = VolumeKind::Labels;
        vol.pixelType = "int32";
        vol.box = l->evalActiveVoxelBoundingBox();
        const auto mm = openvdb::tools::minMax(l->tree());
        vol.minValue = mm.min();
        vol.maxValue = mm.max();
        vol.labels = l;
    } else {
        throw Error(file + ": grid '" + base->getName() + "' has value type " + base->valueType() +
                    "; isohex reads float (intensity, level set) and int32 (label) grids.");
    }
    if (vol.box.empty()) throw Error(file + ": grid '" + base->getName() + "' has no active voxels.");
    return vol;
}

std::vector<fs::path> filesWithExtension(const fs::path& dir, std::initializer_list<const char*> exts) {
    std::vector<fs::path> out;
    for (const auto& e : fs::directory_iterator(dir)) {
        if (!e.is_regular_file()) continue;
        const std::string name = e.path().filename().string();
        if (name.empty() || name[0] == '.') continue;
        const std::string ext = lower(e.path().extension().string());
        for (const char* want : exts)
            if (ext == want) out.push_back(e.path());
    }
    std::sort(out.begin(), out.end(), [](const fs::path& a, const fs::path& b) {
        return detail::naturalLess(a.filename().string(), b.filename().string());
    });
    return out;
}

}  // namespace

namespace {

// The input is a file or folder isohex may open: a named pipe blocked the
// reader for ever, a device was read as voxels, and a file without read
// permission was called damaged by the reader that failed to open it.
void checkInputKind(const fs::path& path, const fs::file_status& status) {
    const std::string file = path.string();
    const auto type = status.type();
    if (type != fs::file_type::regular && type != fs::file_type::directory) {
        const char* what = type == fs::file_type::fifo                                          ? "a named pipe (FIFO)"
                           : type == fs::file_type::character || type == fs::file_type::block ? "a device"
                           : type == fs::file_type::socket                                      ? "a socket"
                                                                                                 : "not a regular file";
        throw Error(file + ": is " + what + ", not a scan file or folder; isohex reads regular files (a pipe "
                    "or device would block or never end). Save the scan to a file and pass its path.");
    }
    const int fd = ::open(file.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
        const int err = errno;
        if (err == EACCES || err == EPERM)
            throw Error(file + ": permission denied: this user may not read the " +
                        (type == fs::file_type::directory ? "folder" : "file") +
                        ". Make it readable (chmod u+r, or ask its owner) and retry.");
        throw Error(file + ": cannot be opened (" + std::strerror(err) + "); check the path and retry.");
    }
    ::close(fd);
}

Volume loadVolumeUnguarded(const fs::path& path, const LoadOptions& options) {
    const std::string file = path.string();
    std::error_code ec;
    const auto status = fs::status(path, ec);
    if (ec || !fs::exists(status)) {
        throw Error(file + ": no such file or folder. Check the path (relative paths start at " +
                    fs::current_path().string() + ").");
    }
    checkInputKind(path, status);
    if (fs::is_directory(status)) {
        if (auto exr = filesWithExtension(path, {".exr"}); !exr.empty())
            return fromRaw(detail::exrReader().readSlices(exr, options), file, options);
        if (auto tif = filesWithExtension(path, {".tif", ".tiff"}); !tif.empty())
            return fromRaw(detail::itkReaders().readTiffSlices(tif, options), file, options);
        return fromRaw(detail::itkReaders().readDicomFolder(path, options), file, options);
    }
    if (fs::file_size(path, ec) == 0) {
        throw Error(file + ": the file is empty; it was probably not written completely. Export it again.");
    }
    if (lower(path.extension().string()) == ".vdb") return loadVdb(path, options);
    // .nii and .nii.gz without ITK (its plugin's load was most of a small
    // scan's load stage); the NIfTI-1 files libnifti2 cannot read as ITK does
    // go on to ITK.
    if (detail::readsWithNiftiLib(path))
        if (std::optional<detail::RawVolume> raw = detail::readWithNiftiLib(path, options))
            return fromRaw(std::move(*raw), file, options);
    return fromRaw(detail::itkReaders().readImageFile(path, options), file, options);
}
}  // namespace

// What the readers and OpenVDB throw that the checks above did not foresee
// (ITK's "unknown component type" from a header's ElementType, OpenVDB's
// refusal of a transform from a degenerate header) is still about this
// input: it is reported as the input's error, not as isohex's.
Volume loadVolume(const fs::path& path, const LoadOptions& options) {
    try {
        return loadVolumeUnguarded(path, options);
    } catch (const Error&) {
        throw;
    } catch (const std::bad_alloc&) {
        throw;
    } catch (const std::exception& e) {
        std::string why = boundedMessage(e.what());
        std::replace(why.begin(), why.end(), '\n', ' ');
        throw Error(path.string() + ": cannot be read (" + why +
                    "). Its header or data is damaged or unusual; check the file or export it again.");
    }
}

}  // namespace isohex::imaging
