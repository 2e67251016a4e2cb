
#include "photorig/daemon/pipelines/led_radiance.h"

#include "photorig/config/rig.h"
#include "photorig/daemon/capture/run_store.h"
#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/io/utc_time.h"
#include "photorig/daemon/pipelines/ps_pipeline.h"
#include "photorig/solvers/core/summary_json.h"

#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <fstream>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
using solvers::lighting::LedRadianceEstimate;

// The rig with each LED's fitted intensity and exponent, a record of the
// calibration beside the LEDs, and without the simulator's intensity error
// (the copy states the LEDs as built).
void WriteCalibratedRig(const LedRadianceRequest& request, const std::string& base_rig, const LedRadianceResult& result) {
  YAML::Node rig = YAML::LoadFile(base_rig);
  YAML::Node leds = rig["lights"]["leds"];
  if (!leds.IsSequence() || leds.size() != result.summary.leds.size())
    throw std::runtime_error(base_rig + ": lights.leds has " + std::to_string(leds.IsSequence() ? leds.size() : 0) +
                             " entries, the calibration " + std::to_string(result.summary.leds.size()));
  double worst_error = 0.0;
  for (std::size_t k = 0; k < result.summary.leds.size(); ++k) {
    const LedRadianceEstimate& e = result.summary.leds[k];
    leds[k]["intensity"] = e.intensity;
    leds[k]["cos_exponent"] = e.cos_exponent;
    worst_error = std::max(worst_error, e.model_error);
  }
  YAML::Node record;
  record["date"] = UtcNowIso8601();
  record["source_run"] = fs::absolute(request.run_directory).string();
  record["albedo"] = request.options.albedo;
  record["exponent"] = solvers::lighting::ExponentRuleName(request.options.exponent);
  record["worst_model_error"] = worst_error;
  rig["lights"]["radiance_calibration"] = record;
  if (rig["sim"] && rig["sim"]["led_intensity_error_pct"]) rig["sim"].remove("led_intensity_error_pct");
  if (!fs::path(request.out_rig).parent_path().empty()) fs::create_directories(fs::path(request.out_rig).parent_path());
  YAML::Emitter emitter;
  emitter.SetDoublePrecision(8);
  emitter << rig;
  std::ofstream out(request.out_rig);
  out << "# LED radiance calibration of " << base_rig << "\n" << emitter.c_str() << "\n";
  if (!out) throw std::runtime_error("cannot write " + request.out_rig);
}

}  // namespace

LedRadianceResult CalibrateLedRadianceRun(const LedRadianceRequest& request) {
  if (!request.out_rig.empty() && fs::exists(request.out_rig))
    throw std::invalid_argument(request.out_rig + " exists: a calibrated rig is always a new file");
  const RunManifest manifest = LoadRunManifest(request.run_directory);
  PhotometricStereoInput input = LoadRunStack(request.run_directory);
  // A rig given to start from brings its LED positions and camera to the fit
  // (positions from mirror spheres, a lens from checkerboards).
  if (!request.base_rig.empty()) ApplyRigCalibration(request.base_rig, &input);
  const solvers::ps::PhotometricStack& stack = input.stack;
  const std::string run = request.run_directory;
  if (input.near_lights.empty())
    throw std::invalid_argument(run + ": the rig gives no LED positions (position_mm): the plane calibrates near LEDs");
  if (stack.dark.empty())
    throw std::invalid_argument(run + ": no dark frame: the plane's signal is measured above one (add a `dark` step)");
  const std::vector<int>& image_leds = input.image_leds;
  bool one_per_led = image_leds.size() == input.run_leds.size();
  for (std::size_t k = 0; one_per_led && k < image_leds.size(); ++k) one_per_led = image_leds[k] == static_cast<int>(k);
  if (!one_per_led)
    throw std::invalid_argument(run + ": " + std::to_string(stack.light_count()) + " LED frames for the rig's " +
                                std::to_string(input.run_leds.size()) +
                                " LEDs: the plane needs one frame per LED, in the rig's order");
  LedRadianceResult result;
  std::vector<solvers::lighting::LedPlaneFrame> frames(input.run_leds.size());
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const config::LedConfig& led = input.run_leds[k];
    solvers::lighting::LedPlaneFrame& frame = frames[k];
    frame.raw = stack.images[k];
    frame.signal = stack.images[k] - stack.dark;
    frame.dn_per_radiance = stack.light_scales[k] / led.intensity;
    frame.position_mm = input.near_lights[k].position_mm;
    frame.axis = input.near_lights[k].axis;
    frame.cos_exponent = input.near_lights[k].cos_exponent;
    result.led_ids.push_back(led.id);
    result.stated_intensity.push_back(led.intensity);
  }
  solvers::lighting::LedRadianceOptions options = request.options;
  options.saturation_level_dn = EffectiveSaturationLevel(input);
  result.summary = solvers::lighting::CalibrateLedRadiance(
      options, *input.camera, {stack.noise.read_sigma, stack.noise.shot_gain}, frames);

  result.output_directory = request.output_directory.empty()
                                ? (fs::path(run) / "results" / "led-radiance").string()
                                : request.output_directory;
  fs::create_directories(result.output_directory);
  const fs::path folder(result.output_directory);
  std::ofstream report(folder / "report.json");
  report << ToJson(request, result).dump(2) << "\n";
  if (!report) throw std::runtime_error("cannot write " + (folder / "report.json").string());
  if (!result.summary.plane_mask.empty()) WriteImage((folder / "plane_mask.png").string(), result.summary.plane_mask);
  if (result.summary.IsSolutionUsable() && !request.out_rig.empty()) {
    const std::string base_rig = request.base_rig.empty() ? manifest.rig_path : request.base_rig;
    WriteCalibratedRig(request, base_rig, result);
    config::LoadRigConfig(request.out_rig);  // what was written loads, or this throws
    result.rig_written = true;
  }
  return result;
}

nlohmann::json ToJson(const LedRadianceRequest& request, const LedRadianceResult& result) {
  const solvers::lighting::LedRadianceSummary& s = result.summary;
  nlohmann::json leds = nlohmann::json::array();
  for (std::size_t k = 0; k < s.leds.size(); ++k) {
    const LedRadianceEstimate& e = s.leds[k];
    leds.push_back({{"id", result.led_ids[k]},
                    {"usable", e.usable},
                    {"intensity", e.intensity},
                    {"intensity_std", e.intensity_std},
                    {"stated_intensity", result.stated_intensity[k]},
                    {"cos_exponent", e.cos_exponent},
                    {"cos_exponent_std", e.cos_exponent_std},
                    {"exponent_fitted", e.exponent_fitted},
                    {"bic_gain", e.bic_gain},
                    {"model_error", e.model_error},
                    {"samples", e.samples},
                    {"note", e.note}});
  }
  nlohmann::json doc = solvers::core::ToJson(s);
  doc.update({{"run", request.run_directory},
              {"albedo", request.options.albedo},
              {"plane_height_mm", request.options.plane_height_mm},
              {"exponent", solvers::lighting::ExponentRuleName(request.options.exponent)},
              {"plane_pixels", s.plane_pixels},
              {"usable", s.usable},
              {"leds", leds}});
  return doc;
}

}  // namespace photorig::daemon
