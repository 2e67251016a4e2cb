// photorig export nexus --run DIR [--out FILE] [--deflate N]

#include "../command.h"
#include "../command_output.h"
#include "photorig/daemon/pipelines/nexus_export.h"

#include <cstdio>
#include <filesystem>

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
  ResultFields() = summary.ToJson();
  ResultFields()["run_directory"] = options.run_dir;
  if (!summary.IsSolutionUsable())
    return Fail(summary.termination == solvers::core::Termination::kFailure ? kExitFailed : kExitUsage,
                summary.message);
  std::printf("%s\n", summary.Line().c_str());
  return kExitOk;
}

CLI::App* Setup(CLI::App& app, Options* options) {
  CLI::App* group = SubcommandGroup(app, "export", "write stored data in other tools' formats");
  CLI::App* sub = group->add_subcommand("nexus", "a run and its solves as one NeXus (HDF5) file (docs/nexus.md)");
  sub->add_option("--run", options->run_dir, "run directory")->required()->check(CLI::ExistingDirectory);
  sub->add_option("--out", options->out, "file to write (default: RUN/run.nxs)");
  sub->add_option("--deflate", options->exporting.writer.deflate_level,
                  "zlib level of the frame stack, 0 (stored) .. 9 (default 4)")
      ->check(CLI::Range(0, 9));
  return sub;
}

const bool registered = RegisterCommand<Options, Setup, Execute>();

}  // namespace
}  // namespace photorig::app
