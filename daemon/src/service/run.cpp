#include "photorig/daemon/service/run.h"
#include "photorig/daemon/pipelines/internal/phantom_json.h"

#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/io/utc_time.h"
#include "photorig/daemon/capture/plan.h"
#include "photorig/daemon/pipelines/ps_pipeline.h"
#include "photorig/daemon/pipelines/internal/results_folder.h"
#include "photorig/daemon/capture/internal/rig_devices.h"
#include "photorig/daemon/service/internal/slurm_solve.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cstdio>
#include <functional>
#include <filesystem>

namespace photorig::daemon {
namespace fs = std::filesystem;

namespace {

// The recipe's solve: its stages on the stored frames, in order, reported as
// they start and end. Photometric stereo goes to Slurm when the recipe's (or
// the rig's) solve executor says so; every other stage runs here.
void SolveStages(const RunRequest& request, const config::Recipe& recipe, const config::RigConfig& rig, RunOutcome* outcome) {
  const StageContext context{outcome->directory, rig.path, request.solve_progress};
  bool first = true;
  for (const SolveStage& stage : StagesOf(recipe)) {
    // An abort that arrived during the previous stage skips the rest.
    if (request.control && request.control->abort_requested()) return;
    if (first && request.on_state) request.on_state(RunState::kSolving, stage.name());
    first = false;
    if (request.on_solve_started) request.on_solve_started(stage.name());
    SolveStageReport report;
    if (stage.kind() == SolveStageKind::kPhotometricStereo && recipe.solve_executor.executor == config::Executor::kSlurm) {
      const SlurmSolveOutcome submitted =
          SolvePhotometricStereoOnSlurm(outcome->directory, *recipe.photometric_stereo, recipe.solve_executor, request);
      if (!submitted.report) {
        // The daemon is stopping: the run goes back to the queue, and the next start follows the same job.
        outcome->capture.status = CaptureStatus::kAborted;
        outcome->capture.reason = "stopped while Slurm job " + submitted.job_id + " solves; followed again at the next start";
        return;
      }
      report = *submitted.report;
    } else {
      try {
        report = stage.Run(context, outcome);
      } catch (const ResultsWriteError& e) {
        // The frames are stored, so only the solve is repeated.
        throw std::runtime_error(std::string(e.what()) + "; the captured frames are intact: `photorig " + stage.command() +
                                 " --run " + outcome->directory + "` solves again");
      }
    }
    spdlog::info("solve {}: {}{}{}", report.stage, report.termination, report.message.empty() ? "" : ": ", report.message);
    if (request.on_solve_finished) request.on_solve_finished(report);
    outcome->solve_stages.push_back(std::move(report));
  }
}

}  // namespace

nlohmann::json ToJson(const CaptureReport& capture) {
  return {{"status", CaptureStatusName(capture.status)}, {"reason", capture.reason},
          {"frames_written", capture.frames_written},      {"steps_total", capture.steps_total},
          {"retries", capture.retries},                     {"dropped_frames", capture.dropped_frames},
          {"elapsed_ms", capture.elapsed_ms}};
}

RunManifest ManifestHeaderFor(const config::RigConfig& rig) {
  RunManifest header;
  header.rig_path = rig.path;
  header.rig_name = rig.name;
  header.camera_id = rig.camera.id;
  header.width = rig.camera.width;
  header.height = rig.camera.height;
  header.bit_depth = rig.camera.bit_depth;
  header.saturation_dn = rig.health.saturation_dn;
  header.dn_per_radiance_per_us = rig.camera.dn_per_radiance_per_us;
  header.e_per_dn = rig.camera.e_per_dn;
  header.pixel_pitch_mm = rig.camera.pixel_pitch_mm;
  header.projection = rig.camera.projection;
  header.pinhole = rig.camera.pinhole;
  header.mosaic = rig.camera.mosaic;
  header.pixel_format = rig.camera.pixel_format;
  if (rig.camera.color_model) {
    header.color_model_path = fs::absolute(rig.camera.color_model->path).lexically_normal().string();
    header.color_model_hash = rig.camera.color_model->content_hash;
  }
  header.lights = rig.lights.leds;
  if (rig.reference_target) header.reference_albedo = rig.reference_target->albedo;
  return header;
}

RunOutcome ExecuteRun(const RunRequest& request) {
  const config::RigConfig rig = config::LoadRigConfig(config::RecipeRigPath(request.recipe_path, request.rig_path));
  const config::Recipe recipe = config::LoadRecipe(request.recipe_path, rig);
  const std::vector<config::CaptureStep> steps = config::CompileSteps(recipe, rig);
  const RunPlan plan = PlanRun(recipe, rig, steps);
  if (!plan.ok()) {
    std::string why;
    for (const std::string& error : plan.errors) why += "\n  " + error;
    throw std::runtime_error("recipe " + recipe.path + " refused before any device was touched:" + why);
  }
  // A run never goes into another run's folder (or any folder with files): a usage error, found before the devices.
  if (!request.resume && !request.output_directory.empty() && fs::exists(request.output_directory) &&
      !fs::is_empty(request.output_directory))
    throw std::invalid_argument("run directory " + request.output_directory +
                                " already exists and is not empty; name a new one (photorig run --out DIR) or remove it");
  RigDevices devices = MakeRigDevices(rig, &recipe);

  RunOutcome outcome;
  outcome.directory = request.output_directory.empty() ? (fs::path("runs") / (recipe.name + "-" + UtcNowInName())).string()
                                                       : request.output_directory;
  RunManifest header = ManifestHeaderFor(rig);
  header.run_id = fs::path(outcome.directory).filename().string();
  header.recipe_path = recipe.path;
  header.recipe_name = recipe.name;
  for (const SolveStage& stage : StagesOf(recipe)) header.solve_stages.push_back(stage.name());
  header.sample_name = recipe.sample_name;
  std::unique_ptr<RunWriter> writer_storage;
  if (request.resume) {
    writer_storage = RunWriter::Reopen(outcome.directory, &outcome.recovery);
    spdlog::info("run {}: resuming with {} frames on disk ({} discarded, {} stray files removed{})", header.run_id,
                 outcome.recovery.frames_kept, outcome.recovery.frames_discarded,
                 outcome.recovery.removed_files.size(), outcome.recovery.journal_tail_torn ? ", torn journal line cut" : "");
  }
  const std::uint64_t needed = plan.estimate.bytes - std::min<std::uint64_t>(plan.estimate.bytes,
      writer_storage ? writer_storage->manifest().frames.size() * plan.estimate.bytes_per_frame : 0);
  const std::uint64_t free_bytes = FreeBytes(outcome.directory);
  if (free_bytes < needed)
    throw std::runtime_error("not enough free space for " + outcome.directory + ": the run needs about " +
                             std::to_string(needed >> 20) + " MiB, " + std::to_string(free_bytes >> 20) + " MiB free");
  if (!writer_storage) writer_storage = std::make_unique<RunWriter>(outcome.directory, header);
  RunWriter& writer = *writer_storage;
  if (devices.world && !writer.manifest().has_ground_truth) {
    const sim::SurfaceMaps& truth = devices.world->surface();
    const sim::Scene& scene = devices.world->config().scene;
    if (scene.shape == sim::Scene::Shape::kPhantom)
      writer.WriteVolumeGroundTruth(cv::Mat(), PhantomToJson(scene.phantom).dump(2) + "\n");
    else if (scene.shape == sim::Scene::Shape::kVolume)
      writer.WriteVolumeGroundTruth(truth.line_integrals, "");
    else
      writer.WriteGroundTruth(truth, devices.world->config().lights, devices.world->TruthColorAlbedo());
  }

  spdlog::info("run {}: recipe {} on rig {} ({} steps) -> {}", header.run_id, recipe.name, rig.name, steps.size(),
               outcome.directory);
  CaptureOptions options;
  options.stop_requested = request.stop_requested;
  options.control = request.control;
  options.retry = request.retry;
  options.on_state = request.on_state;
  options.trigger_output = devices.trigger.get();
  options.health = rig.health;
  options.leds = rig.lights.leds;
  if (rig.motion) {
    options.motion = &devices.motion;
    options.motion_profile = rig.motion->profile;
  }
  options.on_frame = [&request, &writer](const config::CaptureStep& step, const FrameRecord& record, int total) {
    if (request.on_frame) request.on_frame(step, record, static_cast<int>(writer.manifest().frames.size()), total);
  };
  std::optional<AdaptivePoses> adaptive;
  if (const config::Recipe::Group* group = config::AdaptivePlanGroup(recipe)) {
    adaptive.emplace(recipe, *group, rig);
    options.next_pass = [&](const std::vector<config::CaptureStep>& so_far, std::size_t ended, const RunWriter& run) {
      CaptureOptions::AddedSteps added = adaptive->NextPass(so_far, ended, run);
      if (request.on_adaptive_pass && adaptive->passes().size() > outcome.adaptive_passes.size())
        request.on_adaptive_pass(adaptive->passes().back());
      outcome.adaptive_passes = adaptive->passes();
      return added;
    };
  }
  outcome.capture = RunCapture(steps, rig.camera, *devices.lights, *devices.camera, writer, options);
  if (adaptive) {
    nlohmann::json passes = nlohmann::json::array();
    for (const AdaptivePassReport& pass : outcome.adaptive_passes) passes.push_back(pass.ToJson());
    WriteFileDurably((fs::path(outcome.directory) / "adaptive_passes.json").string(), passes.dump(2) + "\n");
  }
  writer.Finish(outcome.capture.ToStopRecord());
  spdlog::info("capture {}: {} of {} frames in {:.0f} ms{}{}", CaptureStatusName(outcome.capture.status), outcome.capture.frames_written,
               outcome.capture.steps_total, outcome.capture.elapsed_ms, outcome.capture.reason.empty() ? "" : ": ",
               outcome.capture.reason);

  if (request.solve && outcome.capture.status == CaptureStatus::kComplete) SolveStages(request, recipe, rig, &outcome);
  if (request.nexus || recipe.export_nexus) {
    outcome.nexus = ExportNexus(outcome.directory, (fs::path(outcome.directory) / "run.nxs").string());
    if (outcome.nexus->IsSolutionUsable()) spdlog::info("run {}: {}", header.run_id, outcome.nexus->Line());
    else spdlog::error("run {}: the NeXus export failed: {}", header.run_id, outcome.nexus->message);
  }
  return outcome;
}

}  // namespace photorig::daemon
