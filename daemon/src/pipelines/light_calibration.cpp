#include "photorig/daemon/pipelines/light_calibration.h"

#include "photorig/daemon/capture/run_store.h"
#include "photorig/daemon/io/image_io.h"
#include "photorig/solvers/lighting/light_files.h"
#include "photorig/solvers/lighting/light_intensity.h"

#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
using namespace photorig::solvers::lighting;

// A copy of `base_rig` whose LEDs carry the calibrated directions (and
// intensities when measured). Lights that failed keep their previous values.
void WriteCalibratedRig(const std::string& base_rig, const std::string& out_rig,
                        const std::vector<LightDirectionEstimate>& directions,
                        const std::vector<LightIntensityEstimate>& intensities) {
  YAML::Node rig = YAML::LoadFile(base_rig);
  YAML::Node leds = rig["lights"]["leds"];
  if (!leds.IsSequence() || leds.size() != directions.size())
    throw std::runtime_error(base_rig + ": lights.leds has " + std::to_string(leds.IsSequence() ? leds.size() : 0) +
                             " entries, the calibration has " + std::to_string(directions.size()));
  for (std::size_t k = 0; k < directions.size(); ++k) {
    if (!directions[k].usable) continue;
    const Eigen::Vector3d& d = directions[k].direction;
    leds[k]["direction"] = std::vector<double>{d.x(), d.y(), d.z()};
    if (k < intensities.size() && intensities[k].usable) {
      const Eigen::Vector3d& rgb = intensities[k].rgb;
      leds[k]["intensity"] = rgb.mean();
      leds[k]["rgb_intensity"] = std::vector<double>{rgb.x(), rgb.y(), rgb.z()};
    }
  }
  // A simulated dome's LEDs are tilted off the directions its file gives; in
  // the copy the calibrated directions are the truth, so the tilt goes.
  if (rig["sim"] && rig["sim"]["led_direction_error_deg"]) rig["sim"].remove("led_direction_error_deg");
  if (!fs::path(out_rig).parent_path().empty()) fs::create_directories(fs::path(out_rig).parent_path());
  std::ofstream out(out_rig);
  out << "# Light calibration of " << base_rig << "\n" << rig << "\n";
  if (!out) throw std::runtime_error("cannot write " + out_rig);
}

}  // namespace

LightCalibrationInputs LoadLightCalibrationInputs(const std::string& run_directory) {
  const RunManifest manifest = LoadRunManifest(run_directory);
  LightCalibrationInputs inputs;
  inputs.frames.resize(manifest.lights.size());
  inputs.names.resize(manifest.lights.size());
  for (const config::LedConfig& led : manifest.lights) inputs.nominal_directions.push_back(led.direction);
  inputs.pixel_pitch_mm = manifest.pixel_pitch_mm;
  inputs.projection = manifest.projection;
  inputs.pinhole = manifest.pinhole;
  for (const FrameRecord& record : manifest.frames) {
    if (record.kind != config::CaptureStep::Kind::kLight || record.led < 0 || record.led >= static_cast<int>(inputs.frames.size())) continue;
    inputs.frames[static_cast<std::size_t>(record.led)] = LoadFrame(run_directory, record);
    inputs.names[static_cast<std::size_t>(record.led)] = fs::path(record.file).filename().string();
  }
  return inputs;
}

void LoadWhiteFrames(const std::vector<std::string>& paths, LightCalibrationInputs* inputs) {
  for (const std::string& path : paths) {
    std::string why;
    cv::Mat image = TryReadImage(path, solvers::codecs::ReadMode::kWithoutAlpha, &why);
    if (image.empty()) throw std::invalid_argument(path + ": cannot read the white-sphere image (" + why + ")");
    inputs->white_frames.push_back(std::move(image));
  }
}

CameraModel SphereCamera(const LightCalibrationInputs& inputs, CameraModel given) {
  if (given.projection == CameraModel::Projection::kPinhole) {
    if (given.fy_px <= 0.0) given.fy_px = given.fx_px;
    return given;
  }
  if (inputs.projection != solvers::camera::Projection::kPinhole) return given;
  const solvers::camera::PinholeLens& lens = inputs.pinhole;
  if (std::any_of(lens.distortion.begin(), lens.distortion.end(), [](double k) { return k != 0.0; }))
    throw std::invalid_argument("the camera's lens has distortion, which the sphere fit does not model; give a "
                                "pinhole camera with the intrinsics of undistorted frames");
  CameraModel own;
  own.projection = CameraModel::Projection::kPinhole;
  own.fx_px = lens.fx_px;
  own.fy_px = lens.fy_px;
  own.cx_px = lens.cx_px;
  own.cy_px = lens.cy_px;
  return own;
}

