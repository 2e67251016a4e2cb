#include "photorig/daemon/pipelines/solve_stage.h"

#include <chrono>
#include <filesystem>
#include <utility>

namespace photorig::daemon {
namespace fs = std::filesystem;

nlohmann::json SolveStageReport::ToJson() const {
  return {{"stage", stage},     {"ok", usable},           {"termination", termination}, {"message", message},
          {"results", results}, {"figures", figures},     {"timings_ms", timings_ms}};
}

namespace {

// What every stage's report opens with; the figures and timings are its own.
SolveStageReport StageReport(SolveStageKind kind, bool usable, std::string termination, std::string message,
                             std::string results) {
  SolveStageReport report;
  report.stage = SolveStageName(kind);
  report.usable = usable;
  report.termination = std::move(termination);
  report.message = std::move(message);
  report.results = std::move(results);
  return report;
}

}  // namespace

SolveStageReport ReportPhotometricStereoStage(const nlohmann::json& stored, bool usable) {
  SolveStageReport report = StageReport(SolveStageKind::kPhotometricStereo, usable, stored.value("termination", ""),
                                        stored.value("message", ""), "results/ps");
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

namespace {

// A rig written inside the run is named relative to it, like the results.
std::string RigInRun(const std::string& out_rig, const std::string& run_directory) {
  const fs::path relative = fs::path(out_rig).lexically_proximate(run_directory);
  return relative.empty() || *relative.begin() == ".." ? out_rig : relative.string();
}

// A calibration stage's report: success or failure, and the rig it wrote.
SolveStageReport CalibrationReport(SolveStageKind kind, bool success, const std::string& message, const char* results,
                                   const std::string& out_rig, const std::string& run_directory, double total_ms) {
  SolveStageReport report = StageReport(kind, success, success ? "success" : "failure", message, results);
  report.figures = nlohmann::json::object();
  if (!out_rig.empty()) report.figures["out_rig"] = RigInRun(out_rig, run_directory);
  report.timings_ms = {{"total", total_ms}};
  return report;
}

SolveStageReport Report(const LightCalibrationSummary& summary, const std::string& run_directory, double total_ms) {
  SolveStageReport report = CalibrationReport(SolveStageKind::kLightCalibration, summary.success, summary.message,
                                              "results/lights", summary.out_rig, run_directory, total_ms);
  report.figures.update(nlohmann::json{{"lights", summary.lights},
                                       {"unusable", summary.unusable},
                                       {"mean_uncertainty_deg", summary.mean_uncertainty_deg},
                                       {"sphere_source", SphereSourceName(summary.sphere_source)},
                                       {"sphere_fit_rms_px", summary.sphere_fit_rms_px}});
  return report;
}

SolveStageReport Report(const LedPositionCalibration& result, const std::string& run_directory, double total_ms) {
  SolveStageReport report = CalibrationReport(SolveStageKind::kLedPositions, result.success, result.message,
                                              "results/leds", result.out_rig, run_directory, total_ms);
  report.figures.update(nlohmann::json{{"leds", result.solve.leds.size()},
                                       {"unusable", result.solve.unusable},
                                       {"mean_rms_ray_distance_mm", result.solve.mean_rms_ray_distance_mm},
                                       {"mean_shift_mm", result.mean_shift_mm},
                                       {"max_shift_mm", result.max_shift_mm}});
  if (result.mean_error_mm >= 0.0) {
    report.figures["positions_vs_truth_mean_mm"] = result.mean_error_mm;
    report.figures["positions_vs_truth_max_mm"] = result.max_error_mm;
  }
  return report;
}

SolveStageReport Report(const TomographyResult& result) {
  SolveStageReport report = StageReport(SolveStageKind::kTomography, result.trusted(),
                                        solvers::core::TerminationName(result.reconstruction.termination),
                                        result.reconstruction.message, "results/tomography");
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

SolveStageReport Report(const BrdfSolveResult& result) {
  const solvers::core::Summary& ended =
      result.selection ? static_cast<const solvers::core::Summary&>(*result.selection) : result.measurement;
  const solvers::core::Termination termination = result.selection || !result.measurement.IsSolutionUsable()
                                                     ? ended.termination
                                                     : solvers::core::Termination::kFailure;
  const std::string message =
      result.usable() ? (result.warning.empty() ? result.selection->message : result.warning) : result.failure();
  SolveStageReport report = StageReport(SolveStageKind::kBrdf, result.usable(), solvers::core::TerminationName(termination),
                                        message, result.results.empty() ? "" : "results/brdf");
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

SolveStageReport Report(const SvbrdfResult& result) {
  SolveStageReport report = StageReport(SolveStageKind::kSvbrdf, result.usable(),
                                        solvers::core::TerminationName(result.summary.termination),
                                        result.summary.message, "results/svbrdf");
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


double MillisecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

fs::path ResultsOf(const StageContext& context, const char* name) {
  return fs::path(context.run_directory) / "results" / name;
}

// A stage's results folder, for stages that write into it as they go rather
// than replacing it whole as they end (results_folder.h): emptied first, so
// it holds only what this solve wrote (a run resumed after a crash mid-solve
// solves again from the frames).
fs::path FreshResults(const StageContext& context, const char* name) {
  const fs::path results = ResultsOf(context, name);
  fs::remove_all(results);
  return results;
}

// The request a stage hands its solver: the recipe's, listening to the run's progress.
template <typename Request>
Request WithProgress(Request request, const StageContext& context) {
  request.progress = context.progress;
  return request;
}

SolveStageReport RunPhotometricStereo(const config::PhotometricStereoRequest& request, const StageContext& context,
                                      SolveResults* results) {
  const PhotometricStereoResult& result = results->photometric_stereo.emplace(SolvePhotometricStereoRun(
      context.run_directory, WithProgress(request, context), ResultsOf(context, "ps").string()));
  return ReportPhotometricStereoStage(ToJson(result), result.usable());
}

// A calibration stage's folder, emptied, and its request: based on the run's
// rig, writing the new one into the folder unless the recipe names another.
template <typename Request>
fs::path PrepareCalibration(const StageContext& context, const char* name, Request* request) {
  const fs::path folder = FreshResults(context, name);
  request->base_rig = context.rig_path;
  if (request->out_rig.empty()) request->out_rig = (folder / "rig.yaml").string();
  return folder;
}

SolveStageReport RunLightCalibration(config::LightCalibrationRequest calibration, const StageContext& context,
                                     SolveResults* results) {
  const auto started = std::chrono::steady_clock::now();
  const fs::path folder = PrepareCalibration(context, "lights", &calibration);
  const LightCalibrationSummary& summary = results->light_calibration.emplace(
      CalibrateLights(LoadLightCalibrationInputs(context.run_directory), calibration, folder.string()));
  return Report(summary, context.run_directory, MillisecondsSince(started));
}

SolveStageReport RunLedPositions(config::LedPositionRequest request, const StageContext& context, SolveResults* results) {
  const auto started = std::chrono::steady_clock::now();
  const fs::path folder = PrepareCalibration(context, "leds", &request);
  const LedPositionCalibration& result = results->led_positions.emplace(
      CalibrateLedPositions(LoadLedPositionInputs(context.run_directory), request, folder.string()));
  return Report(result, context.run_directory, MillisecondsSince(started));
}

SolveStageReport RunTomography(const config::TomographyRequest& request, const StageContext& context,
                               SolveResults* results) {
  const TomographyInput input = LoadTomographyRun(context.run_directory);
  const TomographyResult& result = results->tomography.emplace(SolveTomography(input, WithProgress(request, context)));
  WriteTomographyResults(input, result, ResultsOf(context, "tomography").string());
  return Report(result);
}

SolveStageReport RunSvbrdf(const config::SvbrdfRequest& request, const StageContext& context, SolveResults* results) {
  return Report(results->svbrdf.emplace(SolveSvbrdfAndWrite(LoadRunStack(context.run_directory),
                                                            WithProgress(request, context),
                                                            ResultsOf(context, "svbrdf").string())));
}

SolveStageReport RunBrdf(const config::BrdfRequest& request, const StageContext& context, SolveResults* results) {
  return Report(results->brdf.emplace(
      SolveBrdfAndWrite(context.run_directory, WithProgress(request, context), ResultsOf(context, "brdf").string())));
}

// A stage that runs `run` on its copy of `request`.
template <typename Request, typename Run>
SolveStage MakeStage(SolveStageKind kind, const char* command, const Request& request, Run run) {
  return SolveStage(kind, command, [request, run](const StageContext& context, SolveResults* results) {
    return run(request, context, results);
  });
}

}  // namespace

std::vector<SolveStage> StagesOf(const config::Recipe& recipe) {
  std::vector<SolveStage> stages;
  using Kind = SolveStageKind;
  if (recipe.photometric_stereo)
    stages.push_back(MakeStage(Kind::kPhotometricStereo, "solve ps", *recipe.photometric_stereo, RunPhotometricStereo));
  if (recipe.light_calibration)
    stages.push_back(MakeStage(Kind::kLightCalibration, "calibrate lights", *recipe.light_calibration, RunLightCalibration));
  if (recipe.led_positions)
    stages.push_back(MakeStage(Kind::kLedPositions, "calibrate leds", *recipe.led_positions, RunLedPositions));
  if (recipe.tomography) stages.push_back(MakeStage(Kind::kTomography, "solve tomography", *recipe.tomography, RunTomography));
  if (recipe.svbrdf) stages.push_back(MakeStage(Kind::kSvbrdf, "solve svbrdf", *recipe.svbrdf, RunSvbrdf));
  if (recipe.brdf) stages.push_back(MakeStage(Kind::kBrdf, "solve brdf", *recipe.brdf, RunBrdf));
  return stages;
}

}  // namespace photorig::daemon
