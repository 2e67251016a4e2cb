#include "photorig/daemon/pipelines/brdf_solve.h"
#include "photorig/daemon/pipelines/provenance.h"

#include "photorig/daemon/pipelines/internal/brdf_report.h"
#include "photorig/daemon/pipelines/internal/results_folder.h"
#include "photorig/daemon/capture/run_store.h"
#include "photorig/solvers/brdf/samples.h"
#include "photorig/solvers/core/summary.h"

#include <filesystem>
#include <fstream>

namespace photorig::daemon {

namespace brdf = solvers::brdf;
namespace fs = std::filesystem;

nlohmann::json MeasurementJson(const BrdfMeasurement& m) {
  nlohmann::json clipped = nlohmann::json::array();
  for (const ClippedPose& c : m.clipped)
    clipped.push_back({{"light_arm_deg", c.pose.light_arm_deg},
                       {"camera_arm_deg", c.pose.camera_arm_deg},
                       {"sample_rotation_deg", c.pose.sample_rotation_deg},
                       {"theta_h_deg", c.theta_h_deg},
                       {"shortest_exposure_us", c.shortest_exposure_us}});
  const auto vec = [](const auto& v) { return nlohmann::json{v[0], v[1], v[2]}; };
  nlohmann::json color_model = nullptr;
  if (!m.color_model_path.empty()) {
    color_model = {{"path", m.color_model_path},
                   {"model", m.color_model_kind},
                   {"applied", m.color_model_applied},
                   {"note", m.color_model_note}};
    if (m.color_model_applied) {
      nlohmann::json rows = nlohmann::json::array();
      for (int r = 0; r < 3; ++r) rows.push_back(vec(m.camera_to_linear_srgb.row(r)));
      color_model["camera_to_linear_srgb"] = rows;
    }
  }
  return {{"mosaic", m.mosaic},
          // What the samples' and fits' three channels are.
          {"channels", m.mosaic == "mono" ? "grey" : m.color_model_applied ? "linear_srgb" : "camera"},
          {"color_model", color_model},
          {"pose_frames", m.pose_frames},
          {"dark_frames", m.dark_frames},
          {"reference_frames", m.target_frames},
          {"poses", m.poses},
          {"bracketed_poses", m.bracketed_poses},
          {"samples", m.samples.size()},
          {"clipped_poses", clipped},
          {"peak_clipped", m.peak_clipped},
          {"below_horizon_poses", m.below_horizon},
          {"calibration",
           {{"source", solvers::core::NameOf(BrdfMeasurementOptions::kCalibrationNames, m.calibration)},
            {"dn_per_radiance_per_us", m.dn_per_radiance_per_us},
            {"relative_sigma", m.calibration_relative_sigma},
            {"reference_albedo", m.reference_albedo},
            {"camera_dn_per_radiance_per_us", m.camera_dn_per_radiance_per_us},
            {"channel_dn_per_radiance_per_us", vec(m.channel_dn_per_radiance_per_us)},
            {"channel_relative_sigma", vec(m.channel_calibration_relative_sigma)},
            {"channel_sites", vec(m.channel_sites)}}},
          {"noise",
           {{"read_sigma_dn", m.read_sigma_dn},
            {"read_from", "darks"},
            {"shot_dn_per_dn", m.shot_dn_per_dn},
            {"shot_from", m.shot_estimated ? "repeats" : "camera e_per_dn"},
            {"repeat_sigma_ratio", m.repeat_sigma_ratio},
            {"repeat_dof", m.repeat_dof}}}};
}

std::string BrdfSolveResult::failure() const {
  if (!measurement.IsSolutionUsable()) return measurement.message;
  if (!selection) return "no usable pose frames";
  return selection->IsSolutionUsable() ? std::string() : selection->message;
}

bool BrdfSolveResult::refused_input() const {
  return !measurement.IsSolutionUsable() && measurement.termination != solvers::core::Termination::kFailure;
}

BrdfSolveResult SolveBrdfAndWrite(const std::string& run_dir, const config::BrdfRequest& request, const std::string& out_dir,
                                  FailedCapture failed) {
  const solvers::core::SolveTimer timer;
  BrdfSolveResult result;
  BrdfMeasurementOptions measuring;
  if (!request.calibrate_with_target) measuring.calibration = BrdfMeasurementOptions::Calibration::kCameraResponse;
  const RunManifest manifest = LoadRunManifest(run_dir);
  result.capture = CheckCaptureForSolve(run_dir, manifest, failed);
  result.measurement = MeasureBrdf(run_dir, manifest, measuring);
  const BrdfMeasurement& m = result.measurement;
  result.report = {{"run", run_dir},
                   {"capture", result.capture->ToJson()},
                   {"provenance", MakeProvenance("brdf", run_dir, RequestJson(request),
                                                 {{"accept_failed_capture", failed == FailedCapture::kAccept}})
                                      .ToJson()}};
  if (!m.IsSolutionUsable()) {
    result.total_ms = timer.ElapsedMs();
    return result;
  }
  result.report.update(MeasurementJson(m));
  if (m.samples.empty()) {
    result.total_ms = timer.ElapsedMs();
    return result;
  }
  brdf::SelectionOptions selection;
  selection.fit.loss = request.loss;
  selection.progress = request.progress;
  result.selection = brdf::SelectModel(m.samples, selection);
  result.report.update(SelectionJson(*result.selection));
  // A clipped peak leaves the lobe's height unmeasured: the fit cannot say so itself.
  if (m.peak_clipped) {
    result.warning = "the specular peak was clipped (a pose within " +
                     std::to_string(static_cast<int>(measuring.peak_theta_h_deg)) +
                     " deg of it saturated at every exposure): the lobe's height and width are not measured there; "
                     "capture it with an exposure bracket";
    result.report["warning"] = result.warning;
  }

  ResultsFolder folder(out_dir);
  try {
    std::ofstream report(fs::path(folder.path()) / "report.json");
    report << result.report.dump(2) << "\n";
    report.close();
    if (!report) throw std::runtime_error("writing " + (fs::path(out_dir) / "report.json").string() + " failed");
    const solvers::core::Summary written = brdf::WriteSamplesCsv((fs::path(folder.path()) / "samples.csv").string(), m.samples);
    if (!written.IsSolutionUsable()) throw std::runtime_error(written.message);
    folder.Commit();
  } catch (...) {
    folder.Abandon(std::current_exception());
  }
  result.results = out_dir;
  result.total_ms = timer.ElapsedMs();
  return result;
}

}  // namespace photorig::daemon
