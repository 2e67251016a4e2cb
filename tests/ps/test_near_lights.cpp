// Near-light photometric stereo against a sphere rendered here with the
// physics written out (inverse square, LED axis, Lambert's cosine): the
// distant model's error on a small dome, the near model's, its rounds and the
// depth it places.

#include "photorig/solvers/camera/camera.h"
#include "photorig/solvers/ps/evaluation.h"
#include "photorig/solvers/ps/integration.h"
#include "photorig/solvers/ps/near_lights.h"
#include "photorig/solvers/ps/photometric_stereo.h"

#include "ps_test_scene.h"
#include "summary_checks.h"

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>

#include <cmath>
#include <random>

namespace photorig::solvers::ps {
namespace {

constexpr double kRadiusMm = 17.0;
constexpr double kPitchMm = 0.3;
constexpr int kSize = 128;

struct NearScene {
  PhotometricStack stack;
  std::vector<camera::NearLight> lights;
  camera::Camera camera;
  cv::Mat normals, height_mm;  // truth
};

// The scenes' pinhole camera: 120 mm above the plane with a 128 px image 21
// degrees wide, so the sphere fills it and its rim is seen 8 degrees off axis.
camera::Camera Pinhole() {
  camera::Camera camera;
  camera.projection = camera::Projection::kPinhole;
  camera.width_px = camera.height_px = kSize;
  camera.pinhole.fx_px = camera.pinhole.fy_px = 350.0;
  camera.pinhole.cx_px = camera.pinhole.cy_px = 0.5 * (kSize - 1);
  camera.pinhole.distance_mm = 120.0;
  return camera;
}

// Where pixel (r, c)'s line of sight first meets a sphere of kRadiusMm
// centred on the origin, written out here rather than taken from the solver:
// vertical lines for an orthographic camera, lines from (0, 0, D) along
// ((c - cx) / fx, -(r - cy) / fy, -1) for an undistorted pinhole.
bool HitSphere(const camera::Camera& camera, int r, int c, Eigen::Vector3d* point) {
  if (!camera.IsPinhole()) {
    const double x = (c + 0.5 - 0.5 * kSize) * kPitchMm, y = (0.5 * kSize - r - 0.5) * kPitchMm;
    const double rho2 = x * x + y * y;
    if (rho2 >= 0.97 * kRadiusMm * kRadiusMm) return false;
    *point = {x, y, std::sqrt(kRadiusMm * kRadiusMm - rho2)};
    return true;
  }
  const camera::PinholeLens& lens = camera.pinhole;
  const Eigen::Vector3d centre(0.0, 0.0, lens.distance_mm);
  const Eigen::Vector3d d = Eigen::Vector3d((c - lens.cx_px) / lens.fx_px, -(r - lens.cy_px) / lens.fy_px, -1.0).normalized();
  // |C + t d|^2 = R^2: t^2 + 2 (C . d) t + |C|^2 - R^2 = 0.
  const double half_b = centre.dot(d), discriminant = half_b * half_b - (centre.squaredNorm() - kRadiusMm * kRadiusMm);
  if (discriminant <= 0.0) return false;
  *point = centre + (-half_b - std::sqrt(discriminant)) * d;
  // The same margin from the silhouette as the orthographic sphere's: the
  // normal at least 10 deg from grazing.
  return point->normalized().dot((centre - *point).normalized()) > std::sin(10.0 * M_PI / 180.0);
}

// A GGX lobe of albedo rho_s and roughness a, without Fresnel:
// rho_s D(h) G1(w) G1(v) / (4 (n . w) (n . v)), D the Trowbridge-Reitz
// distribution and G1 Smith's (the model `auto`'s step 6 fits).
struct GgxLobe {
  double albedo = 0.0, roughness = 0.2;
};

double GgxLobeBrdf(const GgxLobe& lobe, const Eigen::Vector3d& n, const Eigen::Vector3d& w, const Eigen::Vector3d& v) {
  const double nw = n.dot(w), nv = n.dot(v);
  if (lobe.albedo == 0.0 || nw <= 0.0 || nv <= 0.0) return 0.0;
  const double a2 = lobe.roughness * lobe.roughness, nh = std::max(0.0, n.dot((w + v).normalized()));
  const double t = nh * nh * (a2 - 1.0) + 1.0;
  auto g1 = [a2](double c) { return 2.0 * c / (c + std::sqrt(a2 + (1.0 - a2) * c * c)); };
  return lobe.albedo * a2 / (M_PI * t * t) * g1(nw) * g1(nv) / (4.0 * nw * nv);
}

// A sphere of diffuse albedo `diffuse_albedo` centred on the origin (its rim
// on the sample plane) under LEDs on a hemisphere of `dome_radius_mm`, each
// aimed at the origin, emitters of radiance profile cos^mu (Lambertian: mu 1)
// and unit irradiance there; with `lobe` a normalised Blinn-Phong lobe, with
// `ggx` a GGX one, seen along each pixel's line of sight.
NearScene RenderNearSphere(double dome_radius_mm, double noise_sigma = 0.0,
                           const camera::Camera& camera = camera::Camera::Orthographic(kSize, kSize, kPitchMm),
                           double cos_exponent = 1.0, testing::Specular lobe = {}, GgxLobe ggx = {},
                           double diffuse_albedo = 0.6) {
  NearScene scene;
  scene.camera = camera;
  for (const Eigen::Vector3d& direction : testing::RingLights(40, 25, 75))
    scene.lights.push_back({dome_radius_mm * direction, -direction, cos_exponent});
  scene.normals = cv::Mat(kSize, kSize, CV_32FC3, cv::Scalar::all(0));
  scene.height_mm = cv::Mat(kSize, kSize, CV_32F, cv::Scalar(std::nanf("")));
  scene.stack.mask = cv::Mat::zeros(kSize, kSize, CV_8U);
  std::mt19937 rng(11);
  std::normal_distribution<float> noise(0.0f, static_cast<float>(noise_sigma));
  for (std::size_t k = 0; k < scene.lights.size(); ++k) scene.stack.images.emplace_back(kSize, kSize, CV_32F, cv::Scalar(0));
  for (int r = 0; r < kSize; ++r)
    for (int c = 0; c < kSize; ++c) {
      Eigen::Vector3d point;
      if (!HitSphere(camera, r, c, &point)) continue;
      const Eigen::Vector3d n = point / kRadiusMm;
      scene.normals.at<cv::Vec3f>(r, c) = cv::Vec3f(float(n.x()), float(n.y()), float(n.z()));
      scene.height_mm.at<float>(r, c) = static_cast<float>(point.z());
      scene.stack.mask.at<std::uint8_t>(r, c) = 255;
      for (std::size_t k = 0; k < scene.lights.size(); ++k) {
        const camera::NearLight& led = scene.lights[k];
        const Eigen::Vector3d to = led.position_mm - point;
        const double d = to.norm();
        // Radiant intensity cos^mu(axis angle) I0, with I0 = R^2 so that the
        // irradiance at the origin, straight on the axis, is 1.
        const double irradiance = dome_radius_mm * dome_radius_mm * std::pow(-led.axis.dot(to / d), cos_exponent) / (d * d);
        const Eigen::Vector3d view =
            camera.IsPinhole() ? Eigen::Vector3d(Eigen::Vector3d(0, 0, camera.pinhole.distance_mm) - point).normalized()
                               : Eigen::Vector3d::UnitZ();
        const double h = std::max(0.0, n.dot((to / d + view).normalized()));
        const double brdf = diffuse_albedo / M_PI + lobe.albedo * (lobe.exponent + 2.0) / (2.0 * M_PI) * std::pow(h, lobe.exponent) +
                            GgxLobeBrdf(ggx, n, to / d, view);
        const double value = brdf * std::max(0.0, n.dot(to / d)) * irradiance * 1000.0;
        scene.stack.images[k].at<float>(r, c) = static_cast<float>(value) + noise(rng);
      }
    }
  for (const camera::NearLight& led : scene.lights) {
    scene.stack.light_directions.push_back(led.position_mm.normalized());
    scene.stack.light_scales.push_back(1000.0);
  }
  if (noise_sigma > 0.0) scene.stack.noise.read_sigma = noise_sigma;
  return scene;
}

PhotometricStereoOptions Lambertian() {
  PhotometricStereoOptions options;
  options.method = Method::kLambertian;
  options.lambertian.shadow_threshold = 1e-3;
  return options;
}

NearLightOptions Near(const camera::Camera& camera = camera::Camera::Orthographic(kSize, kSize, kPitchMm)) {
  NearLightOptions options;
  options.camera = camera;
  return options;
}

TEST(NearLights, IrradianceFallsWithTheSquareOfDistanceAndTheCosineToTheAxis) {
  const camera::NearLight led{{0.0, 0.0, 100.0}, {0.0, 0.0, -1.0}, 2.0};
  Eigen::Vector3d towards;
  EXPECT_DOUBLE_EQ(led.RelativeIrradiance(Eigen::Vector3d::Zero(), &towards), 1.0);
  EXPECT_NEAR(led.RelativeIrradiance({0.0, 0.0, 50.0}, &towards), 4.0, 1e-12);
  // 100 mm aside at the plane: distance sqrt(2) x 100 mm, 45 deg off the axis.
  EXPECT_NEAR(led.RelativeIrradiance({100.0, 0.0, 0.0}, &towards), 0.5 * 0.5, 1e-12);
  EXPECT_NEAR(towards.x(), -std::sqrt(0.5), 1e-12);
  EXPECT_EQ(led.RelativeIrradiance({0.0, 0.0, 150.0}, &towards), 0.0);  // behind the LED
}

TEST(NearLights, RecoverTheSphereWhereTheDistantModelTiltsItByDegrees) {
  const NearScene scene = RenderNearSphere(80.0);
  NormalMap distant;
  ASSERT_TRUE(SolvePhotometricStereo(Lambertian(), scene.stack, &distant).IsSolutionUsable());
  const AngularErrorStats distant_error = CompareNormals(distant.normals, scene.normals, scene.stack.mask);
  EXPECT_GT(distant_error.mean_deg, 5.0);
  // The bias predicted from the geometry alone matches the distant solve's.
  EXPECT_NEAR(DistantModelBiasDeg(scene.lights, scene.stack.light_directions, kRadiusMm), distant_error.mean_deg,
              0.1 * distant_error.mean_deg);

  NormalMap near;
  cv::Mat height;
  const NearLightSummary summary =
      SolveNearLightPhotometricStereo(Lambertian(), Near(), scene.stack, scene.lights, &near, &height);
  ASSERT_EQ(summary.termination, core::Termination::kSuccess) << summary.message;
  const AngularErrorStats error = CompareNormals(near.normals, scene.normals, scene.stack.mask);
  EXPECT_LT(error.mean_deg, 0.3) << "distant model: " << distant_error.mean_deg << " deg";
  EXPECT_GE(summary.rounds, 3);
  EXPECT_LE(summary.rounds, 8);
  ASSERT_EQ(summary.normal_change_deg.size(), static_cast<std::size_t>(summary.rounds - 1));
  EXPECT_LT(summary.normal_change_deg.back(), Near().normal_change_tolerance_deg);
  // The depth is placed where the model fits best: the sphere's true heights.
  cv::Mat difference;
  cv::absdiff(height, scene.height_mm, difference);
  const cv::Mat inside = (scene.stack.mask != 0) & (height == height);
  EXPECT_LT(cv::mean(difference, inside)[0], 0.5);
}

TEST(NearLights, NoiseLeavesTheNearModelWithinHalfADegree) {
  const NearScene scene = RenderNearSphere(150.0, 2.0);  // about 1 % of a mid-grey sample
  PhotometricStereoOptions options = Lambertian();
  options.shadow_threshold_read_sigmas = 3.0;  // as `photorig solve ps` does: noise on a shadow is no light
  NormalMap near;
  cv::Mat height;
  const NearLightSummary summary =
      SolveNearLightPhotometricStereo(options, Near(), scene.stack, scene.lights, &near, &height);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  EXPECT_LT(CompareNormals(near.normals, scene.normals, scene.stack.mask).mean_deg, 0.5);
}

TEST(NearLights, AnLedsRadianceProfileIsPartOfTheModel) {
  // Narrow emitters (cos^4: half the irradiance 33 deg off the axis) on a
  // near dome, whose profile across the sphere the model must follow.
  const NearScene scene = RenderNearSphere(80.0, 0.0, camera::Camera::Orthographic(kSize, kSize, kPitchMm), 4.0);
  NormalMap near;
  const NearLightSummary summary = SolveNearLightPhotometricStereo(Lambertian(), Near(), scene.stack, scene.lights, &near, nullptr);
  ASSERT_EQ(summary.termination, core::Termination::kSuccess) << summary.message;
  EXPECT_LT(CompareNormals(near.normals, scene.normals, scene.stack.mask).mean_deg, 0.3);
  // Taken as Lambertian emitters, the same LEDs tilt the normals.
  std::vector<camera::NearLight> lambertian = scene.lights;
  for (camera::NearLight& led : lambertian) led.cos_exponent = 1.0;
  NormalMap wrong;
  ASSERT_TRUE(SolveNearLightPhotometricStereo(Lambertian(), Near(), scene.stack, lambertian, &wrong, nullptr).IsSolutionUsable());
  EXPECT_GT(CompareNormals(wrong.normals, scene.normals, scene.stack.mask).mean_deg, 0.5);  // 0.71 deg
}

TEST(NearLights, RoundsOnALatticeLeaveTheNormalsAsOnEveryPixel) {
  const NearScene scene = RenderNearSphere(80.0);
  NearLightOptions every_pixel = Near(), lattice = Near();
  every_pixel.round_step_px = 1;
  lattice.round_step_px = 4;
  NormalMap fine, coarse;
  cv::Mat fine_height, coarse_height;
  ASSERT_TRUE(SolveNearLightPhotometricStereo(Lambertian(), every_pixel, scene.stack, scene.lights, &fine, &fine_height)
                  .IsSolutionUsable());
  const NearLightSummary summary =
      SolveNearLightPhotometricStereo(Lambertian(), lattice, scene.stack, scene.lights, &coarse, &coarse_height);
  ASSERT_EQ(summary.termination, core::Termination::kSuccess) << summary.message;
  EXPECT_LT(CompareNormals(coarse.normals, fine.normals, scene.stack.mask).mean_deg, 0.02);
  EXPECT_EQ(cv::countNonZero(coarse.flags == static_cast<int>(PixelFlag::kSolved)),
            cv::countNonZero(fine.flags == static_cast<int>(PixelFlag::kSolved)));
  // The surface returned is integrated at every pixel either way.
  cv::Mat difference;
  cv::absdiff(coarse_height, fine_height, difference);
  EXPECT_LT(cv::mean(difference, (scene.stack.mask != 0) & (fine_height == fine_height))[0], 0.02);
  // Without a surface asked for, the normals are the same.
  NormalMap normals_only;
  ASSERT_TRUE(SolveNearLightPhotometricStereo(Lambertian(), lattice, scene.stack, scene.lights, &normals_only, nullptr)
                  .IsSolutionUsable());
  EXPECT_EQ(cv::norm(normals_only.normals, coarse.normals, cv::NORM_INF), 0.0);
}

TEST(NearLights, ADepthSearchOnAGridAcrossTheObjectPlacesItAsEveryLatticePixelDoes) {
  // With noise, so that the grid's pixel count is what pins the offset.
  const NearScene scene = RenderNearSphere(80.0, 2.0);
  PhotometricStereoOptions options = Lambertian();
  options.shadow_threshold_read_sigmas = 3.0;  // as `photorig solve ps` does: noise on a shadow is no light
  NearLightOptions grid = Near(), every_pixel = Near();  // grid: offset_stride 0, 16 pixels across
  every_pixel.offset_stride = 1;                          // every pixel of the rounds' lattice
  NormalMap on_grid, on_every_pixel;
  const NearLightSummary placed = SolveNearLightPhotometricStereo(options, grid, scene.stack, scene.lights, &on_grid, nullptr);
  const NearLightSummary reference =
      SolveNearLightPhotometricStereo(options, every_pixel, scene.stack, scene.lights, &on_every_pixel, nullptr);
  ASSERT_EQ(placed.termination, core::Termination::kSuccess) << placed.message;
  ASSERT_EQ(reference.termination, core::Termination::kSuccess) << reference.message;
  // An offset 0.02 mm off turns the light of LEDs 80 mm away by 0.015 deg.
  EXPECT_NEAR(placed.depth_offset_mm, reference.depth_offset_mm, 0.02);
  const double grid_deg = CompareNormals(on_grid.normals, scene.normals, scene.stack.mask).mean_deg;
  EXPECT_NEAR(grid_deg, CompareNormals(on_every_pixel.normals, scene.normals, scene.stack.mask).mean_deg, 0.01);
  EXPECT_LT(grid_deg, 0.5);
  NearLightOptions negative = Near();
  negative.offset_stride = -1;
  EXPECT_FALSE(negative.IsValid(nullptr));
}

TEST(NearLights, PixelsBeyondTheConditionLimitAreFlaggedNotSolved) {
  const NearScene scene = RenderNearSphere(150.0);
  PhotometricStereoOptions options = Lambertian();
  // No three LEDs give a 3 x 3 fit this well conditioned.
  options.lambertian.max_condition_number = 1.01;
  NormalMap near;
  const NearLightSummary summary = SolveNearLightPhotometricStereo(options, Near(), scene.stack, scene.lights, &near, nullptr);
  EXPECT_EQ(summary.pixels_solved, 0u);
  EXPECT_EQ(summary.pixels_ill_conditioned, static_cast<std::size_t>(cv::countNonZero(scene.stack.mask)));
  EXPECT_EQ(summary.termination, core::Termination::kFailure);
}

// The same near stack solved with `lambertian` and with `robust` (noise
// known, shadows at 3 read-noise sigmas): each one's mean error, and the
// robust solve's summary.
struct LambertianAndRobust {
  double lambertian_deg = 0.0, robust_deg = 0.0;
  NearLightSummary robust;
};
LambertianAndRobust SolveBoth(const NearScene& scene) {
  PhotometricStereoOptions options = Lambertian();
  options.shadow_threshold_read_sigmas = 3.0;
  NormalMap lambertian, robust;
  LambertianAndRobust out;
  EXPECT_TRUE(SolveNearLightPhotometricStereo(options, Near(), scene.stack, scene.lights, &lambertian, nullptr)
                  .IsSolutionUsable());
  options.method = Method::kRobust;
  out.robust = SolveNearLightPhotometricStereo(options, Near(), scene.stack, scene.lights, &robust, nullptr);
  out.lambertian_deg = CompareNormals(lambertian.normals, scene.normals, scene.stack.mask).mean_deg;
  out.robust_deg = CompareNormals(robust.normals, scene.normals, scene.stack.mask).mean_deg;
  return out;
}

TEST(NearLights, RobustRefitsLeaveOutliersAsUnderDistantLights) {
  NearScene scene = RenderNearSphere(80.0, 2.0);
  // A highlight-like outlier in each pixel: the sample of one light, picked
  // at random, three times as bright as the model says.
  std::mt19937 rng(17);
  std::uniform_int_distribution<int> pick(0, scene.stack.light_count() - 1);
  for (int r = 0; r < kSize; ++r)
    for (int c = 0; c < kSize; ++c)
      if (scene.stack.mask.at<std::uint8_t>(r, c)) scene.stack.images[pick(rng)].at<float>(r, c) *= 3.0f;
  const LambertianAndRobust solved = SolveBoth(scene);
  ASSERT_EQ(solved.robust.termination, core::Termination::kSuccess) << solved.robust.message;
  EXPECT_GT(solved.lambertian_deg, 2.0);
  EXPECT_LT(solved.robust_deg, 0.5) << "lambertian: " << solved.lambertian_deg << " deg";
  // The pixels whose outlier was left out say so.
  EXPECT_GT(solved.robust.pixels_irls, solved.robust.pixels_solved / 2);
}

TEST(NearLights, RobustOnSamplesWithoutOutliersIsTheLambertianFit) {
  const LambertianAndRobust solved = SolveBoth(RenderNearSphere(80.0, 2.0));
  ASSERT_TRUE(solved.robust.IsSolutionUsable()) << solved.robust.message;
  EXPECT_LT(solved.robust_deg, 1.1 * solved.lambertian_deg)
      << "lambertian " << solved.lambertian_deg << " deg, irls pixels " << solved.robust.pixels_irls << " of "
      << solved.robust.pixels_solved;
}

// The scene solved by `method` with *options (its method set to it): the
// mean error, the summary in *summary.
double SolveGlossy(const NearScene& scene, Method method, PhotometricStereoOptions* options, NearLightSummary* summary) {
  options->method = method;
  NormalMap map;
  *summary = SolveNearLightPhotometricStereo(*options, Near(scene.camera), scene.stack, scene.lights, &map, nullptr);
  EXPECT_TRUE(summary->IsSolutionUsable()) << MethodName(method) << ": " << summary->message;
  testing::ExpectStepsWithinSolve(*summary, summary->depth_ms);
  return CompareNormals(map.normals, scene.normals, scene.stack.mask).mean_deg;
}

// A glossy sphere on a near dome seen through a pinhole: the lobe peaks
// where each pixel's own half vector (its LED and its line of sight) meets
// the normal, so only per-pixel geometry fits it.
TEST(NearLights, LobesAreFittedWithEachPixelsLightsAndLineOfSight) {
  const NearScene scene = RenderNearSphere(80.0, 2.0, Pinhole(), 1.0, testing::Specular{0.1, 60.0});
  PhotometricStereoOptions options = Lambertian();
  options.shadow_threshold_read_sigmas = 3.0;
  auto solve = [&](Method method, NearLightSummary* summary) { return SolveGlossy(scene, method, &options, summary); };
  NearLightSummary lambertian, robust, blinn_phong, automatic;
  const double lambertian_deg = solve(Method::kLambertian, &lambertian);
  const double robust_deg = solve(Method::kRobust, &robust);
  const double blinn_phong_deg = solve(Method::kBlinnPhong, &blinn_phong);
  const double auto_deg = solve(Method::kAuto, &automatic);
  // The highlights tilt the Lambertian fit by 9.6 deg and, as its surface
  // is placed to explain them, misplace it by 3 mm.
  EXPECT_GT(lambertian_deg, 5.0);
  // The refits place the surface by their own misfit: 0.47 deg (robust),
  // 0.16 deg (blinn-phong and auto, whose lobe is the scene's); the matte
  // sphere's floor here is 0.22 deg.
  EXPECT_LT(robust_deg, 0.6) << "lambertian " << lambertian_deg << " deg";
  EXPECT_LT(blinn_phong_deg, 0.3) << "lambertian " << lambertian_deg << " deg";
  EXPECT_LT(auto_deg, 0.3) << "lambertian " << lambertian_deg << " deg";
  EXPECT_GT(blinn_phong.pixels_blinn_phong, blinn_phong.pixels_solved / 4);
  EXPECT_GT(automatic.pixels_blinn_phong, automatic.pixels_solved / 4);
  // Step 7's lobe-shift test, with each pixel's own vectors, tries a sample
  // of the lobes and finds them the scene's reflectance.
  EXPECT_GT(automatic.lobe_shift_sample_tested, 50u);
  EXPECT_LE(automatic.lobe_shift_sample_shifted, 3u);
  EXPECT_FALSE(automatic.lobe_shift_every_lobe);
}

// A GGX lobe's tails read as a broader Blinn-Phong lobe away from its peak,
// so the sphere's pixels reject one shared Blinn-Phong shape and `auto`
// fits them GGX (steps 5 and 6), each with its own light and view vectors:
// 0.25 deg, against 1.0 deg for `blinn-phong` and for `auto` stopped at its
// step 4 (GGX on 7,180 of 7,628 pixels).
TEST(NearLights, AutoFitsAGgxLobeWithEachPixelsLightsAndLineOfSight) {
  const NearScene scene = RenderNearSphere(80.0, 2.0, Pinhole(), 1.0, {}, GgxLobe{0.3, 0.2});
  PhotometricStereoOptions options = Lambertian();
  options.shadow_threshold_read_sigmas = 3.0;
  auto solve = [&](Method method, NearLightSummary* summary) { return SolveGlossy(scene, method, &options, summary); };
  NearLightSummary blinn_phong, automatic, stops_at_step_4;
  const double blinn_phong_deg = solve(Method::kBlinnPhong, &blinn_phong);
  const double auto_deg = solve(Method::kAuto, &automatic);
  options.selection.share_lobe = false;
  options.selection.low_frequency = false;
  const double step_4_deg = solve(Method::kAuto, &stops_at_step_4);
  EXPECT_GT(automatic.pixels_ggx, automatic.pixels_solved / 2);
  EXPECT_EQ(stops_at_step_4.pixels_ggx, 0u);
  EXPECT_LT(auto_deg, 0.4);
  EXPECT_LT(auto_deg, 0.5 * blinn_phong_deg) << "step 4 " << step_4_deg << " deg";
  EXPECT_LT(auto_deg, 0.5 * step_4_deg) << "blinn-phong " << blinn_phong_deg << " deg";
}

// A metal under near lights: a GGX lobe every pixel's samples see over a
// dark diffuse term, so every pixel keeps a lobe of its own and step 5 tests
// the region's own lobes against GGX, each with its own light and view
// vectors; most take it, and `auto` fits the sphere GGX (7,562 of 7,628
// pixels, 0.91 deg against `blinn-phong`'s 3.75; without the own lobes'
// test no pixel took GGX and `auto` was 3.68 deg).
TEST(NearLights, AutoFindsAMetalsLobeIsGgxFromItsOwnLobes) {
  const NearScene scene = RenderNearSphere(80.0, 2.0, Pinhole(), 1.0, {}, GgxLobe{0.9, 0.3}, 0.05);
  PhotometricStereoOptions options = Lambertian();
  options.shadow_threshold_read_sigmas = 3.0;
  NearLightSummary blinn_phong, automatic;
  const double blinn_phong_deg = SolveGlossy(scene, Method::kBlinnPhong, &options, &blinn_phong);
  const double auto_deg = SolveGlossy(scene, Method::kAuto, &options, &automatic);
  EXPECT_GT(automatic.pixels_ggx, automatic.pixels_solved / 2);
  EXPECT_LT(auto_deg, 0.5 * blinn_phong_deg) << "blinn-phong " << blinn_phong_deg << " deg";
}

// `low-frequency` under near lights: its rounds place the surface with the
// Lambertian fit, then every pixel is fitted once with its own light and
// view vectors. On the glossy sphere its error (2.15 deg) is between the
// Lambertian fit's (9.6, which the highlights tilt) and the scene's own
// lobe's (0.16): it drops the highlight's core, and its quadratic in n . h
// cannot follow the rest of a lobe of exponent 60.
TEST(NearLights, TheLowFrequencyFitTakesEachPixelsLightsAndLineOfSight) {
  const NearScene scene = RenderNearSphere(80.0, 2.0, Pinhole(), 1.0, testing::Specular{0.1, 60.0});
  PhotometricStereoOptions options = Lambertian();
  options.shadow_threshold_read_sigmas = 3.0;
  NearLightSummary lambertian, low_frequency;
  const double lambertian_deg = SolveGlossy(scene, Method::kLambertian, &options, &lambertian);
  const double low_deg = SolveGlossy(scene, Method::kLowFrequency, &options, &low_frequency);
  EXPECT_GT(low_frequency.pixels_low_frequency, low_frequency.pixels_solved * 9 / 10);
  EXPECT_LT(low_deg, 0.5 * lambertian_deg) << "lambertian " << lambertian_deg << " deg";
  EXPECT_LT(low_deg, 3.0);
}

TEST(NearLights, DistantLightsThroughAPinholeFitEachPixelsLineOfSight) {
  // LEDs a kilometre away are distant to a 34 mm sphere to a millionth; the
  // solver is given them as lights at infinity.
  const NearScene scene = RenderNearSphere(1e6, 2.0, Pinhole(), 1.0, testing::Specular{0.1, 60.0});
  std::vector<camera::NearLight> distant;
  for (const Eigen::Vector3d& direction : scene.stack.light_directions) distant.push_back(camera::NearLight::AtInfinity(direction));
  PhotometricStereoOptions options = Lambertian();
  options.shadow_threshold_read_sigmas = 3.0;
  options.method = Method::kBlinnPhong;
  NormalMap map;
  cv::Mat height;
  const NearLightSummary summary =
      SolveNearLightPhotometricStereo(options, Near(scene.camera), scene.stack, distant, &map, &height);
  ASSERT_EQ(summary.termination, core::Termination::kSuccess) << summary.message;
  EXPECT_EQ(summary.rounds, 1);  // nothing depends on the depth
  const double per_pixel_deg = CompareNormals(map.normals, scene.normals, scene.stack.mask).mean_deg;
  EXPECT_LT(per_pixel_deg, 0.3);
  EXPECT_GT(summary.pixels_blinn_phong, summary.pixels_solved / 4);
  // The distant solve fits the lobes with the view along the camera's axis:
  // 0.65 deg here against 0.19 deg through each pixel's line of sight.
  NormalMap along_axis;
  ASSERT_TRUE(SolvePhotometricStereo(options, scene.stack, &along_axis).IsSolutionUsable());
  EXPECT_GT(CompareNormals(along_axis.normals, scene.normals, scene.stack.mask).mean_deg, 2.0 * per_pixel_deg);
  // The surface through the lens, placed with its geometric-mean distance on the sample plane.
  EXPECT_EQ(cv::countNonZero(height == height), summary.pixels_solved);
}

// On a matte sphere `auto` keeps the Lambertian fit: a lobe must pay for its
// two parameters, and noise alone does not.
TEST(NearLights, AutoFitsNoLobeWhereTheSamplesShowNone) {
  const NearScene scene = RenderNearSphere(80.0, 2.0, Pinhole());
  PhotometricStereoOptions options = Lambertian();
  options.shadow_threshold_read_sigmas = 3.0;
  options.method = Method::kAuto;
  NormalMap map;
  const NearLightSummary summary =
      SolveNearLightPhotometricStereo(options, Near(scene.camera), scene.stack, scene.lights, &map, nullptr);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  EXPECT_LT(summary.pixels_blinn_phong, summary.pixels_solved / 100);
  EXPECT_LT(CompareNormals(map.normals, scene.normals, scene.stack.mask).mean_deg, 0.5);
}

TEST(NearLights, AnLedBelowTheSamplePlaneIsInvalidInput) {
  NearScene scene = RenderNearSphere(400.0);
  scene.lights[3].position_mm.z() = -5.0;
  NormalMap near;
  cv::Mat height;
  const NearLightSummary summary =
      SolveNearLightPhotometricStereo(Lambertian(), Near(), scene.stack, scene.lights, &near, &height);
  EXPECT_EQ(summary.termination, core::Termination::kInvalidInput);
  EXPECT_NE(summary.message.find("near light 3"), std::string::npos) << summary.message;
}

TEST(NearLights, APinholeCameraGivesEveryPixelItsOwnLineOfSight) {
  const NearScene scene = RenderNearSphere(80.0, 0.0, Pinhole());
  NormalMap near;
  cv::Mat height;
  const NearLightSummary summary =
      SolveNearLightPhotometricStereo(Lambertian(), Near(scene.camera), scene.stack, scene.lights, &near, &height);
  ASSERT_EQ(summary.termination, core::Termination::kSuccess) << summary.message;
  EXPECT_LT(CompareNormals(near.normals, scene.normals, scene.stack.mask).mean_deg, 0.3);
  // The scale about the camera's centre is placed where the model fits: the true heights.
  cv::Mat difference;
  cv::absdiff(height, scene.height_mm, difference);
  EXPECT_LT(cv::mean(difference, (scene.stack.mask != 0) & (height == height))[0], 0.5);

  // The same stack taken as orthographic (the pixel size at the sample plane) is measurably off.
  NormalMap as_orthographic;
  const NearLightSummary wrong = SolveNearLightPhotometricStereo(
      Lambertian(), Near(camera::Camera::Orthographic(kSize, kSize, scene.camera.pinhole.distance_mm / scene.camera.pinhole.fx_px)),
      scene.stack, scene.lights, &as_orthographic, &height);
  ASSERT_TRUE(wrong.IsSolutionUsable()) << wrong.message;
  EXPECT_GT(CompareNormals(as_orthographic.normals, scene.normals, scene.stack.mask).mean_deg, 1.0);
}

TEST(NearLights, ACameraOfAnotherSizeThanTheImagesIsInvalidInput) {
  const NearScene scene = RenderNearSphere(400.0);
  NormalMap near;
  cv::Mat height;
  const NearLightSummary summary = SolveNearLightPhotometricStereo(
      Lambertian(), Near(camera::Camera::Orthographic(kSize + 1, kSize, kPitchMm)), scene.stack, scene.lights, &near, &height);
  EXPECT_EQ(summary.termination, core::Termination::kInvalidInput);
  EXPECT_NE(summary.message.find("129x128"), std::string::npos) << summary.message;
}

TEST(PerspectiveIntegration, RecoversTheSpheresHeightsInMillimetres) {
  const NearScene scene = RenderNearSphere(400.0, 0.0, Pinhole());
  const camera::PixelRays rays(scene.camera);
  IntegrationOptions options;
  cv::Mat height;
  const IntegrationSummary summary = IntegrateNormalsPerspective(options, rays, scene.normals, scene.stack.mask, &height);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  // The shape is fixed up to a scale about the camera's centre: scale the
  // truth's distances to the same geometric mean and compare heights.
  const cv::Mat both = (scene.stack.mask != 0) & (height == height);
  double log_sum = 0.0, count = 0.0;
  for (int r = 0; r < kSize; ++r)
    for (int c = 0; c < kSize; ++c)
      if (both.at<std::uint8_t>(r, c)) log_sum += std::log(scene.camera.pinhole.distance_mm - scene.height_mm.at<float>(r, c)), ++count;
  const double scale = scene.camera.pinhole.distance_mm / std::exp(log_sum / count);
  double squared = 0.0;
  for (int r = 0; r < kSize; ++r)
    for (int c = 0; c < kSize; ++c)
      if (both.at<std::uint8_t>(r, c)) {
        const double truth = scene.camera.pinhole.distance_mm - scale * (scene.camera.pinhole.distance_mm - scene.height_mm.at<float>(r, c));
        squared += std::pow(height.at<float>(r, c) - truth, 2);
      }
  const double rms_mm = std::sqrt(squared / count);
  EXPECT_LT(rms_mm, 0.05) << "of a sphere " << 2 * kRadiusMm << " mm across";
  EXPECT_LT(summary.residual_rms, 0.05);

  // Integrating the same normals as if orthographic bends the shape by far more.
  IntegrationOptions orthographic;
  orthographic.pixel_pitch = scene.camera.pinhole.distance_mm / scene.camera.pinhole.fx_px;
  cv::Mat flat_height;
  ASSERT_TRUE(IntegrateNormals(orthographic, scene.normals, scene.stack.mask, &flat_height).IsSolutionUsable());
  double wrong_squared = 0.0;
  const double flat_mean = cv::mean(flat_height, both)[0], true_mean = cv::mean(scene.height_mm, both)[0];
  for (int r = 0; r < kSize; ++r)
    for (int c = 0; c < kSize; ++c)
      if (both.at<std::uint8_t>(r, c))
        wrong_squared += std::pow(flat_height.at<float>(r, c) - flat_mean - (scene.height_mm.at<float>(r, c) - true_mean), 2);
  EXPECT_GT(std::sqrt(wrong_squared / count), 10.0 * rms_mm);
}

TEST(PixelRays, ALensesDistortedPixelSeesThePointOpenCvProjectsOntoIt) {
  camera::Camera camera = Pinhole();
  camera::PinholeLens& lens = camera.pinhole;
  lens.distortion = {-0.2, 0.05, 0.001, -0.002, 0.0};
  const camera::PixelRays rays(camera);
  const cv::Matx33d k(lens.fx_px, 0, lens.cx_px, 0, lens.fy_px, lens.cy_px, 0, 0, 1);
  for (const auto& [r, c] : {std::pair{0, 0}, std::pair{5, 120}, std::pair{64, 64}, std::pair{127, 3}}) {
    const Eigen::Vector3d point = rays.Point(r, c, 12.5);
    // OpenCV's camera frame: x right, y down, z forward (down -z here).
    const std::vector<cv::Point3d> object{{point.x(), -point.y(), lens.distance_mm - point.z()}};
    std::vector<cv::Point2d> image;
    cv::projectPoints(object, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), k, lens.distortion, image);
    EXPECT_NEAR(image[0].x, c, 1e-3);
    EXPECT_NEAR(image[0].y, r, 1e-3);
    EXPECT_NEAR((rays.ViewDirection(r, c) - (Eigen::Vector3d(0, 0, lens.distance_mm) - point).normalized()).norm(), 0.0, 1e-6);
  }
}

TEST(PixelRays, ALatticeIsACameraOfItsOwnWhosePixelsSeeTheImagesRays) {
  camera::Camera camera = Pinhole();
  camera.pinhole.distortion = {-0.2, 0.05, 0.001, -0.002, 0.0};
  const camera::PixelRays rays(camera);
  const camera::PixelRays lattice = rays.Lattice(5, 2);
  ASSERT_EQ(lattice.camera().width_px, 26);  // columns 2, 7, ..., 127
  ASSERT_EQ(lattice.camera().height_px, 26);
  // The lattice's own camera, its lines worked out afresh, sees the same rays.
  const camera::PixelRays afresh(lattice.camera());
  for (const auto& [r, c] : {std::pair{0, 0}, std::pair{3, 25}, std::pair{13, 13}, std::pair{25, 1}}) {
    EXPECT_EQ(lattice.Point(r, c, 12.5), rays.Point(2 + 5 * r, 2 + 5 * c, 12.5));
    EXPECT_NEAR((afresh.Point(r, c, 12.5) - lattice.Point(r, c, 12.5)).norm(), 0.0, 1e-4);
  }
  // An orthographic camera's lattice keeps its pixels' places, a step of pitches apart.
  const camera::PixelRays flat(camera::Camera::Orthographic(kSize, kSize, kPitchMm));
  const camera::PixelRays flat_lattice = flat.Lattice(4, 1);
  EXPECT_DOUBLE_EQ(flat_lattice.camera().pixel_pitch_mm, 4 * kPitchMm);
  EXPECT_EQ(flat_lattice.Point(3, 7, 0.0), flat.Point(13, 29, 0.0));
  EXPECT_NEAR(flat_lattice.Point(3, 8, 0.0).x() - flat_lattice.Point(3, 7, 0.0).x(), 4 * kPitchMm, 1e-6);
}

}  // namespace
}  // namespace photorig::solvers::ps