namespace {

// The calibration sphere's circle in the image: given, fitted to a
// silhouette, or placed by the highlights under the rig's nominal directions.
// False with summary->message saying why when there is none.
bool FindSphereCircle(const LightCalibrationInputs& inputs, const config::LightCalibrationRequest& request,
                      LightCalibrationSummary* summary, std::vector<Eigen::Vector2d>* edges) {
  if (request.circle) {
    summary->circle = *request.circle;
    summary->sphere_source = SphereSource::kCircle;
    return true;
  }
  if (!request.silhouette_image.empty()) {
    std::string why;
    const cv::Mat silhouette = TryReadImage(request.silhouette_image, solvers::codecs::ReadMode::kGrey, &why);
    if (silhouette.empty()) {
      summary->message = request.silhouette_image + ": cannot read the silhouette image (" + why + ")";
      return false;
    }
    const SphereFitSummary fit = FitSphereSilhouette(silhouette);
    if (!fit.IsSolutionUsable()) {
      summary->message = request.silhouette_image + ": " + fit.message;
      return false;
    }
    summary->circle = fit.circle;
    summary->sphere_fit_rms_px = fit.rms_residual_px;
    summary->sphere_source = SphereSource::kSilhouette;
    *edges = fit.edge_points;
    return true;
  }
  if (request.camera.projection != CameraModel::Projection::kOrthographic) {
    summary->message = "locating the sphere from its highlights needs an orthographic camera: give a circle or a silhouette";
    return false;
  }
  if (inputs.nominal_directions.size() != inputs.frames.size()) {
    summary->message = "locating the sphere from its highlights needs the rig's nominal light directions";
    return false;
  }
  HighlightCircleOptions options;
  if (request.sphere_radius_mm > 0.0 && inputs.pixel_pitch_mm > 0.0)
    options.fixed_radius_px = request.sphere_radius_mm / inputs.pixel_pitch_mm;
  const HighlightCircleSummary fit = LocateSphereFromHighlights(inputs.frames, inputs.nominal_directions, options);
  if (!fit.IsSolutionUsable()) {
    summary->message = "sphere from highlights: " + fit.message;
    return false;
  }
  summary->circle = fit.circle;
  summary->sphere_fit_rms_px = fit.rms_residual_px;
  summary->sphere_source = SphereSource::kHighlights;
  return true;
}

// Each light's direction from its highlight on the sphere, added to the report.
std::vector<LightDirectionEstimate> EstimateDirections(const LightCalibrationInputs& inputs, const SphereGeometry& sphere,
                                                       LightCalibrationSummary* summary, nlohmann::json* report) {
  std::vector<LightDirectionEstimate> directions;
  for (std::size_t k = 0; k < inputs.frames.size(); ++k) {
    LightDirectionEstimate e;
    if (inputs.frames[k].empty()) e.note = "no frame";
    else e = EstimateLightDirection(inputs.frames[k], sphere);
    summary->unusable += e.usable ? 0 : 1;
    const std::string name = k < inputs.names.size() ? inputs.names[k] : "";
    (*report)["lights"].push_back({{"index", k}, {"image", name}, {"usable", e.usable},
                                   {"flags", LightFlagsToString(e.flags)}, {"note", e.note},
                                   {"direction", {e.direction.x(), e.direction.y(), e.direction.z()}},
                                   {"highlight_px", {e.highlight_px.x(), e.highlight_px.y()}},
                                   {"uncertainty_deg", e.uncertainty_deg}});
    directions.push_back(e);
  }
  return directions;
}

// A given circle is checked against the one the highlights place under the
// rig's nominal directions: each direction's shift between the two circles
// joins its uncertainty, so a wrong circle cannot report the precision of a
// right one.
void CheckGivenCircle(const LightCalibrationInputs& inputs, const config::LightCalibrationRequest& request,
                      std::vector<LightDirectionEstimate>* directions, LightCalibrationSummary* summary,
                      nlohmann::json* report) {
  if (summary->sphere_source != SphereSource::kCircle || inputs.nominal_directions.size() != inputs.frames.size() ||
      request.camera.projection != CameraModel::Projection::kOrthographic)
    return;
  const HighlightCircleSummary fit = LocateSphereFromHighlights(inputs.frames, inputs.nominal_directions);
  const SphereGeometry check = fit.IsSolutionUsable() ? LocateSphere(request.camera, fit.circle) : SphereGeometry{};
  if (!check.valid) {
    (*report)["sphere"]["check"] = {{"message", "the highlights place no sphere: " + fit.message}};
    return;
  }
  double shift_sum = 0.0;
  for (std::size_t k = 0; k < directions->size(); ++k) {
    LightDirectionEstimate& e = (*directions)[k];
    if (!e.usable) continue;
    const LightDirectionEstimate other = EstimateLightDirection(inputs.frames[k], check);
    const double shift_deg =
        other.usable ? std::acos(std::clamp(e.direction.dot(other.direction), -1.0, 1.0)) * 180.0 / M_PI : 0.0;
    e.uncertainty_deg = std::hypot(e.uncertainty_deg, shift_deg);
    (*report)["lights"][k]["uncertainty_deg"] = e.uncertainty_deg;
    (*report)["lights"][k]["circle_shift_deg"] = shift_deg;
    shift_sum += shift_deg;
  }
  const int checked = summary->lights - summary->unusable;
  summary->circle_shift_deg = checked > 0 ? shift_sum / checked : 0.0;
  (*report)["sphere"]["check"] = {{"highlight_circle", {fit.circle.cx_px, fit.circle.cy_px, fit.circle.radius_px}},
                                  {"highlight_fit_rms_px", fit.rms_residual_px},
                                  {"centre_offset_px", std::hypot(summary->circle.cx_px - fit.circle.cx_px,
                                                                  summary->circle.cy_px - fit.circle.cy_px)},
                                  {"radius_difference_px", summary->circle.radius_px - fit.circle.radius_px},
                                  {"mean_direction_shift_deg", summary->circle_shift_deg}};
}

// Where the sphere was found and how: report.json's and the summary's "sphere".
nlohmann::json SphereJson(const LightCalibrationSummary& summary) {
  return {{"source", SphereSourceName(summary.sphere_source)},
          {"cx_px", summary.circle.cx_px},
          {"cy_px", summary.circle.cy_px},
          {"radius_px", summary.circle.radius_px},
          {"fit_rms_px", summary.sphere_fit_rms_px}};
}

// lights.lp and DiLiGenT's light_directions.txt and light_intensities.txt.
void WriteLightFiles(const LightCalibrationInputs& inputs, const std::vector<LightDirectionEstimate>& directions,
                     const std::vector<LightIntensityEstimate>& intensities, const std::string& out_directory) {
  fs::create_directories(out_directory);
  std::vector<LightPosition> lp;
  std::vector<Eigen::Vector3d> diligent_directions, diligent_intensities;
  for (std::size_t k = 0; k < directions.size(); ++k) {
    lp.push_back({k < inputs.names.size() ? inputs.names[k] : "", directions[k].direction});
    diligent_directions.push_back(directions[k].direction);
    diligent_intensities.push_back(intensities[k].usable ? intensities[k].rgb : Eigen::Vector3d::Ones());
  }
  WriteLpFile((fs::path(out_directory) / "lights.lp").string(), lp);
  WriteTriplesFile((fs::path(out_directory) / "light_directions.txt").string(), diligent_directions);
  WriteTriplesFile((fs::path(out_directory) / "light_intensities.txt").string(), diligent_intensities);
}

}  // namespace

