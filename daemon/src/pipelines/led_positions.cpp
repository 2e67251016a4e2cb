#include "photorig/daemon/pipelines/led_positions.h"

#include "photorig/daemon/capture/run_store.h"
#include "photorig/daemon/io/utc_time.h"
#include "photorig/solvers/lighting/light_files.h"

#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
using namespace photorig::solvers::lighting;

// Millimetres to 1e-4: far below the rays' residual, and readable (a YAML
// node keeps a double with all 17 digits, whatever the emitter's precision).
std::string Millimetres(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.4f", value);
  return text;
}

YAML::Node FlowTriple(const Eigen::Vector3d& v) {
  YAML::Node node(YAML::NodeType::Sequence);
  for (int i = 0; i < 3; ++i) node.push_back(Millimetres(v[i]));
  node.SetStyle(YAML::EmitterStyle::Flow);
  return node;
}

nlohmann::json Triple(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

// The base rig with every LED at its calibrated position and the record of
// the calibration (docs/lighting.md, "LED positions"). Only called when every
// LED was placed.
void WriteCalibratedRig(const LedPositionInputs& inputs, const config::LedPositionRequest& request,
                        const LedPositionCalibration& result) {
  YAML::Node rig = YAML::LoadFile(request.base_rig);
  YAML::Node leds = rig["lights"]["leds"];
  const std::vector<LedPositionEstimate>& placed = result.solve.leds;
  if (!leds.IsSequence() || leds.size() != placed.size())
    throw std::runtime_error(request.base_rig + ": lights.leds has " + std::to_string(leds.IsSequence() ? leds.size() : 0) +
                             " entries, the calibration has " + std::to_string(placed.size()));
  for (std::size_t k = 0; k < placed.size(); ++k) {
    leds[k].remove("direction");  // a placed LED is a near one
    leds[k]["position_mm"] = FlowTriple(placed[k].position_mm);
  }
  YAML::Node record;
  record["date"] = UtcNowIso8601();
  record["source_run"] = fs::absolute(inputs.run_directory).lexically_normal().string();
  record["method"] = "mirror spheres";
  YAML::Node spheres(YAML::NodeType::Sequence);
  for (const Eigen::Vector3d& centre : request.sphere_centres_mm) spheres.push_back(FlowTriple(centre));
  record["spheres_mm"] = spheres;
  record["radius_mm"] = request.sphere_radius_mm;
  record["leds_placed"] = result.solve.usable;
  record["mean_rms_ray_distance_mm"] = Millimetres(result.solve.mean_rms_ray_distance_mm);
  record["max_rms_ray_distance_mm"] = Millimetres(result.max_rms_ray_distance_mm);
  record["mean_shift_mm"] = Millimetres(result.mean_shift_mm);
  record["max_shift_mm"] = Millimetres(result.max_shift_mm);
  rig["lights"]["position_calibration"] = record;
  // A simulated dome's LEDs are turned off the positions its file gives; in
  // the copy the calibrated positions are the truth, so the turn goes.
  if (rig["sim"] && rig["sim"]["led_direction_error_deg"]) rig["sim"].remove("led_direction_error_deg");

  if (!fs::path(request.out_rig).parent_path().empty()) fs::create_directories(fs::path(request.out_rig).parent_path());
  std::ofstream out(request.out_rig);
  out << "# LED positions of " << request.base_rig << "\n" << rig << "\n";
  if (!out) throw std::runtime_error("cannot write " + request.out_rig);
}

nlohmann::json LedJson(const LedPositionInputs& inputs, std::size_t k, const LedPositionEstimate& led) {
  nlohmann::json spheres = nlohmann::json::array();
  for (std::size_t s = 0; s < led.highlights.size(); ++s) {
    const LightDirectionEstimate& h = led.highlights[s];
    spheres.push_back({{"sphere", s},
                       {"used", std::find(led.used_spheres.begin(), led.used_spheres.end(), static_cast<int>(s)) !=
                                    led.used_spheres.end()},
                       {"flags", LightFlagsToString(h.flags)},
                       {"highlight_px", {h.highlight_px.x(), h.highlight_px.y()}},
                       {"uncertainty_deg", h.uncertainty_deg},
                       {"note", h.note}});
  }
  nlohmann::json j{{"index", k},
                   {"id", k < inputs.leds.size() ? inputs.leds[k].id : static_cast<int>(k)},
                   {"image", k < inputs.names.size() ? inputs.names[k] : ""},
                   {"usable", led.usable},
                   {"flags", LedFlagsToString(led.flags)},
                   {"note", led.note},
                   {"rms_ray_distance_mm", led.rms_ray_distance_mm},
                   {"ray_tolerance_mm", led.ray_tolerance_mm},
                   {"predicted_sigma_mm", led.predicted_sigma_mm},
                   {"spheres", spheres}};
  // An unusable LED has no position: none is reported, so none can be taken.
  if (led.usable) j["position_mm"] = Triple(led.position_mm);
  if (k < inputs.leds.size() && inputs.leds[k].position_mm) {
    j["nominal_mm"] = Triple(*inputs.leds[k].position_mm);
    if (led.usable) {
      j["shift_mm"] = Triple(led.position_mm - *inputs.leds[k].position_mm);
      j["shift_norm_mm"] = (led.position_mm - *inputs.leds[k].position_mm).norm();
    }
  }
  if (led.usable && k < inputs.true_positions_mm.size())
    j["error_vs_truth_mm"] = (led.position_mm - inputs.true_positions_mm[k]).norm();
  return j;
}

// Shifts from the nominal positions and, for a simulated run, errors against the truth.
void Score(const LedPositionInputs& inputs, LedPositionCalibration* result) {
  int shifted = 0, scored = 0;
  double shift_sum = 0.0, error_sum = 0.0;
  for (std::size_t k = 0; k < result->solve.leds.size(); ++k) {
    const LedPositionEstimate& led = result->solve.leds[k];
    if (!led.usable) continue;
    result->max_rms_ray_distance_mm = std::max(result->max_rms_ray_distance_mm, led.rms_ray_distance_mm);
    if (k < inputs.leds.size() && inputs.leds[k].position_mm) {
      const double shift = (led.position_mm - *inputs.leds[k].position_mm).norm();
      shift_sum += shift;
      result->max_shift_mm = std::max(result->max_shift_mm, shift);
      ++shifted;
    }
    if (k < inputs.true_positions_mm.size()) {
      const double error = (led.position_mm - inputs.true_positions_mm[k]).norm();
      error_sum += error;
      result->max_error_mm = std::max(result->max_error_mm, error);
      ++scored;
    }
  }
  result->mean_shift_mm = shifted > 0 ? shift_sum / shifted : 0.0;
  if (scored > 0) result->mean_error_mm = error_sum / scored;
}

}  // namespace

