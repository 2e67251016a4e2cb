// photorig solve tomography (--run DIR [--accept-failed-capture] | --projections DIR) [--method sirt|art|cgls|sart] [--tv] [--projector joseph|siddon]
//                           [--max-iterations N] [--volume NX NY NZ] [--voxel-mm MM] [--cor-offset-mm MM]
//                           [--ring-filter] [--no-held-out] [--out DIR]
//
// A turntable scan's frames -> absorbance (flats and darks) -> optionally the
// ring filter -> the centre of rotation estimated from the data (unless
// --cor-offset-mm gives it) -> a volume by SIRT, ART, CGLS or SART
// (optionally with total variation) stopped by the discrepancy rule, and the
// held-out-angle residual as its quality figure (docs/tomography.md);
// volume.nrrd and, where built with OpenVDB, volume.vdb.
// Exit 0 when the rule stopped it; 1 when the solve failed or cannot be
// trusted (the residual never reached the noise level, inconsistent data);
// 2 for missing flats or darks or a geometry that does not fit the frames.
// With --mpi, under `mpirun -np N`, the views and slabs of the volume are
// shared by the N processes (solvers/tomography_mpi; --mpi-slabs S: N / S
// groups of views x S slabs); the first writes the results.

#include "../command.h"
#include "../command_output.h"
#include "../progress_display.h"
#include "photorig/config/recipe.h"
#include "photorig/config/solve_requests.h"
#include "photorig/daemon/pipelines/tomography_pipeline.h"
#include "ps_report.h"

#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <utility>

#if PHOTORIG_HAVE_TOMOGRAPHY_MPI
#include "photorig/solvers/tomography_mpi/distributed_projector.h"
#endif

