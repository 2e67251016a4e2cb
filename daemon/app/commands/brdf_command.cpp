// photorig solve brdf --run DIR [--loss weighted|log] [--calibration reference|camera] [--out DIR]
//   (--json as every command: docs/cli.md)
//
// Gonioreflectometer frames -> BRDF samples (daemon/brdf_measurement.h: the
// bracket merged per pixel, calibrated against the rig's reference target,
// deviations from the sensor's noise model) -> every candidate model fitted
// and the one the data support chosen (solvers/brdf). A grey camera gives
// the same value in all three channels; a colour camera's are its own
// channels, each calibrated against the grey target.

#include "../command.h"
#include "../command_output.h"
#include "brdf_report.h"
#include "photorig/daemon/brdf_measurement.h"
#include "photorig/daemon/run_store.h"
#include "photorig/solvers/brdf/fit.h"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>

namespace photorig::app {
namespace {

namespace brdf = photorig::solvers::brdf;
namespace fs = std::filesystem;

struct Options {
  std::string run_dir, out, loss = "weighted", calibration = "reference";
};

nlohmann::json MeasurementJson(const daemon::BrdfMeasurement& m) {
  nlohmann::json clipped = nlohmann::json::array();
  for (const daemon::ClippedPose& c : m.clipped)
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
           {{"source", m.calibration},
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

int Execute(const Options& options) {
  nlohmann::json doc = {{"run", options.run_dir}};
  // The report is also the command's --json document (main adds command, ok, exit_code).
  auto finish = [&](ExitCode code, const std::string& error) {
    ResultFields() = doc;
    return error.empty() ? static_cast<int>(code) : Fail(code, error);
  };
  brdf::SelectionOptions selection;
  selection.fit.loss = options.loss == "log" ? brdf::FitLoss::kLog : brdf::FitLoss::kWeighted;
  daemon::BrdfMeasurementOptions measuring;
  if (options.calibration == "camera")
    measuring.calibration = daemon::BrdfMeasurementOptions::Calibration::kCameraResponse;
  daemon::BrdfMeasurement m;
  try {
    m = daemon::MeasureBrdf(options.run_dir, daemon::LoadRunManifest(options.run_dir), measuring);
  } catch (const std::exception& e) {  // an unreadable manifest or frame
    return finish(kExitUsage, e.what());
  }
  if (!m.IsSolutionUsable())
    return finish(m.termination == solvers::Termination::kFailure ? kExitFailed : kExitUsage, m.message);
  doc.update(MeasurementJson(m));
  FILE* text = stdout;  // under --json main points it at stderr
  std::fprintf(text, "%zu samples from %d poses (%d frames, %d bracketed), %zu clipped, %d below the horizon\n",
               m.samples.size(), m.poses, m.pose_frames, m.bracketed_poses, m.clipped.size(), m.below_horizon);
  for (const daemon::ClippedPose& c : m.clipped)
    std::fprintf(text, "  clipped: light %+.1f camera %+.1f deg (theta_h %.1f deg) even at %.0f us: no sample\n",
                 c.pose.light_arm_deg, c.pose.camera_arm_deg, c.theta_h_deg, c.shortest_exposure_us);
  if (m.calibration == "reference_target")
    std::fprintf(text, "calibration: reference target of albedo %.3f: %.5g DN per radiance per us +- %.2g %% "
                 "(a scale every f_r shares; the camera states %.5g)\n",
                 m.reference_albedo, m.dn_per_radiance_per_us, 100.0 * m.calibration_relative_sigma,
                 m.camera_dn_per_radiance_per_us);
  else
    std::fprintf(text, "calibration: the camera's stated response, %.5g DN per radiance per us (uncertainty not known)\n",
                 m.dn_per_radiance_per_us);
  if (m.mosaic != "mono") {
    const Eigen::Vector3d& k = m.channel_dn_per_radiance_per_us;
    const Eigen::Vector3d& r = m.channel_calibration_relative_sigma;
    std::fprintf(text, "colour camera (%s): K per channel R %.5g +- %.2g %%, G %.5g +- %.2g %%, B %.5g +- %.2g %% "
                 "from %d/%d/%d sites of the block; f_r per channel\n",
                 m.mosaic.c_str(), k[0], 100.0 * r[0], k[1], 100.0 * r[1], k[2], 100.0 * r[2], m.channel_sites[0],
                 m.channel_sites[1], m.channel_sites[2]);
    if (!m.color_model_path.empty())
      std::fprintf(text, "colour model %s (%s): %s\n", m.color_model_path.c_str(), m.color_model_kind.c_str(),
                   m.color_model_note.c_str());
  }
  std::fprintf(text, "noise: read %.2f DN (from the darks), shot %.4g DN^2 per DN (%s)", m.read_sigma_dn,
               m.shot_dn_per_dn, m.shot_estimated ? "estimated from the repeats" : "from the camera's e_per_dn");
  if (m.repeat_dof > 0)
    std::fprintf(text, "; repeats scatter %.2f x the propagated deviation (%d dof)", m.repeat_sigma_ratio,
                 m.repeat_dof);
  std::fprintf(text, "\n");
  if (m.samples.empty()) return finish(kExitFailed, "no usable pose frames");
  const brdf::SelectionSummary s = brdf::SelectModel(m.samples, selection);
  doc.update(SelectionJson(s));
  // A clipped peak leaves the lobe's height unmeasured: the fit cannot say so itself.
  if (m.peak_clipped)
    doc["warning"] = "the specular peak was clipped (a pose within " +
                     std::to_string(static_cast<int>(measuring.peak_theta_h_deg)) +
                     " deg of it saturated at every exposure): the lobe's height and width are not measured there; "
                     "capture it with an exposure bracket";

  const std::string out = options.out.empty() ? (fs::path(options.run_dir) / "results" / "brdf").string() : options.out;
  fs::create_directories(out);
  std::ofstream(fs::path(out) / "report.json") << doc.dump(2) << "\n";
  const solvers::Summary written = brdf::WriteSamplesCsv((fs::path(out) / "samples.csv").string(), m.samples);
  if (!written.IsSolutionUsable()) return finish(kExitFailed, written.message);
  doc["results"] = out;

  std::fprintf(text, "closest theta_h %.1f deg\n", s.min_theta_h_deg);
  PrintSelection(text, s);
  if (m.peak_clipped) std::fprintf(text, "warning: %s\n", doc["warning"].get<std::string>().c_str());
  std::fprintf(text, "results: %s/\n", out.c_str());
  return finish(s.IsSolutionUsable() ? kExitOk : kExitFailed, s.IsSolutionUsable() ? "" : s.message);
}

CommandRunner Setup(CLI::App& app) {
  auto options = std::make_shared<Options>();
  CLI::App* solve = SubcommandGroup(app, "solve", "run a solver on stored data");
  CLI::App* sub = solve->add_subcommand("brdf", "fit BRDF models to a gonioreflectometer run and choose one");
  sub->add_option("--run", options->run_dir, "run directory")->required()->check(CLI::ExistingDirectory);
  sub->add_option("--loss", options->loss, "weighted (by each sample's deviation, default) | log")
      ->check(CLI::IsMember({"weighted", "log"}));
  sub->add_option("--calibration", options->calibration,
                  "reference (the rig's reference target, default) | camera (the camera's stated response)")
      ->check(CLI::IsMember({"reference", "camera"}));
  sub->add_option("--out", options->out, "output directory (default: RUN/results/brdf)");
  return {sub, [options] { return Execute(*options); }};
}

const bool registered = RegisterCommand(Setup);

}  // namespace
}  // namespace photorig::app
