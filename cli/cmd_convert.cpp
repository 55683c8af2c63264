// isohex convert IN OUT: rewrite a hex mesh in another format (by extension).
#include <iostream>
#include <memory>
#include <string>

#include "Commands.hpp"
#include "Isolate.hpp"
#include "JobStage.hpp"
#include "Jobs.hpp"
#include "isohex/core/MeshIO.hpp"

namespace isohex::cli {

namespace {
struct ConvertArgs {
    std::string input;
    std::string output;
    bool force = false;
};

std::string list(const std::vector<std::string>& items) {
    std::string s;
    for (const auto& i : items) s += (s.empty() ? "" : " ") + i;
    return s;
}
}  // namespace

void addConvertCommand(CLI::App& app) {
    auto args = std::make_shared<ConvertArgs>();
    CLI::App* cmd = app.add_subcommand(
        "convert", "Convert a hex mesh between formats, chosen by extension (reads " +
                       list(io::readableExtensions()) + "; writes " + list(io::writableExtensions()) + ")");
    cmd->add_option("input", args->input, "Mesh to read")->required();
    cmd->add_option("output", args->output, "Mesh to write")->required();
    cmd->add_flag("--force", args->force, "Replace the output file if it exists");
    cmd->callback([args] {
        io::formatFromPath(args->output);  // reject a bad output name before reading a large input
        checkOutputPaths({args->output}, {args->input}, args->force);
        // In a child process, as isohex mesh (cli/Isolate.hpp).
        runIsolated(args->input, {args->output}, [&] {
            nowReading(args->input);
            const HexMesh mesh = io::read(args->input);
            stageBegins("write");
            io::WriteOptions opt;
            opt.overwrite = args->force;
            io::write(mesh, args->output, opt);
            std::cout << "wrote " << args->output << ": " << mesh.nodeCount() << " nodes, " << mesh.hexCount()
                      << " hexes\n";
            std::cout.flush();
            return nlohmann::json::object();
        });
    });
}

}  // namespace isohex::cli