namespace photorig::app {
namespace {

namespace fs = std::filesystem;

struct Options {
  std::string run_dir, projections_dir, out;
  std::vector<int> volume;
  bool mpi = false;
  int mpi_slabs = 0;  // 0: chosen from the volume's size (DecompositionOptions)
  bool accept_failed_capture = false;
  config::TomographyRequest request;
  double cor_offset_mm = 0.0;  // with --cor-offset-mm only
  CLI::Option* cor_offset_option = nullptr;
  bool no_held_out = false;
};

int Execute(const Options& options) {
  if (options.run_dir.empty() && options.projections_dir.empty())
    return Fail(kExitUsage, "give --run DIR or --projections DIR");
  config::TomographyRequest request = options.request;
  request.iteration_limit_name = "--max-iterations";
  if (options.cor_offset_option->count() > 0) request.cor_offset_mm = options.cor_offset_mm;
  // Under --mpi the held-out solve would run whole in every process.
  request.held_out = !options.no_held_out && !options.mpi;
  if (!options.volume.empty()) request.volume = {options.volume[0], options.volume[1], options.volume[2]};
  if (std::string why; !request.IsValid(&why)) return Fail(kExitUsage, why);
  const bool from_run = !options.run_dir.empty();
  const std::string source = from_run ? options.run_dir : options.projections_dir;
  const std::string destination =
      options.out.empty() ? (fs::path(source) / "results" / "tomography").string() : options.out;
  daemon::SystemMatrixFactory factory = daemon::InProcessSystemMatrix();
  int ranks = 1;
  std::optional<std::pair<int, int>> view_groups_and_slabs;
#if PHOTORIG_HAVE_TOMOGRAPHY_MPI
  // Under mpirun: every process loads the scan and solves its block of views;
  // the first writes the results and speaks for all.
  std::optional<solvers::tomography_mpi::Session> session;
  if (options.mpi) {
    session.emplace(nullptr, nullptr);
    ranks = session->size();
    if (session->rank() != 0) SilenceOutput();
    solvers::tomography_mpi::DecompositionOptions decomposition;
    decomposition.slabs = options.mpi_slabs;
    if (std::string why; !decomposition.IsValid(&why)) return Fail(kExitUsage, "--mpi-slabs: " + why);
    // Known before any work (the centre's search reconstructs whole in every process).
    if (decomposition.slabs > 0 && ranks % decomposition.slabs != 0)
      return Fail(kExitUsage, "--mpi-slabs: " + std::to_string(ranks) + " processes cannot hold " +
                                  std::to_string(decomposition.slabs) +
                                  " slabs: the processes are view groups x slabs, so the slabs must divide them");
    factory = [decomposition, &view_groups_and_slabs](
                  const solvers::tomography::VolumeGrid& grid, const solvers::tomography::Geometry& geometry,
                  const solvers::tomography::ProjectorOptions& projector_options,
                  std::unique_ptr<solvers::tomography::SystemMatrix>* matrix, std::int64_t* first_ray) {
      solvers::tomography::ProjectorSummary summary = solvers::tomography_mpi::MakeDistributedProjector(
          grid, geometry, projector_options, decomposition, MPI_COMM_WORLD, matrix, first_ray);
      if (summary.IsSolutionUsable()) {
        const auto& used = static_cast<const solvers::tomography_mpi::DistributedProjector&>(**matrix).decomposition();
        view_groups_and_slabs = {used.view_groups, used.slabs};
      }
      return summary;
    };
    // Only the simultaneous iterations run on distributed products and sums.
    using solvers::tomography::Method;
    if (request.method != Method::kSirt && request.method != Method::kCgls)
      return Fail(kExitUsage, std::string("--mpi solves by sirt or cgls, not ") + solvers::tomography::MethodName(request.method) +
                                  (request.method == Method::kArt ? " (ART visits one ray at a time)" : ""));
  }
  const bool writes = !session || session->rank() == 0;
#else
  if (options.mpi) return Fail(kExitUsage, "this photorig was built without MPI (libopenmpi-dev): no --mpi");
  const bool writes = true;
#endif
  if (!options.mpi && options.mpi_slabs != 0) return Fail(kExitUsage, "--mpi-slabs needs --mpi");
  const daemon::TomographyInput input =
      from_run ? daemon::LoadTomographyRun(source, FailedCapturePolicy(options.accept_failed_capture))
               : daemon::LoadProjectionFolder(source);

  ProgressDisplay progress;
  request.progress = progress.Callback();
  const daemon::TomographyResult result = daemon::SolveTomography(input, request, factory);
  progress.EndLine();
  if (writes) daemon::WriteTomographyResults(input, result, destination);

  const solvers::tomography::ReconstructionSummary& r = result.reconstruction;
  std::printf("tomography (%s, %s): %s, %d views, %d x %d x %d voxels of %.3g mm\n", solvers::tomography::MethodName(r.method),
              solvers::tomography::InterpolationName(request.projector), solvers::core::TerminationName(r.termination), result.geometry.views(),
              result.grid.nx, result.grid.ny, result.grid.nz, result.grid.voxel_mm);
  if (r.iterations > 0 && result.stopped_by_held_out)
    std::printf("  %d iterations, where the held-out-angle residual was lowest (no noise estimate: fewer than two flats "
                "or darks)\n",
                r.iterations);
  else if (r.iterations > 0)
    std::printf("  %d iterations, stopped by %s: residual %.4g against the noise level %.4g\n", r.iterations,
                solvers::tomography::StopReasonName(r.stop_reason), r.residual_history.back(), r.discrepancy_target);
  if (!r.message.empty()) std::printf("  %s\n", r.message.c_str());
  const double pixel_mm = result.geometry.pixel_mm;
  if (result.cor && result.cor->IsSolutionUsable())
    std::printf("  centre of rotation %+.3f px (%+.4g mm) +- %.3f px, estimated by %s%s%s\n",
                result.geometry.cor_offset_mm / pixel_mm, result.geometry.cor_offset_mm, result.cor->offset_sigma_mm / pixel_mm,
                solvers::tomography::CorMethodName(result.cor->method), result.cor->message.empty() ? "" : ": ",
                result.cor->message.c_str());
  else if (!result.cor)
    std::printf("  centre of rotation %+.3f px (%+.4g mm), as given\n", result.geometry.cor_offset_mm / pixel_mm,
                result.geometry.cor_offset_mm);
  if (result.ring_filter)
    std::printf("  ring filter: %d stripes, largest offset %.3g in b\n", result.ring_filter->stripes, result.ring_filter->max_offset);
  if (result.held_out) {
    if (result.held_out->IsSolutionUsable())
      std::printf("  held-out-angle residual %.4f (noise floor %.4f): %d views reconstructed, %d predicted\n",
                  result.held_out->relative_residual, result.held_out->noise_floor, result.held_out->fit_views,
                  result.held_out->held_out_views);
    else
      std::printf("  no held-out-angle residual: %s\n", result.held_out->message.c_str());
  }
  if (result.absorbance.flagged() > 0)
    std::printf("  %lld of %lld pixels flagged by the absorbance (saturated, dark or without flat signal)\n",
                static_cast<long long>(result.absorbance.flagged()), static_cast<long long>(result.absorbance.rays));
  if (result.relative_error_vs_truth)
    std::printf("  vs the phantom: relative L2 error %.3f\n", *result.relative_error_vs_truth);
  std::printf("  %.0f ms (absorbance %.0f, projector %.0f, solve %.0f)\n", result.total_ms, result.absorbance_ms,
              result.projector.total_ms, r.solve_ms);
  WarnOfFailedCapture(result.capture);

  ResultFields() = result.ToJson();
  ResultFields()["source"] = source;
  ResultFields()["processes"] = ranks;
  if (view_groups_and_slabs) {
    ResultFields()["view_groups"] = view_groups_and_slabs->first;
    ResultFields()["slabs"] = view_groups_and_slabs->second;
  }
  ReportResultsDirectory(destination);
  if (!result.trusted())
    return Fail(kExitFailed, r.IsSolutionUsable() ? "the reconstruction cannot be trusted: " + r.message
                                                  : "no usable reconstruction: " + r.message);
  return kExitOk;
}

CLI::App* Setup(CLI::App& app, Options* options) {
  CLI::App* sub = SolveGroup(app)->add_subcommand(
      "tomography", "reconstruct a volume from a turntable scan (run or projection folder)");
  auto* run = sub->add_option("--run", options->run_dir, "run directory")->check(CLI::ExistingDirectory);
  auto* folder = sub->add_option("--projections", options->projections_dir,
                                 "folder with geometry.json, projections/, flats/, darks/ (docs/tomography.md)")
                     ->check(CLI::ExistingDirectory);
  run->excludes(folder);
  AddAcceptFailedCaptureFlag(sub, &options->accept_failed_capture);
  AddChoice(sub, "--method", &options->request.method, solvers::tomography::kMethodNames, "reconstruction method");
  sub->add_flag("--tv", options->request.total_variation,
                "SART with total-variation regularisation: for piecewise-constant samples (docs/tomography.md)");
  AddChoice(sub, "--projector", &options->request.projector, solvers::tomography::kInterpolationNames,
            "how rays sample the voxels");
  sub->add_option("--max-iterations", options->request.max_iterations, "iteration limit (default 300)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--discrepancy-factor", options->request.discrepancy_factor,
                  "stop when the residual reaches this times the noise level (default 1.2)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--volume", options->volume, "voxels NX NY NZ (default: detector columns, columns, rows)")
      ->expected(3);
  sub->add_option("--voxel-mm", options->request.voxel_mm, "voxel size (default: the detector pitch)")
      ->check(CLI::NonNegativeNumber);
  options->cor_offset_option =
      sub->add_option("--cor-offset-mm", options->cor_offset_mm,
                      "centre of rotation on the detector, added to the stored geometry's (default: estimated from the data)");
  sub->add_flag("--ring-filter", options->request.ring_filter,
                "remove detector-column stripes from the sinogram (ring artefacts)");
  sub->add_flag("--no-held-out", options->no_held_out,
                "skip the held-out-angle residual (a second solve of half the views)");
  sub->add_option("--out", options->out, "output directory (default: SOURCE/results/tomography)");
  sub->add_flag("--mpi", options->mpi,
                "distribute the views and slabs of the volume over the MPI processes this runs in (under mpirun; "
                "sirt or cgls)");
  sub->add_option("--mpi-slabs", options->mpi_slabs,
                  "with --mpi: slabs of the volume along z; the processes are view groups x slabs "
                  "(default 0: views alone when one process's volume vectors fit 4 GiB, "
                  "else the fewest slabs that fit)")
      ->check(CLI::NonNegativeNumber);
  return sub;
}

const bool registered = RegisterCommand<Options, Setup, Execute>();

}  // namespace
}  // namespace photorig::app
