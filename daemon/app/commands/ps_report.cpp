#include "ps_report.h"

#include "photorig/daemon/pipelines/diligent.h"

#include <cstdio>
#include <filesystem>

namespace photorig::app {

void AddAcceptFailedCaptureFlag(CLI::App* solve, bool* accept) {
  solve->add_flag("--accept-failed-capture", *accept,
                  "solve a run whose capture failed or was aborted (refused otherwise); every result and report says so");
}

void AddIntegratorOption(CLI::App* solve, config::PhotometricStereoRequest* request) {
  solve->add_option_function<std::string>(
           "--integrator", [request](const std::string& name) { config::ParseIntegratorChoice(name, &request->integrator); },
           "depth from the normals: poisson (default) | frankot-chellappa | none")
      ->check(CLI::IsMember(config::IntegratorChoices()));
}

std::string StackSource::ResultsDirectory(const std::string& out, const std::string& family) const {
  if (!out.empty()) return out;
  return (std::filesystem::path(from_run() ? run_dir : dataset_dir) / "results" / family).string();
}

daemon::PhotometricStereoInput StackSource::Load(const daemon::ColorStackOptions& color) const {
  return from_run() ? daemon::LoadRunStack(run_dir, color, FailedCapturePolicy(accept_failed_capture))
                    : daemon::LoadDiligent(dataset_dir);
}

void AddStackSourceOptions(CLI::App* solve, StackSource* source) {
  auto* run = solve->add_option("--run", source->run_dir, "run directory")->check(CLI::ExistingDirectory);
  auto* dataset =
      solve->add_option("--dataset", source->dataset_dir, "DiLiGenT-layout folder")->check(CLI::ExistingDirectory);
  run->excludes(dataset);
  AddAcceptFailedCaptureFlag(solve, &source->accept_failed_capture);
}

void WarnOfFailedCapture(const std::optional<daemon::CaptureVerdict>& capture) {
  if (!capture || capture->complete()) return;
  std::printf("warning: solved from a %s capture (--accept-failed-capture); not a measurement to rely on:\n",
              daemon::CaptureStatusName(capture->status));
  for (const std::string& reason : capture->reasons) std::printf("  - %s\n", reason.c_str());
}

void PrintPhotometricStereoSummary(const daemon::PhotometricStereoResult& result) {
  const solvers::ps::SolverSummary& summary = result.summary;
  std::printf("photometric stereo (%s): %s, %zu pixels solved, %.1f ms solve\n", summary.method.c_str(),
              solvers::core::TerminationName(summary.termination), summary.pixels_solved, summary.solve_ms);
  if (!summary.message.empty()) std::printf("  solver says: %s\n", summary.message.c_str());
  if (result.fill && result.fill->pixels_filled + result.fill->pixels_left > 0)
    std::printf("  %s\n", result.fill->BriefReport().c_str());
  if (result.normals_vs_truth) {
    const solvers::ps::AngularErrorStats& gt = *result.normals_vs_truth;
    std::printf("  vs ground truth: mean %.3f deg, median %.3f deg, <5 deg %.1f%%, <10 deg %.1f%%, <15 deg %.1f%%, "
                "%zu of %zu pixels unresolved\n",
                gt.mean_deg, gt.median_deg, 100.0 * gt.fraction_under_5deg, 100.0 * gt.fraction_under_10deg,
                100.0 * gt.fraction_under_15deg, gt.pixels_unresolved, gt.pixels_with_truth);
    if (result.filled_vs_truth)
      std::printf("  ... of which filled from their neighbours: mean %.3f deg, median %.3f deg over %zu pixels\n",
                  result.filled_vs_truth->mean_deg, result.filled_vs_truth->median_deg,
                  result.filled_vs_truth->pixels_evaluated);
  }
  if (result.color) {
    const daemon::ColorProvenance& c = *result.color;
    std::printf("  colour: %s, demosaic %s, albedo in %s%s%s\n", c.mosaic.c_str(), c.demosaic.c_str(),
                c.color_space.c_str(), c.color_model_path.empty() ? "" : " via ", c.color_model_path.c_str());
  }
  if (result.albedo_ciede2000_vs_truth) {
    const auto& e = *result.albedo_ciede2000_vs_truth;
    std::printf("  albedo vs ground truth: CIEDE2000 mean %.2f, median %.2f, 95th percentile %.2f over %d pixels; "
                "inside the paints (5 x 5 from an edge) mean %.2f, 95th percentile %.2f over %d pixels\n",
                e.all.mean, e.all.median, e.all.p95, e.all.pixels, e.interior.mean, e.interior.p95, e.interior.pixels);
  }
}

}  // namespace photorig::app
