// photorig export nexus --run DIR [--out FILE] [--deflate N]

#include "../command.h"
#include "../command_output.h"
#include "photorig/daemon/pipelines/nexus_export.h"

#include <cstdio>
#include <filesystem>
#include <memory>

namespace photorig::app {
namespace {

struct Options {
  std::string run_dir, out;
  daemon::NexusExportOptions exporting;
};

int Execute(const Options& options) {
  const std::string path =
      options.out.empty() ? (std::filesystem::path(options.run_dir) / "run.nxs").string() : options.out;
  const daemon::NexusExportSummary summary = daemon::ExportNexus(options.run_dir, path, options.exporting);
  for (const std::string& warning : summary.warnings) std::fprintf(stderr, "warning: %s\n", warning.c_str());
  ResultFields() = {{"run_directory", options.run_dir},
                    {"out", path},
                    {"frames", summary.frames},
                    {"processes", summary.processes},
                    {"warnings", summary.warnings},
                    {"file_bytes", summary.file_bytes},
                    {"frame_bytes", summary.frame_bytes},
                    {"total_ms", summary.total_ms}};
  if (!summary.IsSolutionUsable())
    return Fail(summary.termination == solvers::core::Termination::kFailure ? kExitFailed : kExitUsage,
                summary.message);
  std::string solves = "no solves";
  for (std::size_t i = 0; i < summary.processes.size(); ++i)
    solves = (i == 0 ? "solves: " : solves + ", ") + summary.processes[i];
  std::printf("wrote %s: %d frames, %s, %.1f MB (the frames' PNGs %.1f MB), %.0f ms\n", path.c_str(), summary.frames,
              solves.c_str(), summary.file_bytes / 1e6, summary.frame_bytes / 1e6, summary.total_ms);
  return kExitOk;
}

CommandRunner Setup(CLI::App& app) {
  auto options = std::make_shared<Options>();
  CLI::App* group = SubcommandGroup(app, "export", "write stored data in other tools' formats");
  CLI::App* sub = group->add_subcommand("nexus", "a run and its solves as one NeXus (HDF5) file (docs/nexus.md)");
  sub->add_option("--run", options->run_dir, "run directory")->required()->check(CLI::ExistingDirectory);
  sub->add_option("--out", options->out, "file to write (default: RUN/run.nxs)");
  sub->add_option("--deflate", options->exporting.writer.deflate_level,
                  "zlib level of the frame stack, 0 (stored) .. 9 (default 4)")
      ->check(CLI::Range(0, 9));
  return {sub, [options] { return Execute(*options); }};
}

const bool registered = RegisterCommand(Setup);

}  // namespace
}  // namespace photorig::app
