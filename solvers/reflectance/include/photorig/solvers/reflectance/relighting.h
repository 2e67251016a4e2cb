#pragma once
// Relighting the fitted reflectance: its image under any light, and the
// check that needs no ground truth, each light held out in turn and
// predicted from the others.

#include "photorig/solvers/core/progress.h"
#include "photorig/solvers/reflectance/fit.h"
#include "photorig/solvers/core/summary.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <array>
#include <string>
#include <vector>

namespace photorig::solvers::reflectance {

// The image of the fitted reflectance under one light (radiance in the
// stack's units): CV_32FC(C), zero where the pixel was not fitted.
core::Summary RenderReflectance(const ReflectanceMaps& maps, const Eigen::Vector3d& light_direction,
                          const Eigen::Vector3d& intensity, const Eigen::Vector3d& view_direction, cv::Mat* image);
// The same seen along each pixel's own line of sight (a pinhole camera):
// views, CV_32FC3 of the maps' size, the unit vectors towards the camera.
core::Summary RenderReflectance(const ReflectanceMaps& maps, const Eigen::Vector3d& light_direction,
                                const Eigen::Vector3d& intensity, const cv::Mat& views, cv::Mat* image);

// ---- Held-out-light relighting ----

enum class Method {
  kLambertian,     // per-pixel albedo, no lobe
  kPerPixelLobe,   // per-pixel albedo and per-pixel Blinn-Phong lobe
  kPerMaterial     // the materials of FitReflectance
};
const char* MethodName(Method method);  // "lambertian", "per_pixel_lobe", "per_material"

struct RelightingOptions {
  ReflectanceOptions fit;
  // How many lights to hold out, one at a time: a stratified subset spread
  // over the light directions by farthest-point sampling (0 = every light). Default 8.
  int held_out_lights = 8;
  // The lights to hold out, by index, in this order; empty: the stratified
  // subset of held_out_lights. Default empty.
  std::vector<int> lights;
  // Keep each held-out light's predicted image per method
  // (RelightingSummary::predictions). Default false.
  bool keep_predictions = false;
  // The methods evaluated; the others' errors stay 0. Default all three.
  std::vector<Method> methods = {Method::kLambertian, Method::kPerPixelLobe, Method::kPerMaterial};
  core::ProgressCallback progress;  // one unit per held-out light and method
  bool IsValid(std::string* why) const;
};

struct HeldOutError {
  int light = 0;
  Method method = Method::kLambertian;
  double rmse = 0.0;     // image units, over the pixels every method fitted, unsaturated samples
  double psnr_db = 0.0;  // 20 log10(peak / rmse), peak = the held-out image's 99.9th percentile over the mask
  double fit_ms = 0.0;   // time to fit without the light
};

// A held-out light's image as a method predicts it from the other lights:
// CV_32FC(C) in the stack's units, NaN where the pixel was not evaluated (not
// fitted by every method), 0 where the light does not reach the surface.
// Clipped samples are predicted, though left out of the errors.
struct HeldOutPrediction {
  int light = 0;
  Method method = Method::kLambertian;
  cv::Mat image;
};

struct RelightingSummary : core::Summary {
  std::vector<int> held_out;  // light indices, in evaluation order
  std::vector<HeldOutError> errors;
  std::vector<HeldOutPrediction> predictions;  // with RelightingOptions::keep_predictions
  // Mean RMSE over the held-out lights per method, indexed by Method.
  double mean_rmse[3] = {0.0, 0.0, 0.0};
  double mean_psnr_db[3] = {0.0, 0.0, 0.0};
  double mean_fit_ms[3] = {0.0, 0.0, 0.0};
  int materials = 0;  // chosen on all lights and kept for every held-out fit
  // [material][method]: RMSE over every held-out sample of the material's
  // pixels (all held-out lights pooled): where a lobe was chosen the
  // per-material error should lie below the Lambertian one, where none was
  // they should agree within noise.
  std::vector<std::array<double, 3>> material_rmse;
};

// For each held-out light: fit each method on the other lights (the number
// of materials and their lobes chosen once on all lights, the lobe shapes,
// weights and albedos refitted), render the held-out light, compare.
RelightingSummary EvaluateHeldOutLights(const RelightingOptions& options, const ReflectanceStack& stack,
                                        const cv::Mat& normals, const cv::Mat& mask);
// The same with the fit on every light already made (FitReflectance with
// options.fit on this stack, normals and mask), so it is not made again.
RelightingSummary EvaluateHeldOutLights(const RelightingOptions& options, const ReflectanceStack& stack,
                                        const cv::Mat& normals, const cv::Mat& mask, const ReflectanceMaps& full,
                                        const ReflectanceSummary& fitted);

// The stratified subset EvaluateHeldOutLights holds out.
std::vector<int> StratifiedLights(const std::vector<Eigen::Vector3d>& directions, int count);

}  // namespace photorig::solvers::reflectance