LedPositionInputs LoadLedPositionInputs(const std::string& run_directory) {
  const RunManifest manifest = LoadRunManifest(run_directory);
  LedPositionInputs inputs;
  inputs.run_directory = run_directory;
  inputs.leds = manifest.lights;
  inputs.camera = {manifest.projection, manifest.width, manifest.height, manifest.pixel_pitch_mm, manifest.pinhole};
  inputs.frames.resize(manifest.lights.size());
  inputs.names.resize(manifest.lights.size());
  for (const FrameRecord& record : manifest.frames) {
    if (record.kind != config::CaptureStep::Kind::kLight || record.led < 0 ||
        record.led >= static_cast<int>(inputs.frames.size()))
      continue;
    inputs.frames[static_cast<std::size_t>(record.led)] = LoadFrame(run_directory, record);
    inputs.names[static_cast<std::size_t>(record.led)] = fs::path(record.file).filename().string();
  }
  const fs::path truth = fs::path(run_directory) / "ground_truth" / "light_positions.txt";
  if (fs::exists(truth)) inputs.true_positions_mm = ReadTriplesFile(truth.string());
  return inputs;
}

LedPositionCalibration CalibrateLedPositions(const LedPositionInputs& inputs, const config::LedPositionRequest& request,
                                             const std::string& out_directory) {
  LedPositionCalibration result;
  result.bad_input = true;
  if (!request.IsValid(&result.message)) return result;
  if (inputs.frames.empty()) {
    result.message = "no LED frames";
    return result;
  }
  if (!request.out_rig.empty() && fs::exists(request.out_rig)) {
    result.message = request.out_rig + " exists: a calibrated rig is always a new file";
    return result;
  }
  MirrorSphereLayout layout{request.sphere_centres_mm, request.sphere_radius_mm};
  result.solve = EstimateLedPositions(inputs.frames, inputs.camera, layout);
  if (result.solve.termination == solvers::core::Termination::kInvalidInput ||
      result.solve.termination == solvers::core::Termination::kInvalidOptions) {
    result.message = result.solve.message;
    return result;
  }
  result.bad_input = false;
  Score(inputs, &result);

  nlohmann::json report{{"camera", solvers::camera::ProjectionName(inputs.camera.projection)},
                        {"radius_mm", request.sphere_radius_mm},
                        {"spheres", nlohmann::json::array()},
                        {"leds", nlohmann::json::array()}};
  for (std::size_t s = 0; s < layout.centres_mm.size(); ++s) {
    const Circle& c = result.solve.sphere_circles[s];
    report["spheres"].push_back({{"centre_mm", Triple(layout.centres_mm[s])}, {"circle_px", {c.cx_px, c.cy_px, c.radius_px}}});
  }
  for (std::size_t k = 0; k < result.solve.leds.size(); ++k)
    report["leds"].push_back(LedJson(inputs, k, result.solve.leds[k]));

  const bool all_placed = result.solve.unusable == 0;
  if (!request.out_rig.empty() && all_placed) {
    WriteCalibratedRig(inputs, request, result);
    config::LoadRigConfig(request.out_rig);  // what was written loads, or this throws
    result.out_rig = request.out_rig;
  }
  report["summary"] = {{"leds", result.solve.leds.size()},
                       {"unusable", result.solve.unusable},
                       {"mean_rms_ray_distance_mm", result.solve.mean_rms_ray_distance_mm},
                       {"max_rms_ray_distance_mm", result.max_rms_ray_distance_mm},
                       {"mean_shift_mm", result.mean_shift_mm},
                       {"max_shift_mm", result.max_shift_mm},
                       {"out_rig", result.out_rig}};
  if (result.mean_error_mm >= 0.0)
    report["ground_truth"] = {{"mean_error_mm", result.mean_error_mm}, {"max_error_mm", result.max_error_mm}};
  fs::create_directories(out_directory);
  std::ofstream out((fs::path(out_directory) / "report.json").string());
  out << report.dump(2) << "\n";
  if (!out) throw std::runtime_error("cannot write " + (fs::path(out_directory) / "report.json").string());

  result.success = all_placed;
  result.message = std::to_string(result.solve.usable) + " of " + std::to_string(result.solve.leds.size()) + " LEDs placed";
  if (!all_placed) {
    std::string unusable;
    for (std::size_t k = 0; k < result.solve.leds.size(); ++k)
      if (!result.solve.leds[k].usable) unusable += (unusable.empty() ? "" : ", ") + std::to_string(k);
    result.message += "; unusable: LED " + unusable + (request.out_rig.empty() ? "" : " (no rig written)");
  }
  return result;
}

nlohmann::json ToJson(const LedPositionCalibration& result) {
  nlohmann::json doc = {{"success", result.success},
                        {"message", result.message},
                        {"leds", result.solve.leds.size()},
                        {"unusable", result.solve.unusable},
                        {"mean_rms_ray_distance_mm", result.solve.mean_rms_ray_distance_mm},
                        {"mean_shift_mm", result.mean_shift_mm},
                        {"max_shift_mm", result.max_shift_mm},
                        {"out_rig", result.out_rig}};
  if (result.mean_error_mm >= 0.0) {
    doc["mean_error_vs_truth_mm"] = result.mean_error_mm;
    doc["max_error_vs_truth_mm"] = result.max_error_mm;
  }
  return doc;
}

}  // namespace photorig::daemon
