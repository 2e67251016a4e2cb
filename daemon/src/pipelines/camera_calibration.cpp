#include "photorig/daemon/pipelines/camera_calibration.h"

#include "photorig/config/rig.h"
#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/io/lens_json.h"
#include "photorig/daemon/io/utc_time.h"
#include "photorig/solvers/core/summary_json.h"

#include <yaml-cpp/yaml.h>

#include <ctime>
#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;

YAML::Node FlowSequence(const std::vector<std::string>& items) {
  YAML::Node node(YAML::NodeType::Sequence);
  for (const std::string& item : items) node.push_back(item);
  node.SetStyle(YAML::EmitterStyle::Flow);
  return node;
}

// The base rig with the calibrated pinhole camera (an orthographic rig's
// pixel pitch goes: a pinhole's follows from its lens) and the record of
// the calibration (docs/cameras.md).
void WriteCalibratedRig(const CameraCalibrationRequest& request,
                        const solvers::camera::CheckerboardCalibrationSummary& summary) {
  YAML::Node rig = YAML::LoadFile(request.base_rig);
  YAML::Node camera = rig["camera"];
  camera["projection"] = "pinhole";
  camera.remove("pixel_pitch_mm");
  const solvers::camera::PinholeLens& lens = summary.lens;
  YAML::Node pinhole;
  pinhole["fx_px"] = lens.fx_px;
  pinhole["fy_px"] = lens.fy_px;
  pinhole["cx_px"] = lens.cx_px;
  pinhole["cy_px"] = lens.cy_px;
  pinhole["distortion"] = std::vector<double>(lens.distortion.begin(), lens.distortion.end());
  pinhole["distortion"].SetStyle(YAML::EmitterStyle::Flow);
  pinhole["distance_mm"] = lens.distance_mm;
  pinhole.SetStyle(YAML::EmitterStyle::Flow);
  camera["pinhole"] = pinhole;

  const solvers::camera::CheckerboardCalibrationOptions& options = request.options;
  YAML::Node record;
  record["date"] = UtcNowIso8601();
  record["rms_px"] = summary.rms_px;
  record["distortion_model"] = solvers::core::NameOf(solvers::camera::kDistortionModelNames, summary.distortion_model);
  record["tilt_deg"] = summary.tilt_deg;
  YAML::Node board;
  board["inner_corners"] = std::vector<int>{options.inner_corners_cols, options.inner_corners_rows};
  board["inner_corners"].SetStyle(YAML::EmitterStyle::Flow);
  board["square_mm"] = options.square_mm;
  board.SetStyle(YAML::EmitterStyle::Flow);
  record["board"] = board;
  record["plane_image"] = request.images[static_cast<std::size_t>(options.plane_image)];
  record["images"] = FlowSequence(summary.used);
  if (!summary.rejected.empty()) record["rejected"] = FlowSequence(summary.rejected);
  camera["calibration"] = record;

  if (!fs::path(request.out_rig).parent_path().empty()) fs::create_directories(fs::path(request.out_rig).parent_path());
  YAML::Emitter emitter;
  emitter.SetDoublePrecision(10);  // far below the fit's uncertainty, readable
  emitter << rig;
  std::ofstream out(request.out_rig);
  out << "# Camera calibration of " << request.base_rig << "\n" << emitter.c_str() << "\n";
  if (!out) throw std::runtime_error("cannot write " + request.out_rig);
}

}  // namespace

CameraCalibrationResult CalibrateCamera(const CameraCalibrationRequest& request) {
  if (fs::exists(request.out_rig)) throw std::invalid_argument(request.out_rig + " exists: give a new file for the rig");
  const config::RigConfig base = config::LoadRigConfig(request.base_rig);
  std::vector<cv::Mat> images;
  for (const std::string& path : request.images) {
    images.push_back(ReadInputImage(path, solvers::codecs::ReadMode::kWithoutAlpha));
    if (images.back().cols != base.camera.width || images.back().rows != base.camera.height)
      throw std::invalid_argument(path + ": " + std::to_string(images.back().cols) + " x " +
                                  std::to_string(images.back().rows) + " px, the camera of " + request.base_rig +
                                  " takes " + std::to_string(base.camera.width) + " x " +
                                  std::to_string(base.camera.height));
  }
  CameraCalibrationResult result;
  result.summary = solvers::camera::CalibrateFromCheckerboards(request.options, images, request.images);
  if (!result.summary.IsSolutionUsable()) return result;
  WriteCalibratedRig(request, result.summary);
  config::LoadRigConfig(request.out_rig);  // what was written loads, or this throws
  result.rig_written = true;
  return result;
}

nlohmann::json ToJson(const CameraCalibrationResult& result, const CameraCalibrationRequest& request) {
  const solvers::camera::CheckerboardCalibrationSummary& s = result.summary;
  nlohmann::json doc = solvers::core::ToJson(s);
  doc.update({{"width_px", s.width_px},
              {"height_px", s.height_px},
              {"lens", PinholeLensJson(s.lens)},
              {"std",
               {{"fx_px", s.fx_std_px},
                {"fy_px", s.fy_std_px},
                {"cx_px", s.cx_std_px},
                {"cy_px", s.cy_std_px},
                {"distortion", s.distortion_std}}},
              {"rms_px", s.rms_px},
              {"tilt_deg", s.tilt_deg},
              {"corner_reach", s.corner_reach},
              {"used", s.used},
              {"image_rms_px", s.image_rms_px},
              {"rejected", s.rejected},
              {"distortion_model", solvers::core::NameOf(solvers::camera::kDistortionModelNames, s.distortion_model)},
              {"distortion_reason", s.distortion_reason},
              {"out_rig", result.rig_written ? request.out_rig : ""}});
  doc["candidates"] = nlohmann::json::array();
  for (const solvers::camera::DistortionCandidate& c : s.candidates)
    doc["candidates"].push_back({{"model", solvers::core::NameOf(solvers::camera::kDistortionModelNames, c.model)},
                                 {"rms_px", c.rms_px},
                                 {"bic", c.bic}});
  return doc;
}

}  // namespace photorig::daemon
