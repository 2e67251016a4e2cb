#include "photorig/config/solve_requests.h"

#include "photorig/solvers/ps/integration.h"
#include "photorig/solvers/tomography/ray_trace.h"
#include "photorig/solvers/tomography/reconstruct.h"

#include <Eigen/Core>

#include <cmath>
#include <filesystem>
#include <stdexcept>

namespace photorig::config {
namespace fs = std::filesystem;

bool ParseDerivative(const std::string& name, solvers::ps::BlinnPhongOptions* options) {
  if (name == "lanes") {
    options->fitter = solvers::ps::BlinnPhongOptions::Fitter::kLanes;
    return true;
  }
  for (auto m : {solvers::autodiff::DerivativeMethod::kForward, solvers::autodiff::DerivativeMethod::kReverse,
                 solvers::autodiff::DerivativeMethod::kSymbolic, solvers::autodiff::DerivativeMethod::kCentralDifference}) {
    if (name == solvers::autodiff::ToString(m)) {
      options->fitter = solvers::ps::BlinnPhongOptions::Fitter::kPerPixel;
      options->derivative = m;
      return true;
    }
  }
  return false;
}

void ValidatePhotometricStereoRequest(const PhotometricStereoRequest& request) {
  solvers::ps::Method method;
  if (!solvers::ps::ParseMethod(request.method, &method))
    throw std::invalid_argument("method '" + request.method + "' (expected l2, lambertian, robust, blinn-phong or auto)");
  solvers::ps::BlinnPhongOptions blinn_phong;
  if (!ParseDerivative(request.derivative, &blinn_phong))
    throw std::invalid_argument("derivative '" + request.derivative +
                                "' (expected lanes, forward, reverse, symbolic or central-difference)");
  solvers::ps::Integrator integrator;
  if (request.integrator != "none" && !solvers::ps::ParseIntegrator(request.integrator, &integrator))
    throw std::invalid_argument("integrator '" + request.integrator + "' (expected poisson, frankot-chellappa or none)");
  if (!(request.shadow_threshold_sigma >= 0)) throw std::invalid_argument("shadow_threshold_sigma must be >= 0");
  if (!(request.max_condition_number > 1)) throw std::invalid_argument("max_condition_number must be > 1");
}

PhotometricStereoRequest ParsePhotometricStereoRequest(const YamlNode& node) {
  node.ExpectKeys({"method", "shadow_threshold_sigma", "max_condition_number", "derivative", "integrator"});
  PhotometricStereoRequest request;
  request.method = node.String("method", request.method);
  request.shadow_threshold_sigma = node.Double("shadow_threshold_sigma", request.shadow_threshold_sigma);
  request.max_condition_number = node.Double("max_condition_number", request.max_condition_number);
  request.derivative = node.String("derivative", request.derivative);
  request.integrator = node.String("integrator", request.integrator);
  try {
    ValidatePhotometricStereoRequest(request);
  } catch (const std::invalid_argument& e) {
    node.Fail(e.what());
  }
  return request;
}

bool LightCalibrationRequest::IsValid(std::string* why) const {
  auto fail = [why](const std::string& message) {
    if (why) *why = message;
    return false;
  };
  if (circle && !(circle->radius_px > 0.0)) return fail("the sphere circle needs a positive radius");
  if (!(sphere_radius_mm >= 0.0)) return fail("sphere radius_mm must be >= 0");
  if (!camera.IsValid(why)) return false;
  if (base_rig.empty() != out_rig.empty()) return fail("a new rig file needs both the rig to copy and the file to write");
  return true;
}

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
    if (!(request.sphere_radius_mm >= 0.0)) (*sphere)["radius_mm"].Fail("must be >= 0");
  }
  if (auto out_rig = node.Find("out_rig")) {
    request.out_rig = out_rig->AsPath();
    // A rig file and nothing else: never the queue, a frame or a recipe.
    const std::string extension = fs::path(request.out_rig).extension().string();
    if (extension != ".yaml" && extension != ".yml") out_rig->Fail("must name a .yaml file");
  }
  return request;
}

