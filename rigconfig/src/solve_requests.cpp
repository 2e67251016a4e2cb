#include "photorig/config/solve_requests.h"

#include "photorig/solvers/core/summary.h"
#include "photorig/solvers/ps/integration.h"
#include "photorig/solvers/reflectance/fit.h"
#include "photorig/solvers/tomography/ray_trace.h"
#include "photorig/solvers/tomography/reconstruct.h"

#include <Eigen/Core>

#include <cmath>
#include <filesystem>
#include <stdexcept>

namespace photorig::config {
using solvers::core::Refuse;
namespace fs = std::filesystem;

bool PhotometricStereoRequest::IsValid(std::string* why) const {
  if (!(shadow_threshold_sigma >= 0)) return Refuse(why, "shadow_threshold_sigma must be >= 0");
  if (!(max_condition_number > 1)) return Refuse(why, "max_condition_number must be > 1");
  if (!(max_distant_bias_deg > 0) || !(max_distant_bias_deg <= 90))
    return Refuse(why, "max_distant_bias_deg must be within (0, 90]");
  return true;
}

bool ParseIntegratorChoice(std::string_view name, std::optional<solvers::ps::Integrator>* integrator) {
  if (name == kNoIntegrator) {
    integrator->reset();
    return true;
  }
  const std::optional<solvers::ps::Integrator> parsed = solvers::ps::ParseIntegrator(name);
  if (parsed) *integrator = parsed;
  return parsed.has_value();
}

const char* IntegratorChoiceName(const std::optional<solvers::ps::Integrator>& integrator) {
  return integrator ? solvers::ps::IntegratorName(*integrator) : kNoIntegrator;
}

std::vector<std::string> IntegratorChoices() {
  std::vector<std::string> names;
  for (const auto& entry : solvers::ps::kIntegratorNames) names.emplace_back(entry.name);
  names.emplace_back(kNoIntegrator);
  return names;
}

PhotometricStereoRequest ParsePhotometricStereoRequest(const YamlNode& node) {
  node.ExpectKeys({"method", "shadow_threshold_sigma", "max_condition_number", "derivative", "integrator",
                   "assume_distant", "max_distant_bias_deg", "fill_unresolved"});
  PhotometricStereoRequest request;
  request.method = node.Choice("method", solvers::ps::kMethodNames, request.method);
  request.shadow_threshold_sigma = node.Double("shadow_threshold_sigma", request.shadow_threshold_sigma);
  request.max_condition_number = node.Double("max_condition_number", request.max_condition_number);
  request.derivative = node.Choice("derivative", solvers::ps::kBlinnPhongDerivativeNames, request.derivative);
  request.assume_distant = node.Bool("assume_distant", request.assume_distant);
  request.max_distant_bias_deg = node.Double("max_distant_bias_deg", request.max_distant_bias_deg);
  request.fill_unresolved = node.Bool("fill_unresolved", request.fill_unresolved);
  if (auto integrator = node.Find("integrator")) {
    const std::string name = integrator->AsString();
    if (!ParseIntegratorChoice(name, &request.integrator))
      integrator->Fail("'" + name + "' is no integrator (expected poisson, frankot-chellappa or none)");
  }
  if (std::string why; !request.IsValid(&why)) node.Fail(why);
  return request;
}

bool LightCalibrationRequest::IsValid(std::string* why) const {
  if (circle && !(circle->radius_px > 0.0)) return Refuse(why, "the sphere circle needs a positive radius");
  if (!(sphere_radius_mm >= 0.0) || !std::isfinite(sphere_radius_mm))
    return Refuse(why, "sphere radius_mm must be finite and >= 0 (0: unknown)");
  if (!camera.IsValid(why)) return false;
  if (base_rig.empty() != out_rig.empty()) return Refuse(why, "a new rig file needs both the rig to copy and the file to write");
  return true;
}

namespace {
// A rig file and nothing else: never the queue, a frame or a recipe.
std::string ParseOutRig(const YamlNode& node) {
  const std::string path = node.AsPath();
  const std::string extension = fs::path(path).extension().string();
  if (extension != ".yaml" && extension != ".yml") node.Fail("must name a .yaml file");
  return path;
}
}  // namespace

LightCalibrationRequest ParseLightCalibrationRequest(const YamlNode& node) {
  node.ExpectKeys({"sphere", "out_rig"});
  LightCalibrationRequest request;
  if (auto sphere = node.Find("sphere")) {
    sphere->ExpectKeys({"circle", "silhouette", "from", "radius_mm"});
    if (auto circle = sphere->Find("circle")) {
      const Eigen::Vector3d c = circle->AsVector3();
      if (!(c.z() > 0.0)) circle->Fail("the circle is [cx, cy, radius] in pixels with a positive radius");
      request.circle = solvers::lighting::Circle{c.x(), c.y(), c.z()};
    }
    if (auto silhouette = sphere->Find("silhouette")) request.silhouette_image = silhouette->AsPath();
    if (auto from = sphere->Find("from")) {
      if (from->AsString() != "highlights") from->Fail("expected 'highlights' (or give a circle or a silhouette)");
      if (request.circle || !request.silhouette_image.empty()) from->Fail("give one of circle, silhouette or from");
    }
    if (request.circle && !request.silhouette_image.empty()) (*sphere)["silhouette"].Fail("give one of circle, silhouette or from");
    request.sphere_radius_mm = sphere->Double("radius_mm", 0.0);
    if (!(request.sphere_radius_mm >= 0.0) || !std::isfinite(request.sphere_radius_mm))
      (*sphere)["radius_mm"].Fail("must be finite and >= 0");
  }
  if (auto out_rig = node.Find("out_rig")) request.out_rig = ParseOutRig(*out_rig);
  return request;
}

bool LedPositionRequest::IsValid(std::string* why) const {
  if (sphere_centres_mm.size() < 2) return solvers::core::Refuse(why, "LED positions need two or more spheres");
  for (const Eigen::Vector3d& centre : sphere_centres_mm)
    if (!centre.allFinite()) return solvers::core::Refuse(why, "sphere centres must be finite");
  if (!(sphere_radius_mm > 0.0) || !std::isfinite(sphere_radius_mm))
    return solvers::core::Refuse(why, "the spheres' radius_mm must be > 0");
  if (base_rig.empty() != out_rig.empty())
    return solvers::core::Refuse(why, "a new rig file needs both the rig to copy and the file to write");
  return true;
}

LedPositionRequest ParseLedPositionRequest(const YamlNode& node) {
  node.ExpectKeys({"spheres", "radius_mm", "out_rig"});
  LedPositionRequest request;
  for (const YamlNode& item : node["spheres"].Items()) {
    const std::vector<YamlNode> xyz = item.Items();
    if (xyz.size() != 2 && xyz.size() != 3) item.Fail("each sphere is [x, y] or [x, y, z] in millimetres");
    request.sphere_centres_mm.emplace_back(xyz[0].AsDouble(), xyz[1].AsDouble(), xyz.size() == 3 ? xyz[2].AsDouble() : 0.0);
  }
  if (request.sphere_centres_mm.size() < 2) node["spheres"].Fail("give two or more sphere centres");
  request.sphere_radius_mm = node["radius_mm"].AsDouble();
  if (!(request.sphere_radius_mm > 0.0)) node["radius_mm"].Fail("must be > 0");
  if (auto out_rig = node.Find("out_rig")) request.out_rig = ParseOutRig(*out_rig);
  return request;
}

bool TomographyRequest::IsValid(std::string* why) const {
  if (total_variation && method != solvers::tomography::Method::kSart) return Refuse(why, "total_variation needs method sart");
  if (max_iterations < 1 || max_iterations > 100000) return Refuse(why, "max_iterations must be within [1, 100000]");
  if (!(discrepancy_factor > 0) || !std::isfinite(discrepancy_factor)) return Refuse(why, "discrepancy_factor must be > 0");
  for (int n : volume)
    if (n < 0 || n > 4096) return Refuse(why, "volume sizes must be within [0, 4096] (0: from the detector)");
  if (!(voxel_mm >= 0) || !std::isfinite(voxel_mm)) return Refuse(why, "voxel_mm must be >= 0 (0: the detector pitch)");
  if (cor_offset_mm && !std::isfinite(*cor_offset_mm)) return Refuse(why, "cor_offset_mm must be finite");
  return true;
}

TomographyRequest ParseTomographyRequest(const YamlNode& node) {
  node.ExpectKeys({"method", "total_variation", "projector", "max_iterations", "discrepancy_factor", "volume",
                   "voxel_mm", "cor_offset_mm", "ring_filter", "held_out"});
  TomographyRequest request;
  request.method = node.Choice("method", solvers::tomography::kMethodNames, request.method);
  request.total_variation = node.Bool("total_variation", request.total_variation);
  request.projector = node.Choice("projector", solvers::tomography::kInterpolationNames, request.projector);
  request.max_iterations = node.Int("max_iterations", request.max_iterations);
  request.discrepancy_factor = node.Double("discrepancy_factor", request.discrepancy_factor);
  if (auto volume = node.Find("volume")) {
    const std::vector<int> sizes = volume->AsIntList();
    if (sizes.size() != 3) volume->Fail("expected [nx, ny, nz]");
    request.volume = {sizes[0], sizes[1], sizes[2]};
  }
  request.voxel_mm = node.Double("voxel_mm", request.voxel_mm);
  if (node.Find("cor_offset_mm")) request.cor_offset_mm = node.Double("cor_offset_mm", 0.0);
  request.ring_filter = node.Bool("ring_filter", request.ring_filter);
  request.held_out = node.Bool("held_out", request.held_out);
  if (std::string why; !request.IsValid(&why)) node.Fail(why);
  return request;
}

bool SvbrdfRequest::IsValid(std::string* why) const {
  if (!ps.IsValid(why)) return false;
  solvers::reflectance::ReflectanceOptions fit;
  fit.max_materials = max_materials;
  if (!fit.IsValid(why)) return false;
  // RelightingOptions takes 0 and more; -1 is the request's "no check".
  if (held_out_lights < -1)
    return Refuse(why, "held_out_lights must be >= -1 (-1: no held-out check, 0: every light)");
  return true;
}

SvbrdfRequest ParseSvbrdfRequest(const YamlNode& node) {
  node.ExpectKeys({"photometric_stereo", "max_materials", "held_out_lights", "gltf", "refine_normals"});
  SvbrdfRequest request;
  if (auto ps = node.Find("photometric_stereo")) request.ps = ParsePhotometricStereoRequest(*ps);
  if (auto materials = node.Find("max_materials")) request.max_materials = materials->AsInt();
  if (auto held_out = node.Find("held_out_lights")) request.held_out_lights = held_out->AsInt();
  request.export_gltf = node.Bool("gltf", request.export_gltf);
  request.refine_normals = node.Bool("refine_normals", request.refine_normals);
  if (std::string why; !request.IsValid(&why)) node.Fail(why);
  return request;
}

BrdfRequest ParseBrdfRequest(const YamlNode& node) {
  node.ExpectKeys({"loss", "calibration"});
  BrdfRequest request;
  request.loss = node.Choice("loss", solvers::brdf::kFitLossNames, request.loss);
  // reference: the rig's reference target; camera: the camera's stated response.
  request.calibrate_with_target = node.Choice("calibration", BrdfRequest::kCalibrationNames, request.calibrate_with_target);
  return request;
}

}  // namespace photorig::config
