#include "photorig/solvers/ps/near_lights.h"

#include "photorig/solvers/ps/evaluation.h"

#include <opencv2/imgproc.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>

namespace photorig::solvers::ps {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

double RadiansToDegrees(double radians) { return radians * 180.0 / kPi; }

// A NearLight with its per-light constants worked out once: the fits
// evaluate it for every sample of every pixel in every round.
struct PreparedLight {
  Eigen::Vector3d position_mm, axis;
  double cos_exponent = 1.0;
  double scale = 1.0;  // |p|^2 / cos^mu(origin): the relative irradiance's constant

  explicit PreparedLight(const NearLight& light)
      : position_mm(light.position_mm), axis(light.axis), cos_exponent(light.cos_exponent) {
    const double origin_squared = position_mm.squaredNorm();
    const double origin_cos = std::max(1e-12, -axis.dot(position_mm) / std::sqrt(origin_squared));
    scale = origin_squared / std::pow(origin_cos, cos_exponent);
  }
  // NearLight::RelativeIrradiance, without its constants' cost.
  double RelativeIrradiance(const Eigen::Vector3d& point_mm, Eigen::Vector3d* towards_light) const {
    const Eigen::Vector3d to = position_mm - point_mm;
    const double distance_squared = to.squaredNorm();
    *towards_light = to / std::sqrt(distance_squared);
    const double cos_axis = -axis.dot(*towards_light);
    if (cos_axis <= 0.0) return 0.0;
    const double profile = cos_exponent == 1.0 ? cos_axis : std::pow(cos_axis, cos_exponent);
    return scale * profile / distance_squared;
  }
};

// What every pixel's fit reads: the stack's samples and the lights'
// geometry, fixed for the whole solve.
struct PixelProblem {
  const PhotometricStack& stack;
  std::vector<PreparedLight> lights;
  camera::PixelRays rays;
  double shadow_threshold = 0.0;   // I - D at or below: shadowed
  double saturation_level = 0.0;   // I at or above: clipped
  bool exclude_unusable = true;    // false for l2: every sample enters
  double max_condition_number = 0.0;