LightCalibrationSummary CalibrateLights(const LightCalibrationInputs& inputs, const config::LightCalibrationRequest& request,
                                        const std::string& out_directory, LightCalibrationEstimates* estimates) {
  LightCalibrationSummary summary;
  summary.lights = static_cast<int>(inputs.frames.size());
  if (!request.IsValid(&summary.message)) return summary;
  if (inputs.frames.empty()) {
    summary.message = "no light frames";
    return summary;
  }
  if (!inputs.white_frames.empty() && inputs.white_frames.size() != inputs.frames.size()) {
    summary.message = "white-sphere frames: " + std::to_string(inputs.white_frames.size()) + " for " +
                      std::to_string(inputs.frames.size()) + " lights";
    return summary;
  }
  std::vector<Eigen::Vector2d> edges;
  if (!FindSphereCircle(inputs, request, &summary, &edges)) return summary;
  const SphereGeometry sphere = LocateSphere(request.camera, summary.circle, edges);
  if (!sphere.valid) {
    summary.message = "sphere: " + sphere.message;
    return summary;
  }

  nlohmann::json report{{"sphere", SphereJson(summary)}, {"lights", nlohmann::json::array()}};
  std::vector<LightDirectionEstimate> directions = EstimateDirections(inputs, sphere, &summary, &report);
  CheckGivenCircle(inputs, request, &directions, &summary, &report);
  const int usable = summary.lights - summary.unusable;
  double uncertainty_sum = 0.0;
  for (const LightDirectionEstimate& e : directions)
    if (e.usable) uncertainty_sum += e.uncertainty_deg;
  summary.mean_uncertainty_deg = usable > 0 ? uncertainty_sum / usable : 0.0;

  std::vector<LightIntensityEstimate> intensities(inputs.frames.size());
  std::string unusable_intensity;  // the first, for the message
  if (!inputs.white_frames.empty()) {
    for (std::size_t k = 0; k < inputs.frames.size(); ++k)
      intensities[k] = EstimateIntensityFromSphere(inputs.white_frames[k], sphere, directions[k].direction);
    NormaliseIntensities(&intensities);
    for (std::size_t k = 0; k < inputs.frames.size(); ++k) {
      const LightIntensityEstimate& e = intensities[k];
      nlohmann::json& light = report["lights"][k];
      light["intensity_usable"] = e.usable;
      light["intensity_note"] = e.note;
      light["rgb_intensity"] = {e.rgb.x(), e.rgb.y(), e.rgb.z()};
      light["intensity_model_error"] = e.model_error;
      light["intensity_relative_noise_rms"] = e.relative_noise_rms;
      if (e.usable) continue;
      if (summary.unusable_intensities++ == 0) unusable_intensity = "light " + std::to_string(k) + "'s intensity: " + e.note;
    }
  }
  WriteLightFiles(inputs, directions, intensities, out_directory);
  if (estimates) *estimates = {directions, inputs.white_frames.empty() ? std::vector<LightIntensityEstimate>{} : intensities};

  bool rig_written = request.out_rig.empty();
  if (!request.out_rig.empty()) {
    if (fs::exists(request.out_rig)) {
      summary.message = request.out_rig + " exists: a calibrated rig is always a new file";
    } else {
      WriteCalibratedRig(request.base_rig, request.out_rig, directions, intensities);
      summary.out_rig = request.out_rig;
      rig_written = true;
    }
  }
  report["summary"] = {{"lights", summary.lights}, {"unusable", summary.unusable},
                       {"unusable_intensities", summary.unusable_intensities},
                       {"mean_uncertainty_deg", summary.mean_uncertainty_deg},
                       {"circle_shift_deg", summary.circle_shift_deg}, {"out_rig", summary.out_rig}};
  std::ofstream((fs::path(out_directory) / "report.json").string()) << report.dump(2) << "\n";
  summary.success = rig_written && summary.unusable == 0 && summary.unusable_intensities == 0;
  if (summary.message.empty())
    summary.message = std::to_string(usable) + " of " + std::to_string(summary.lights) + " lights calibrated (sphere from " +
                      SphereSourceName(summary.sphere_source) + ")";
  if (summary.unusable_intensities > 0)
    summary.message += "; " + std::to_string(summary.unusable_intensities) + " of " + std::to_string(summary.lights) +
                       " intensities unusable and kept at their previous values, e.g. " + unusable_intensity;
  return summary;
}

nlohmann::json ToJson(const LightCalibrationSummary& summary) {
  return {{"success", summary.success},
          {"message", summary.message},
          {"sphere", SphereJson(summary)},
          {"lights", summary.lights},
          {"unusable", summary.unusable},
          {"unusable_intensities", summary.unusable_intensities},
          {"mean_uncertainty_deg", summary.mean_uncertainty_deg},
          {"out_rig", summary.out_rig}};
}

}  // namespace photorig::daemon