bool TomographyRequest::IsValid(std::string* why) const {
  auto fail = [why](const std::string& message) {
    if (why) *why = message;
    return false;
  };
  if (!solvers::tomography::ParseMethod(method)) return fail("method '" + method + "' (expected sirt, art, cgls or sart)");
  if (total_variation && method != "sart") return fail("total_variation needs method sart");
  if (!solvers::tomography::ParseInterpolation(projector)) return fail("projector '" + projector + "' (expected joseph or siddon)");
  if (max_iterations < 1 || max_iterations > 100000) return fail("max_iterations must be within [1, 100000]");
  if (!(discrepancy_factor > 0) || !std::isfinite(discrepancy_factor)) return fail("discrepancy_factor must be > 0");
  for (int n : volume)
    if (n < 0 || n > 4096) return fail("volume sizes must be within [0, 4096] (0: from the detector)");
  if (!(voxel_mm >= 0) || !std::isfinite(voxel_mm)) return fail("voxel_mm must be >= 0 (0: the detector pitch)");
  if (!std::isfinite(cor_offset_mm)) return fail("cor_offset_mm must be finite");
  return true;
}

TomographyRequest ParseTomographyRequest(const YamlNode& node) {
  node.ExpectKeys({"method", "total_variation", "projector", "max_iterations", "discrepancy_factor", "volume",
                   "voxel_mm", "cor_offset_mm"});
  TomographyRequest request;
  request.method = node.String("method", request.method);
  request.total_variation = node.Bool("total_variation", request.total_variation);
  request.projector = node.String("projector", request.projector);
  request.max_iterations = node.Int("max_iterations", request.max_iterations);
  request.discrepancy_factor = node.Double("discrepancy_factor", request.discrepancy_factor);
  if (auto volume = node.Find("volume")) {
    const std::vector<int> sizes = volume->AsIntList();
    if (sizes.size() != 3) volume->Fail("expected [nx, ny, nz]");
    request.volume = {sizes[0], sizes[1], sizes[2]};
  }
  request.voxel_mm = node.Double("voxel_mm", request.voxel_mm);
  request.cor_offset_mm = node.Double("cor_offset_mm", request.cor_offset_mm);
  if (std::string why; !request.IsValid(&why)) node.Fail(why);
  return request;
}

SvbrdfRequest ParseSvbrdfRequest(const YamlNode& node) {
  node.ExpectKeys({"photometric_stereo", "max_materials", "held_out_lights", "gltf", "refine_normals"});
  SvbrdfRequest request;
  if (auto ps = node.Find("photometric_stereo")) request.ps = ParsePhotometricStereoRequest(*ps);
  if (auto materials = node.Find("max_materials")) {
    request.max_materials = materials->AsInt();
    if (request.max_materials < 1 || request.max_materials > 16) materials->Fail("must lie in [1, 16]");
  }
  if (auto held_out = node.Find("held_out_lights")) {
    request.held_out_lights = held_out->AsInt();
    if (request.held_out_lights < -1) held_out->Fail("must be >= -1 (-1: no held-out check, 0: every light)");
  }
  request.export_gltf = node.Bool("gltf", request.export_gltf);
  request.refine_normals = node.Bool("refine_normals", request.refine_normals);
  return request;
}

BrdfRequest ParseBrdfRequest(const YamlNode& node) {
  node.ExpectKeys({"loss", "calibration"});
  BrdfRequest request;
  if (auto loss = node.Find("loss")) {
    const std::string name = loss->AsString();
    if (name != "weighted" && name != "log") loss->Fail("'" + name + "' is no loss (expected weighted or log)");
    request.loss = name == "log" ? solvers::brdf::FitLoss::kLog : solvers::brdf::FitLoss::kWeighted;
  }
  if (auto calibration = node.Find("calibration")) {
    const std::string name = calibration->AsString();
    if (name != "reference" && name != "camera")
      calibration->Fail("'" + name + "' is no calibration (expected reference: the rig's reference target, or camera: "
                        "the camera's stated response)");
    request.calibrate_with_target = name == "reference";
  }
  return request;
}

}  // namespace photorig::config
