#include "Jobs.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <set>

#include <fcntl.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "BatchPace.hpp"
#include "Commands.hpp"
#include "FullDisks.hpp"
#include "Isolate.hpp"
#include "Report.hpp"
#include "Svg.hpp"
#include "Versions.hpp"
#include "isohex/core/AtomicFile.hpp"
#include "isohex/core/DiskFullError.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/MeshIO.hpp"
#include "isohex/core/Pieces.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/core/Validate.hpp"
#include "isohex/imaging/ReaderPlugin.hpp"
#include "isohex/pipeline/MeshPipeline.hpp"

namespace isohex::cli {

namespace fs = std::filesystem;

std::string stemOf(const std::string& input) {
    std::string name = fs::path(input).filename().string();
    if (name.empty()) name = fs::path(input).parent_path().filename().string();  // a folder given with a slash
    for (const char* ext : {".nii.gz", ".nii", ".nrrd", ".nhdr", ".mha", ".mhd", ".tiff", ".tif", ".vdb", ".stl",
                            ".obj", ".ply", ".off", ".dcm"})
        if (name.size() > std::strlen(ext) && name.compare(name.size() - std::strlen(ext), std::string::npos, ext) == 0)
            return name.substr(0, name.size() - std::strlen(ext));
    return name;
}

namespace {

// Creates and removes a file in `dir` as the writers will (a temporary
// beside the target): a read-only folder or file system, missing permission
// or a full inode table shows now rather than after the meshing.
void requireWritableFolder(const std::string& output, const fs::path& dir) {
    const fs::path probe = dir / (io::temporaryPrefix(output, ::getpid()) + "probe");
    const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    if (fd < 0) {
        if (errno == EEXIST) return;  // a leftover of this process id: the folder takes files
        throw Error(output + ": cannot write in the folder " + dir.string() + " (" + std::strerror(errno) +
                    "); choose another output folder or fix its permissions");
    }
    ::close(fd);
    ::unlink(probe.c_str());
}

}  // namespace

std::vector<bool> checkOutputPaths(const std::vector<std::string>& outputs, const std::vector<std::string>& inputs,
                                   bool force) {
    std::vector<bool> existed;
    std::set<fs::path> seen;
    for (const auto& o : outputs) {
        std::error_code ec;
        const fs::path path(o);
        if (!seen.insert(fs::absolute(path, ec).lexically_normal()).second)
            throw Error(o + ": named twice among the outputs; give each output its own path");
        if (fs::is_directory(path, ec)) throw Error(o + ": is a folder; give an output file name");
        for (const auto& in : inputs)
            if (fs::exists(path, ec) && fs::equivalent(path, fs::path(in), ec))
                throw Error(o + ": is the input " + in + "; writing there would replace it, choose another output path");
        const fs::path dir = path.parent_path().empty() ? fs::path(".") : path.parent_path();
        if (!fs::is_directory(dir, ec))
            throw Error(o + ": the folder " + dir.string() + " does not exist; create it or choose another output path");
        requireWritableFolder(o, dir);
        existed.push_back(fs::exists(path, ec));
        if (existed.back() && !force)
            throw Error(o + ": file exists; refusing to overwrite it (use --force to replace it)");
    }
    return existed;
}

std::vector<std::string> filesOf(const Job& job) {
    std::vector<std::string> files = job.outputs;
    if (!job.plot.empty()) files.push_back(job.plot);
    if (!job.report.empty()) files.push_back(job.report);
    return files;
}

bool upToDate(const Job& job) {
    std::error_code ec;
    const auto inTime = fs::last_write_time(job.input, ec);
    if (ec) return false;
    const std::vector<std::string> all = filesOf(job);
    for (const auto& o : all) {
        const auto t = fs::last_write_time(o, ec);
        if (ec || t < inTime) return false;
    }
    return !all.empty();
}

namespace {

// A job's figures for the summary line.
JobResult resultOf(const Job& job, const QualitySummary& s, double seconds) {
    JobResult r;
    r.input = job.input;
    r.status = "ok";
    r.hexes = s.hexes;
    r.minScaledJacobian = s.scaledJacobian.min;
    r.meanScaledJacobian = s.scaledJacobian.mean;
    r.inverted = s.inverted;
    r.below02 = s.below02;
    r.seconds = seconds;
    return r;
}

// What a mesh below the minimum quality says: the target, what was reached,
// whether it was written, the places and what to try (--max-deviation only
// where the run relaxes the boundary; the option is refused otherwise).
std::string belowMessage(const pipeline::QualityCertificate& c, bool written, const pipeline::MeshSettings& s) {
    char figures[96];
    std::snprintf(figures, sizeof figures, "%g: smallest scaled Jacobian %.3g, ", c.target, c.achieved);
    const bool relaxes = pipeline::relaxesBoundary(s);
    return "below the minimum quality " + std::string(figures) + std::to_string(c.hexesBelow) + " hex(es) below it" +
           (written ? " (written: --allow-below)" : " (nothing written; --allow-below writes it)") + ":\n" +
           pipeline::describePlaces(c, 10) + "  a finer --size" +
           (relaxes ? " or a larger --max-deviation" : "") +
           " may reach it; --min-quality sets a lower minimum\n";
}

// After each job of a batch of several, how many are left and when the
// batch will end at its pace so far (an info line, or a "batch_progress"
// event with --log-json).
void notePace(ProgressSink& sink, const BatchPace& pace) {
    if (pace.ran() + pace.left() < 2 || pace.left() == 0) return;
    nlohmann::json fields = {{"ran", pace.ran()}, {"left", pace.left()}, {"elapsed_s", pace.elapsedSeconds()}};
    if (const auto eta = pace.etaSeconds()) fields["eta_s"] = *eta;
    sink.event("batch_progress", fields);
    if (sink.mode() != ProgressSink::Mode::Json) sink.note("info", "batch: " + pace.line());
}

// A mesh in several pieces is said aloud: each piece of a finite-element
// model needs its own support, and noise specks of a scan are such pieces.
// (Not for a part of a split scan: isohex merge's report counts the merged mesh's.)
void notePieces(ProgressSink& sink, const std::vector<MeshPiece>& pieces, const pipeline::MeshSettings& settings) {
    const std::string d = describePieces(pieces);
    if (d.empty() || settings.part) return;
    sink.note("info", "the mesh has " + d + "; in a finite-element model each piece needs its own support" +
                          (settings.keepLargest ? "" : " (--keep-largest keeps only the largest region of each material)"));
}

}  // namespace

JobResult runJob(const Job& job, ProgressSink& sink) {
    const Stopwatch total;
    MeshArgs args = job.args;
    checkSettings(args);
    // Every file the job writes (meshes, report, plot) is checked before
    // minutes of meshing: not an existing file without --force, not a
    // folder, in a folder that exists, and not named twice.
    const std::vector<std::string> files = filesOf(job);
    const std::vector<bool> existed = checkOutputPaths(files, {job.input}, args.run.force);
    for (const auto& o : job.outputs) io::formatFromPath(o);  // unknown extension: fail now, not after meshing
    if (args.settings.part)
        for (const auto& o : job.outputs)
            if (io::formatFromPath(o) != io::Format::Vtu)
                throw Error(o + ": a part (--part) is written as .vtu, with the node keys isohex merge joins the "
                                "parts by; write part files as .vtu and give the merged mesh's format to isohex merge");
    pipeline::MeshOutcome out = pipeline::runMeshPipeline(job.input, args.settings, sink);
    const Stopwatch quality;
    // validate's topology is gone before the per-hex measures exist (the two
    // together were the job's peak once the optimiser's was lowered)
    const ValidityReport v = validate(out.mesh);
    const std::vector<MeshPiece> pieces = meshPieces(out.mesh);
    notePieces(sink, pieces, args.settings);
    HexQuality q = computeQuality(out.mesh);
    const QualitySummary s = summarize(out.mesh, q);
    std::vector<double> scaledJacobian = std::move(q.scaledJacobian);
    q = {};  // the other measures are summarised
    const double qualitySeconds = quality.seconds();
    // A part's hexes at its cuts were optimised against frozen nodes; the
    // merge's band pass improves them, and isohex merge certifies the merged
    // mesh: a part is written whatever its minimum (its report still says it).
    if (!out.quality.certified && !args.settings.allowBelow && !args.settings.part) {
        // Nothing is written: the mesh is refused, its places named.
        JobResult r = resultOf(job, s, total.seconds());
        r.status = "below";
        r.written = false;
        r.message = belowMessage(out.quality, false, args.settings);
        return r;
    }
    nlohmann::json report = out.report;
    const nlohmann::json qj = toJson(s);
    for (const auto& [k, val] : qj.items()) report[k] = val;
    report["validity"] = toJson(v);
    report["pieces"] = toJson(pieces);
    nlohmann::json timings;
    for (const auto& [stage, secs] : sink.timings().items()) timings[stage] = secs;
    timings["quality"] = qualitySeconds;
    const Stopwatch writing;
    io::WriteOptions w;
    w.overwrite = args.run.force;
    w.scaledJacobian = std::move(scaledJacobian);
    w.cellFields = out.cellFields;
    if (out.part) pipeline::addPartArrays(w, out.mesh, *out.partNodes, *out.part);
    // Each file is written whole or not at all (a temporary file renamed);
    // if one fails, the files this job created before it are removed again,
    // so a failed job leaves none of its outputs behind (files it replaced
    // under --force are gone either way).
    std::size_t written = 0;
    // and if the process is interrupted meanwhile, the signal handler
    // removes them (the files a job creates, never ones it replaces)
    std::vector<int> onSignal;
    struct Release {
        std::vector<int>& handles;
        ~Release() {
            for (int h : handles) io::releaseOnSignal(h);
        }
    } release{onSignal};
    auto track = [&](std::size_t i) {
        if (!existed[i]) onSignal.push_back(io::removeOnSignal(files[i]));
    };
    try {
        for (const auto& o : job.outputs) {
            const Stopwatch one;
            sink.begin("write");
            io::write(out.mesh, o, w);
            track(written);
            ++written;
            sink.end("write", one.seconds());
        }
        timings["write"] = writing.seconds();
        timings["total"] = total.seconds();
        report["timings_s"] = timings;
        report["peak_memory_mb"] = peakMemoryMb();
        report["huge_pages"] = hugePagesRequested();
        report["outputs"] = job.outputs;
        report["versions"] = versionsJson();
        if (!job.plot.empty()) {
            writeHistogramSvg(job.plot, args.run.force, "Scaled Jacobian of " + stemOf(job.input),
                              {{out.report["pillow"].value("enabled", false) ? "with fundamental sheet" : "without sheet",
                                s.histogram, s.degenerate}});
            track(written);
            ++written;
        }
        if (!job.report.empty()) writeJsonFile(report, job.report, args.run.force);
    } catch (...) {
        for (std::size_t i = 0; i < written; ++i) {  // the meshes, then the plot
            std::error_code ec;
            if (!existed[i]) fs::remove(files[i], ec);
        }
        throw;
    }
    JobResult r = resultOf(job, s, timings["total"]);
    if (!v.ok()) {
        // one readable line; the report's validity block has every example
        const std::string m = describeDefects(v);
        r.message = m + (job.report.empty() ? "" : "; every example in the report's validity block");
    }
    if (!out.quality.certified && !args.settings.part) {
        r.status = "below";
        r.message = belowMessage(out.quality, true, args.settings) + (r.message.empty() ? "" : r.message + "\n");
    }
    return r;
}

namespace {

std::string firstLine(const std::string& s) { return s.substr(0, s.find('\n')); }

// A job's result as the isolated child sends it to the parent.
nlohmann::json resultJson(const JobResult& r) {
    return {{"status", r.status},     {"message", bytesOf(r.message)}, {"written", r.written},
            {"hexes", r.hexes},       {"min", r.minScaledJacobian}, {"mean", r.meanScaledJacobian},
            {"inverted", r.inverted}, {"below02", r.below02},      {"seconds", r.seconds}};
}

JobResult resultFrom(const nlohmann::json& j) {
    JobResult r;
    r.status = j.at("status").get<std::string>();
    r.message = textOf(j.at("message"));
    r.written = j.at("written").get<bool>();
    r.hexes = j.at("hexes").get<std::size_t>();
    r.minScaledJacobian = j.at("min").is_number() ? j.at("min").get<double>() : 0.0;
    r.meanScaledJacobian = j.at("mean").is_number() ? j.at("mean").get<double>() : 0.0;
    r.inverted = j.at("inverted").get<std::size_t>();
    r.below02 = j.at("below02").get<std::size_t>();
    r.seconds = j.at("seconds").get<double>();
    return r;
}
}  // namespace

JobResult runJobIsolated(const Job& job, ProgressSink& sink) {
    const std::vector<std::string> files = filesOf(job);
    JobResult r = resultFrom(runIsolated(job.input, files, [&] { return resultJson(runJob(job, sink)); }));
    r.input = job.input;
    return r;
}

int JobsOutcome::exitCode() const {
    if (failed > 0) return kExitError;
    return belowQuality > 0 ? kExitBelowQuality : kExitOk;
}

JobsOutcome runJobs(const std::vector<Job>& jobs, bool force, ProgressSink::Mode mode, SettingNames names) {
    std::vector<JobResult> results;
    JobsOutcome outcome;
    std::size_t& failed = outcome.failed;
    FullDisks fullDisks;
    // The plugins of the jobs' formats are loaded here, once: each job's child
    // process inherits them instead of loading them again.
    std::size_t toRun = 0;
    for (const Job& job : jobs) {
        if (!force && !job.args.run.force && upToDate(job)) continue;
        ++toRun;
        imaging::preloadReader(job.input);
        for (const std::string& out : job.outputs) io::preloadFormat(out);
    }
    BatchPace pace(toRun);
    ProgressSink batchSink(mode);
    for (std::size_t i = 0; i < jobs.size(); ++i) {
        const Job& job = jobs[i];
        ProgressSink sink(mode, "[" + std::to_string(i + 1) + "/" + std::to_string(jobs.size()) + "] " + stemOf(job.input));
        if (!force && !job.args.run.force && upToDate(job)) {
            results.push_back({job.input, "skipped", "outputs are up to date (use --force to redo)"});
            sink.event("job_skipped", {{"input", job.input}});
            continue;
        }
        auto fail = [&](const std::string& message) {
            ++failed;
            results.push_back({job.input, "failed", message});
            sink.note("error", message);
            sink.event("job_end", {{"input", job.input}, {"status", "failed"}, {"message", message}});
        };
        sink.event("job_begin", {{"input", job.input}, {"outputs", job.outputs}});
        if (const std::string why = fullDisks.holdsBack(job); !why.empty()) {
            fail(why);
            continue;
        }
        const Stopwatch running;
        try {
            results.push_back(runJobIsolated(job, sink));
            const JobResult& r = results.back();
            if (r.status == "below") {
                ++outcome.belowQuality;
                sink.note("error", job.input + ": " + r.message);
            }
            sink.event("job_end", {{"input", job.input}, {"status", r.status}});
        } catch (const io::DiskFullError& e) {
            fullDisks.add(e.folder(), job.input);
            fail(boundedMessage(e.what(), 65536));
        } catch (const std::exception& e) {
            fail(boundedMessage(userMessage(e, names), 65536));
        }
        pace.jobRan(running.seconds());  // a failed job's time counts too
        notePace(batchSink, pace);
    }
    std::printf("%-40s %-8s %10s %8s %8s %8s %8s  %s\n", "input", "status", "hexes", "min SJ", "mean SJ", "<0.2",
                "inverted", "seconds / message");
    for (const auto& r : results) {
        std::string name = r.input.size() > 40 ? "..." + r.input.substr(r.input.size() - 37) : r.input;
        if (r.status == "ok" || r.status == "below")
            std::printf("%-40s %-8s %10zu %8.3f %8.3f %8zu %8zu  %.1f%s%s\n", name.c_str(), r.status.c_str(), r.hexes,
                        r.minScaledJacobian, r.meanScaledJacobian, r.below02, r.inverted, r.seconds,
                        r.message.empty() ? "" : "  ", firstLine(r.message).c_str());
        else
            std::printf("%-40s %-8s %10s %8s %8s %8s %8s  %s\n", name.c_str(), r.status.c_str(), "-", "-", "-", "-", "-",
                        r.message.c_str());
    }
    std::printf("%zu job(s): %zu ok, %zu skipped, %zu failed, %zu below the minimum quality\n", results.size(),
                static_cast<std::size_t>(std::count_if(results.begin(), results.end(), [](auto& r) { return r.status == "ok"; })),
                static_cast<std::size_t>(std::count_if(results.begin(), results.end(), [](auto& r) { return r.status == "skipped"; })),
                failed, outcome.belowQuality);
    return outcome;
}

}  // namespace isohex::cli
