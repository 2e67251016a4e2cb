#include "photorig/daemon/pipelines/provenance.h"

#include "photorig/config/color_model.h"
#include "photorig/daemon/capture/run_store.h"
#include "photorig/daemon/io/utc_time.h"

#include <chrono>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace photorig::daemon {
namespace fs = std::filesystem;
using nlohmann::json;
using solvers::core::NameOf;

namespace {

}  // namespace

json Provenance::ToJson() const {
  return {{"program", program}, {"version", version}, {"date", date}, {"options", options}, {"inputs", inputs}};
}

json RequestJson(const config::PhotometricStereoRequest& request) {
  return {{"method", NameOf(solvers::ps::kMethodNames, request.method)},
          {"shadow_threshold_sigma", request.shadow_threshold_sigma},
          {"max_condition_number", request.max_condition_number},
          {"derivative", NameOf(solvers::ps::kBlinnPhongDerivativeNames, request.derivative)},
          {"integrator", config::IntegratorChoiceName(request.integrator)},
          {"assume_distant", request.assume_distant},
          {"max_distant_bias_deg", request.max_distant_bias_deg},
          {"fill_unresolved", request.fill_unresolved}};
}

json RequestJson(const config::TomographyRequest& request) {
  json doc = {{"method", NameOf(solvers::tomography::kMethodNames, request.method)},
              {"total_variation", request.total_variation},
              {"projector", NameOf(solvers::tomography::kInterpolationNames, request.projector)},
              {"max_iterations", request.max_iterations},
              {"discrepancy_factor", request.discrepancy_factor},
              {"volume", request.volume},
              {"voxel_mm", request.voxel_mm},
              {"ring_filter", request.ring_filter},
              {"held_out", request.held_out}};
  if (request.cor_offset_mm) doc["cor_offset_mm"] = *request.cor_offset_mm;
  return doc;
}

json RequestJson(const config::BrdfRequest& request) {
  return {{"loss", NameOf(solvers::brdf::kFitLossNames, request.loss)},
          {"calibration", NameOf(config::BrdfRequest::kCalibrationNames, request.calibrate_with_target)}};
}

json RunInputs(const std::string& directory) {
  const std::string absolute = fs::absolute(directory).lexically_normal().string();
  const fs::path manifest_path = fs::path(directory) / "manifest.json";
  if (!fs::exists(manifest_path)) return {{"folder", absolute}};
  std::ifstream in(manifest_path, std::ios::binary);
  const std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  const RunManifest manifest = LoadRunManifest(directory);
  std::string crcs;
  for (const FrameRecord& frame : manifest.frames) crcs += std::to_string(frame.crc32) + "\n";
  return {{"run", absolute},
          {"manifest_fnv1a64", config::ContentHash(bytes)},
          {"frames", manifest.frames.size()},
          {"frames_crc32_fnv1a64", config::ContentHash(crcs)}};
}

Provenance MakeProvenance(const std::string& stage, const std::string& directory, json request, json loading) {
  Provenance provenance;
  provenance.version = PHOTORIG_VERSION;
  provenance.date = UtcNowIso8601();
  provenance.options = {{"stage", stage}, {"request", std::move(request)}, {"loading", std::move(loading)}};
  provenance.inputs = RunInputs(directory);
  return provenance;
}

Provenance ProvenanceFromJson(const json& doc, const std::string& source) {
  const auto missing = [&source](const std::string& what) {
    return std::invalid_argument(source + " has no " + what +
                                 ": it was solved before photorig recorded how (or is no photorig result); "
                                 "solve the run again with the options you want");
  };
  if (!doc.is_object()) throw missing("provenance");
  for (const char* key : {"program", "version", "date", "options", "inputs"})
    if (!doc.contains(key)) throw missing(std::string("provenance.") + key);
  Provenance provenance;
  provenance.program = doc["program"].get<std::string>();
  provenance.version = doc["version"].get<std::string>();
  provenance.date = doc["date"].get<std::string>();
  provenance.options = doc["options"];
  provenance.inputs = doc["inputs"];
  for (const char* key : {"stage", "request", "loading"})
    if (!provenance.options.contains(key)) throw missing(std::string("provenance.options.") + key);
  return provenance;
}

}  // namespace photorig::daemon