  Eigen::Vector3d Point(int r, int c, double z_mm) const { return rays.Point(r, c, z_mm); }
  // The height of a pixel whose integrated height is `relative` (0 at the
  // reference) with the surface placed at offset_mm: a shift along z for an
  // orthographic camera, a scale about the pinhole's centre for a pinhole.
  double Height(float relative, double offset_mm) const {
    if (!rays.camera().IsPinhole()) return relative + offset_mm;
    const double d = rays.camera().pinhole.distance_mm;
    return d - (d - relative) * (d - offset_mm) / d;
  }
};

struct PixelFit {
  PixelFlag flag = PixelFlag::kSolved;
  Eigen::Vector3d b = Eigen::Vector3d::Zero();  // rho / pi * n
  int usable = 0;
  double chi_square = 0.0;  // weighted by the noise where it is known
};

// Weighted least squares of I_k - D = s_k f_k(x) (b . l_k(x)) over the
// pixel's usable samples, x its surface point at height z_mm.
PixelFit FitPixel(const PixelProblem& p, int r, int c, double z_mm) {
  const Eigen::Vector3d point = p.Point(r, c, z_mm);
  const float dark = p.stack.dark.empty() ? 0.0f : p.stack.dark.at<float>(r, c);
  Eigen::Matrix3d normal_matrix = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  double weighted_square_sum = 0.0;
  PixelFit fit;
  for (int k = 0; k < p.stack.light_count(); ++k) {
    const float value = p.stack.images[k].at<float>(r, c);
    const double signal = value - dark;
    if (p.exclude_unusable && (signal <= p.shadow_threshold || value >= p.saturation_level)) continue;
    Eigen::Vector3d towards;
    const double falloff = p.lights[k].RelativeIrradiance(point, &towards);
    if (falloff <= 0.0) continue;  // behind the LED: it cannot light this point
    const Eigen::Vector3d row = p.stack.light_scales[k] * falloff * towards;
    const double weight = p.stack.noise.IsKnown() ? 1.0 / p.stack.noise.Variance(signal) : 1.0;
    normal_matrix.noalias() += weight * row * row.transpose();
    rhs.noalias() += weight * signal * row;
    weighted_square_sum += weight * signal * signal;
    ++fit.usable;
  }
  if (fit.usable < 3) {
    fit.flag = PixelFlag::kTooFewLights;
    return fit;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(normal_matrix, Eigen::EigenvaluesOnly);
  const double smallest = eigen.eigenvalues()(0), largest = eigen.eigenvalues()(2);
  // The normal matrix holds A^T W A: its eigenvalues are squared singular values.
  if (!(smallest > 0.0) || std::sqrt(largest / smallest) > p.max_condition_number) {
    fit.flag = PixelFlag::kIllConditioned;
    return fit;
  }
  fit.b = normal_matrix.ldlt().solve(rhs);
  fit.chi_square = std::max(0.0, weighted_square_sum - 2.0 * fit.b.dot(rhs) + fit.b.dot(normal_matrix * fit.b));
  if (!(fit.b.norm() > 0.0)) fit.flag = PixelFlag::kRejectedByModel;
  return fit;
}

bool InMask(const PhotometricStack& stack, int r, int c) {
  return stack.mask.empty() || stack.mask.at<std::uint8_t>(r, c) != 0;
}

void AllocateResult(const cv::Size size, NormalMap* result) {
  result->normals.create(size, CV_32FC3);
  result->normals.setTo(cv::Scalar::all(kNaN));
  result->albedo.create(size, CV_32F);
  result->albedo.setTo(kNaN);
  result->flags.create(size, CV_8U);
  result->flags.setTo(static_cast<int>(PixelFlag::kOutsideMask));
  result->usable_lights = cv::Mat::zeros(size, CV_16U);
  result->model = cv::Mat::zeros(size, CV_8U);
  result->confidence = cv::Mat::zeros(size, CV_32F);
  result->specular = cv::Mat::zeros(size, CV_32FC2);
}

// Every pixel of the mask fitted with its surface at height_mm.
void FitAllPixels(const PixelProblem& p, const cv::Mat& height_mm, NormalMap* result) {
  const bool noise_known = p.stack.noise.IsKnown();
#pragma omp parallel for schedule(dynamic, 4)
  for (int r = 0; r < p.stack.height(); ++r)
    for (int c = 0; c < p.stack.width(); ++c) {
      if (!InMask(p.stack, r, c)) continue;
      const PixelFit fit = FitPixel(p, r, c, height_mm.at<float>(r, c));
      result->flags.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(fit.flag);
      result->usable_lights.at<std::uint16_t>(r, c) = static_cast<std::uint16_t>(std::min(fit.usable, 65535));
      if (fit.flag != PixelFlag::kSolved) {
        result->normals.at<cv::Vec3f>(r, c) = cv::Vec3f(kNaN, kNaN, kNaN);
        result->albedo.at<float>(r, c) = kNaN;
        result->model.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(PixelModel::kNone);
        result->confidence.at<float>(r, c) = 0.0f;
        continue;
      }
      const Eigen::Vector3d n = fit.b.normalized();
      result->normals.at<cv::Vec3f>(r, c) = cv::Vec3f(float(n.x()), float(n.y()), float(n.z()));
      result->albedo.at<float>(r, c) = static_cast<float>(kPi * fit.b.norm());
      result->model.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(PixelModel::kLambertian);
      // The residual variance against the noise's (1 at the noise level);
      // nothing to test with exactly three samples or without a noise model.
      const int dof = fit.usable - 3;
      result->confidence.at<float>(r, c) =
          noise_known && dof > 0 ? static_cast<float>(std::min(1.0, dof / std::max(fit.chi_square, 1e-300))) : 0.0f;
    }
}

// The integrated height on every masked pixel, 0 at its reference (the
// mean for an orthographic camera; for a pinhole one, the geometric-mean
// distance from the camera at the sample plane). The integrator leaves out
// pixels too close to grazing, which take their nearest neighbour's height (a
// rim pixel sits at the height of the surface beside it).
cv::Mat RelativeDepth(const NearLightOptions& options, const PixelProblem& p, const NormalMap& map, const cv::Mat& mask) {
  const cv::Mat solved = map.flags == static_cast<int>(PixelFlag::kSolved);
  IntegrationOptions integration;
  integration.integrator = options.integrator;
  const bool pinhole = options.camera.IsPinhole();
  if (!pinhole) integration.pixel_pitch = options.camera.pixel_pitch_mm;
  cv::Mat depth;
  const IntegrationSummary integrated =
      pinhole ? IntegrateNormalsPerspective(integration, p.rays, map.normals, solved, &depth)
              : IntegrateNormals(integration, map.normals, solved, &depth);
  cv::Mat relative = cv::Mat::zeros(map.normals.size(), CV_32F);
  if (!integrated.IsSolutionUsable() || integrated.pixels == 0) return relative;
  const cv::Mat known = depth == depth;  // not NaN
  cv::Mat distance, labels;
  cv::Mat unknown = ~known;
  cv::distanceTransform(unknown, distance, labels, cv::DIST_L2, cv::DIST_MASK_5, cv::DIST_LABEL_PIXEL);
  std::vector<float> value_of_label(depth.total() + 1, 0.0f);  // labels number the known pixels from 1
  for (int r = 0; r < depth.rows; ++r)
    for (int c = 0; c < depth.cols; ++c)
      if (known.at<std::uint8_t>(r, c)) value_of_label[labels.at<int>(r, c)] = depth.at<float>(r, c);
  const double reference = pinhole ? 0.0 : cv::mean(depth, known)[0];
  for (int r = 0; r < depth.rows; ++r)
    for (int c = 0; c < depth.cols; ++c)
      if (mask.empty() || mask.at<std::uint8_t>(r, c))
        relative.at<float>(r, c) =
            static_cast<float>((known.at<std::uint8_t>(r, c) ? depth.at<float>(r, c) : value_of_label[labels.at<int>(r, c)]) - reference);
  return relative;
}

// The sum of the fits' chi-squares over a sparse grid of solved pixels with
// the surface at relative + offset_mm.
double SparseChiSquare(const PixelProblem& p, const NearLightOptions& options, const cv::Mat& solved,
                       const cv::Mat& relative, double offset_mm) {
  double total = 0.0;
#pragma omp parallel for reduction(+ : total) schedule(dynamic, 1)
  for (int r = options.offset_stride / 2; r < relative.rows; r += options.offset_stride)
    for (int c = options.offset_stride / 2; c < relative.cols; c += options.offset_stride) {
      if (!solved.at<std::uint8_t>(r, c)) continue;
      const PixelFit fit = FitPixel(p, r, c, p.Height(relative.at<float>(r, c), offset_mm));
      if (fit.flag == PixelFlag::kSolved) total += fit.chi_square;
    }
  return total;
}

// Golden-section search for the depth offset within [low, high].
double BestOffset(const PixelProblem& p, const NearLightOptions& options, const cv::Mat& solved,
                  const cv::Mat& relative, double low, double high) {
  constexpr double kInverseGolden = 0.6180339887498949;
  constexpr double kToleranceMm = 0.01;
  double a = low, b = high;
  double x1 = b - kInverseGolden * (b - a), x2 = a + kInverseGolden * (b - a);
  double f1 = SparseChiSquare(p, options, solved, relative, x1);
  double f2 = SparseChiSquare(p, options, solved, relative, x2);
  while (b - a > kToleranceMm) {
    if (f1 <= f2) {
      b = x2, x2 = x1, f2 = f1;
      x1 = b - kInverseGolden * (b - a);
      f1 = SparseChiSquare(p, options, solved, relative, x1);
    } else {
      a = x1, x1 = x2, f1 = f2;
      x2 = a + kInverseGolden * (b - a);
      f2 = SparseChiSquare(p, options, solved, relative, x2);
    }
  }
  return 0.5 * (a + b);
}

void CountPixels(const NormalMap& map, NearLightSummary* summary) {
  summary->pixels_total = map.flags.total();
  for (auto it = map.flags.begin<std::uint8_t>(); it != map.flags.end<std::uint8_t>(); ++it) {
    switch (static_cast<PixelFlag>(*it)) {
      case PixelFlag::kSolved: ++summary->pixels_solved; break;
      case PixelFlag::kOutsideMask: ++summary->pixels_outside_mask; break;
      case PixelFlag::kTooFewLights: ++summary->pixels_too_few_lights; break;
      case PixelFlag::kIllConditioned: ++summary->pixels_ill_conditioned; break;
      case PixelFlag::kRejectedByModel: ++summary->pixels_rejected_by_model; break;
      case PixelFlag::kFilled: break;  // only FillUnresolvedNormals sets it, after a solve
    }
  }
  summary->pixels_lambertian = summary->pixels_solved;
}

std::string CheckInputs(const PhotometricStack& stack, const std::vector<NearLight>& lights, const camera::Camera& camera) {
  if (std::string why; !stack.IsValid(&why)) return why;
  if (camera.width_px != stack.width() || camera.height_px != stack.height())
    return "near lights: the camera is " + std::to_string(camera.width_px) + "x" + std::to_string(camera.height_px) +
           " pixels, the images " + std::to_string(stack.width()) + "x" + std::to_string(stack.height());
  if (static_cast<int>(lights.size()) != stack.light_count())
    return "near lights: " + std::to_string(lights.size()) + " LEDs for " + std::to_string(stack.light_count()) + " images";
  // Every LED must stand above the object: the depth search stays below the lowest.
  for (std::size_t k = 0; k < lights.size(); ++k)
    if (!(lights[k].position_mm.z() > 0.0) || !lights[k].position_mm.allFinite())
      return "near light " + std::to_string(k) + " is not above the sample plane (z <= 0)";
  return {};
}

}  // namespace

double NearLight::RelativeIrradiance(const Eigen::Vector3d& point_mm, Eigen::Vector3d* towards_light) const {
  return PreparedLight(*this).RelativeIrradiance(point_mm, towards_light);
}

std::vector<NearLight> LightsAimedAtOrigin(const std::vector<Eigen::Vector3d>& positions_mm, double cos_exponent) {
  std::vector<NearLight> lights;
  for (const Eigen::Vector3d& position : positions_mm)
    lights.push_back({position, -position.normalized(), cos_exponent});
  return lights;
}

double DistantModelBiasDeg(const std::vector<NearLight>& lights, const std::vector<Eigen::Vector3d>& directions,
                           double radius_mm) {
  // A grid of 41 x 41 points over the disk, each seen on the hemisphere.
  constexpr int kSteps = 41;
  double sum = 0.0;
  int count = 0;
  for (int i = 0; i < kSteps; ++i)
    for (int j = 0; j < kSteps; ++j) {
      const double x = (2.0 * (i + 0.5) / kSteps - 1.0) * radius_mm, y = (2.0 * (j + 0.5) / kSteps - 1.0) * radius_mm;
      const double rho2 = x * x + y * y;
      if (rho2 > 0.9 * radius_mm * radius_mm) continue;  // the rim is flagged, not solved
      const Eigen::Vector3d point(x, y, std::sqrt(radius_mm * radius_mm - rho2));
      const Eigen::Vector3d normal = point / radius_mm;
      Eigen::Matrix3d normal_matrix = Eigen::Matrix3d::Zero();
      Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
      int lit = 0;
      for (std::size_t k = 0; k < lights.size(); ++k) {
        Eigen::Vector3d towards;
        const double value = lights[k].RelativeIrradiance(point, &towards) * std::max(0.0, normal.dot(towards));
        if (value <= 0.0) continue;  // a shadow: the distant solve leaves it out too
        normal_matrix.noalias() += directions[k] * directions[k].transpose();
        rhs.noalias() += value * directions[k];
        ++lit;
      }
      if (lit < 3) continue;
      const Eigen::Vector3d b = normal_matrix.ldlt().solve(rhs);
      if (!(b.norm() > 0.0)) continue;
      sum += std::acos(std::clamp(b.normalized().dot(normal), -1.0, 1.0));
      ++count;
    }
  return count > 0 ? RadiansToDegrees(sum / count) : 0.0;
}

bool NearLightOptions::IsValid(std::string* why) const {
  if (std::string camera_why; !camera.IsValid(&camera_why)) return core::Refuse(why, "camera: " + camera_why);
  if (max_rounds < 1 || max_rounds > 100) return core::Refuse(why, "max_rounds must be within [1, 100]");
  if (!(normal_change_tolerance_deg > 0.0)) return core::Refuse(why, "normal_change_tolerance_deg must be > 0");
  if (offset_stride < 1) return core::Refuse(why, "offset_stride must be >= 1");
  return true;
}

NearLightSummary SolveNearLightPhotometricStereo(const PhotometricStereoOptions& options,
                                                 const NearLightOptions& near_options,
                                                 const PhotometricStack& stack, const std::vector<NearLight>& lights,
                                                 NormalMap* result, cv::Mat* height_mm) {
  core::SolveTimer timer;
  NearLightSummary summary;
  summary.method = MethodName(options.method);
  summary.light_count = stack.light_count();
  if (core::EndIfInvalid(options, &summary) || core::EndIfInvalid(near_options, &summary)) return summary;
  if (options.method != Method::kL2 && options.method != Method::kLambertian) {
    summary.End(Termination::kInvalidOptions,
                std::string("near lights are solved with the l2 and lambertian methods; ") + MethodName(options.method) +
                    " fits one light matrix for every pixel");
    return summary;
  }
  if (core::EndIfBadInput(CheckInputs(stack, lights, near_options.camera), &summary)) return summary;
  PixelProblem problem{stack, {lights.begin(), lights.end()}, camera::PixelRays(near_options.camera)};
  problem.exclude_unusable = options.method != Method::kL2;
  problem.shadow_threshold = std::max(options.lambertian.shadow_threshold,
                                      options.shadow_threshold_read_sigmas * stack.noise.read_sigma);
  problem.saturation_level = options.lambertian.saturation_level;
  problem.max_condition_number = options.lambertian.max_condition_number;
  summary.shadow_threshold = problem.shadow_threshold;
  summary.noise_read_sigma = stack.noise.read_sigma;
  summary.noise_shot_gain = stack.noise.shot_gain;

  double lowest_led_mm = std::numeric_limits<double>::infinity();
  for (const NearLight& light : lights) lowest_led_mm = std::min(lowest_led_mm, light.position_mm.z());
  // Round 1 places the surface on the sample plane; each later round at the
  // depth integrated from the previous round's normals.
  cv::Mat height = cv::Mat::zeros(stack.height(), stack.width(), CV_32F);
  AllocateResult(height.size(), result);
  timer.SetupDone(&summary);
  bool converged = false;
  for (int round = 1; round <= near_options.max_rounds; ++round) {
    const cv::Mat previous = round > 1 ? result->normals.clone() : cv::Mat();
    FitAllPixels(problem, height, result);
    summary.rounds = round;
    if (options.progress) options.progress({"near lights", round, near_options.max_rounds, {}});
    if (round > 1) {
      // The mean angle between the two rounds' normals, over the pixels both solved.
      summary.normal_change_deg.push_back(CompareNormals(result->normals, previous).mean_deg);
      if (summary.normal_change_deg.back() < near_options.normal_change_tolerance_deg) {
        converged = true;
        break;
      }
    }
    const core::SolveTimer depth_timer;
    const cv::Mat relative = RelativeDepth(near_options, problem, *result, stack.mask);
    const cv::Mat solved = result->flags == static_cast<int>(PixelFlag::kSolved);
    // The offset lies below the lowest LED and no deeper than that under the
    // plane; a pinhole's scale stays positive.
    double highest_mm = 0.5 * lowest_led_mm;
    if (near_options.camera.IsPinhole()) highest_mm = std::min(highest_mm, 0.9 * near_options.camera.pinhole.distance_mm);
    summary.depth_offset_mm = BestOffset(problem, near_options, solved, relative, -0.5 * lowest_led_mm, highest_mm);
    summary.depth_ms += depth_timer.ElapsedMs();
    for (int r = 0; r < height.rows; ++r)
      for (int c = 0; c < height.cols; ++c)
        height.at<float>(r, c) = static_cast<float>(problem.Height(relative.at<float>(r, c), summary.depth_offset_mm));
  }
  CountPixels(*result, &summary);
  *height_mm = height.clone();
  height_mm->setTo(kNaN, result->flags != static_cast<int>(PixelFlag::kSolved));
  timer.Finish(&summary);
  if (summary.pixels_solved == 0) {
    summary.End(Termination::kFailure, "no pixel could be solved under the near lights");
    return summary;
  }
  summary.termination = converged ? Termination::kSuccess : Termination::kNoConvergence;
  if (!converged)
    summary.message = "the normals still moved " +
                      std::to_string(summary.normal_change_deg.empty() ? 0.0 : summary.normal_change_deg.back()) +
                      " deg in the last of " + std::to_string(near_options.max_rounds) + " rounds";
  return summary;
}

}  // namespace photorig::solvers::ps
