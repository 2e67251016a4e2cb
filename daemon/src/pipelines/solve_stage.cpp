#include "photorig/daemon/pipelines/solve_stage.h"

#include <filesystem>

namespace photorig::daemon {
namespace fs = std::filesystem;

nlohmann::json SolveStageReport::ToJson() const {
  return {{"stage", stage},     {"ok", usable},           {"termination", termination}, {"message", message},
          {"results", results}, {"figures", figures},     {"timings_ms", timings_ms}};
}

SolveStageReport ReportSolveStage(const PhotometricStereoResult& result) {
  return ReportPhotometricStereoStage(ToJson(result), result.usable());
}

SolveStageReport ReportPhotometricStereoStage(const nlohmann::json& stored, bool usable) {
  SolveStageReport report;
  report.stage = "photometric_stereo";
  report.usable = usable;
  report.termination = stored.value("termination", "");
  report.message = stored.value("message", "");
  report.results = "results/ps";
  const nlohmann::json pixels = stored.value("pixels", nlohmann::json::object());
  report.figures = {{"method", stored.value("method", "")},
                    {"lights", stored.value("lights", 0)},
                    {"pixels_solved", pixels.value("solved", 0)},
                    {"pixels_total", pixels.value("total", 0)}};
  if (stored.contains("mean_confidence")) report.figures["mean_confidence"] = stored["mean_confidence"];
  if (stored.contains("ground_truth")) {
    report.figures["normals_vs_truth_mean_deg"] = stored["ground_truth"].value("mean_angular_error_deg", 0.0);
    report.figures["normals_vs_truth_median_deg"] = stored["ground_truth"].value("median_angular_error_deg", 0.0);
  }
  if (stored.contains("depth") && stored["depth"].contains("rms_error_vs_truth"))
    report.figures["depth_rms_vs_truth"] = stored["depth"]["rms_error_vs_truth"];
  const nlohmann::json timings = stored.value("timings_ms", nlohmann::json::object());
  report.timings_ms = {{"setup", timings.value("setup", 0.0)},
                       {"solve", timings.value("solve", 0.0)},
                       {"total", timings.value("total", 0.0)}};
  return report;
}

SolveStageReport ReportSolveStage(const LightCalibrationSummary& summary, const std::string& run_directory,
                                  double total_ms) {
  SolveStageReport report;
  report.stage = "light_calibration";
  report.usable = summary.success;
  report.termination = summary.success ? "success" : "failure";
  report.message = summary.message;
  report.results = "results/lights";
  report.figures = {{"lights", summary.lights},
                    {"unusable", summary.unusable},
                    {"mean_uncertainty_deg", summary.mean_uncertainty_deg},
                    {"sphere_source", summary.sphere_source},
                    {"sphere_fit_rms_px", summary.sphere_fit_rms_px}};
  // A rig written inside the run is named relative to it, like the results.
  if (!summary.out_rig.empty()) {
    const fs::path relative = fs::path(summary.out_rig).lexically_proximate(run_directory);
    report.figures["out_rig"] = relative.empty() || *relative.begin() == ".." ? summary.out_rig : relative.string();
  }
  report.timings_ms = {{"total", total_ms}};
  return report;
}

SolveStageReport ReportSolveStage(const TomographyResult& result) {
  SolveStageReport report;
  report.stage = "tomography";
  report.usable = result.trusted();
  report.termination = solvers::core::TerminationName(result.reconstruction.termination);
  report.message = result.reconstruction.message;
  report.results = "results/tomography";
  report.figures = {{"method", solvers::tomography::MethodName(result.reconstruction.method)},
                    {"views", result.geometry.views()},
                    {"iterations", result.reconstruction.iterations},
                    {"stop_reason", solvers::tomography::StopReasonName(result.reconstruction.stop_reason)},
                    {"volume", {result.grid.nx, result.grid.ny, result.grid.nz}}};
  if (result.relative_error_vs_truth) report.figures["relative_error_vs_truth"] = *result.relative_error_vs_truth;
  report.timings_ms = {{"setup", result.reconstruction.setup_ms},
                       {"solve", result.reconstruction.solve_ms},
                       {"total", result.total_ms}};
  return report;
}

SolveStageReport ReportSolveStage(const BrdfSolveResult& result) {
  SolveStageReport report;
  report.stage = "brdf";
  report.usable = result.usable();
  const solvers::core::Summary& ended =
      result.selection ? static_cast<const solvers::core::Summary&>(*result.selection) : result.measurement;
  report.termination = result.selection || !result.measurement.IsSolutionUsable()
                           ? solvers::core::TerminationName(ended.termination)
                           : solvers::core::TerminationName(solvers::core::Termination::kFailure);
  report.message = result.usable() ? (result.warning.empty() ? result.selection->message : result.warning)
                                   : result.failure();
  report.results = result.results.empty() ? "" : "results/brdf";
  const BrdfMeasurement& m = result.measurement;
  report.figures = {{"samples", m.samples.size()}, {"poses", m.poses}, {"clipped_poses", m.clipped.size()},
                    {"peak_clipped", m.peak_clipped}};
  if (result.selection && result.selection->chosen) {
    const solvers::brdf::FitSummary& chosen = result.selection->candidates[result.selection->chosen_index];
    report.figures["chosen"] = solvers::brdf::ModelName(*result.selection->chosen);
    report.figures["held_out_rms"] = chosen.held_out_rms;
  }
  report.timings_ms = {{"measure", m.total_ms},
                       {"fit", result.selection ? result.selection->total_ms : 0.0},
                       {"total", result.total_ms}};
  return report;
}

SolveStageReport ReportSolveStage(const SvbrdfResult& result) {
  SolveStageReport report;
  report.stage = "svbrdf";
  report.usable = result.usable();
  report.termination = solvers::core::TerminationName(result.summary.termination);
  report.message = result.summary.message;
  report.results = "results/svbrdf";
  nlohmann::json models = nlohmann::json::array();
  for (const auto& m : result.material_fits) models.push_back(solvers::brdf::ModelName(m.model));
  report.figures = {{"pixels_fitted", result.summary.pixels_fitted},
                    {"pixels_mixed", result.summary.pixels_mixed},
                    {"materials", result.summary.materials},
                    {"models", models},
                    {"gltf", !result.gltf_path.empty()}};
  if (result.relighting && result.relighting->IsSolutionUsable())
    for (int m = 0; m < 3; ++m)
      report.figures[std::string("held_out_rmse_") + solvers::reflectance::MethodName(static_cast<solvers::reflectance::Method>(m))] =
          result.relighting->mean_rmse[m];
  report.timings_ms = {{"setup", result.summary.setup_ms}, {"solve", result.summary.solve_ms}, {"total", result.total_ms}};
  return report;
}

}  // namespace photorig::daemon
