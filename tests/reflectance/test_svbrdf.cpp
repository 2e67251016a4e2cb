#include "svbrdf_scene.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace photorig::testing {
namespace {

using refl::FitReflectance;
using refl::PixelFlag;
using refl::ReflectanceMaps;
using refl::ReflectanceOptions;

// Per true material: the fitted material most of its pixels went to.
std::vector<int> Correspondence(const ReflectanceMaps& truth, const ReflectanceMaps& fit) {
  std::vector<int> out;
  for (std::size_t m = 0; m < truth.materials.size(); ++m) {
    std::vector<int> votes(fit.materials.size(), 0);
    for (int i = 0; i < static_cast<int>(truth.material.total()); ++i)
      if (truth.material.at<std::uint8_t>(i) == m && fit.material.at<std::uint8_t>(i) < fit.materials.size())
        ++votes[fit.material.at<std::uint8_t>(i)];
    out.push_back(static_cast<int>(std::max_element(votes.begin(), votes.end()) - votes.begin()));
  }
  return out;
}

// Median relative albedo error over fitted pixels.
double AlbedoError(const ReflectanceMaps& truth, const ReflectanceMaps& fit) {
  std::vector<double> errors;
  const int C = truth.albedo.channels();
  for (int i = 0; i < static_cast<int>(truth.material.total()); ++i) {
    if (fit.flags.at<std::uint8_t>(i) != static_cast<std::uint8_t>(PixelFlag::kFitted)) continue;
    for (int ch = 0; ch < C; ++ch) {
      const double t = truth.albedo.ptr<float>()[i * C + ch], f = fit.albedo.ptr<float>()[i * C + ch];
      errors.push_back(std::abs(f - t) / t);
    }
  }
  std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
  return errors[errors.size() / 2];
}

TEST(Svbrdf, ThreeMaterialsInColourAreFoundWithTheirLobes) {
  const SvbrdfScene scene = MakeScene(ThreeMaterials());
  ReflectanceMaps fit;
  const auto summary = FitReflectance({}, scene.stack, scene.truth.normals, scene.mask, &fit);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  ASSERT_EQ(summary.materials, 3);
  const std::vector<int> match = Correspondence(scene.truth, fit);
  for (std::size_t m = 0; m < 3; ++m) {
    const auto& t = scene.truth.materials[m];
    const auto& f = fit.materials[match[m]];
    EXPECT_EQ(f.model, t.model) << "material " << m;
    if (t.model != brdf::Model::kLambertian && f.model == t.model) {
      EXPECT_NEAR(f.shape / t.shape, 1.0, 0.05) << "material " << m;
      for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(f.specular[ch] / t.specular[ch], 1.0, 0.05) << "material " << m;
    }
    EXPECT_TRUE(f.warnings.empty()) << "material " << m;
  }
  EXPECT_LT(AlbedoError(scene.truth, fit), 0.01);
  // Unflagged pixels whose band boundary a material reaches across are few.
  int wrong = 0;
  for (int i = 0; i < static_cast<int>(scene.truth.material.total()); ++i) {
    if (fit.flags.at<std::uint8_t>(i) != static_cast<std::uint8_t>(PixelFlag::kFitted)) continue;
    const int t = scene.truth.material.at<std::uint8_t>(i);
    if (t < 3 && fit.material.at<std::uint8_t>(i) != match[t]) ++wrong;
  }
  EXPECT_LT(wrong, 0.02 * summary.pixels_fitted);
}

TEST(Svbrdf, TwoMaterialsInMonochromeAreTold) {
  SceneSpec spec;
  spec.channels = 1;
  spec.materials = {Matte(), Phong(0.3, 40.0)};
  const SvbrdfScene scene = MakeScene(spec);
  ReflectanceMaps fit;
  const auto summary = FitReflectance({}, scene.stack, scene.truth.normals, scene.mask, &fit);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  ASSERT_EQ(summary.materials, 2);
  const std::vector<int> match = Correspondence(scene.truth, fit);
  EXPECT_EQ(fit.materials[match[0]].model, brdf::Model::kLambertian);
  EXPECT_EQ(fit.materials[match[1]].model, brdf::Model::kBlinnPhong);
  EXPECT_NEAR(fit.materials[match[1]].shape / 40.0, 1.0, 0.05);
  EXPECT_LT(AlbedoError(scene.truth, fit), 0.01);
}

// A colour camera's demosaicing blends the pixels on either side of a paint
// edge (here two thirds of the pixel's own paint, a third of the other's):
// the blends are flagged mixed before the materials are chosen, and
// assigned a material once they are; the two paints stay two materials.
TEST(Svbrdf, BlendsAlongAPaintEdgeAreFlaggedMixedThenAssigned) {
  SceneSpec spec;
  spec.materials = {Matte(), Phong(0.3, 40.0)};
  spec.band_colour = {Eigen::Vector3d(0.9, 0.6, 0.4), Eigen::Vector3d(0.4, 0.7, 0.9)};
  SvbrdfScene scene = MakeScene(spec);
  cv::Mat blended(scene.mask.size(), CV_8U, cv::Scalar(0));
  const cv::Mat& truth = scene.truth.material;
  for (cv::Mat& image : scene.stack.images) {
    const cv::Mat original = image.clone();
    for (int r = 0; r < truth.rows; ++r)
      for (int c = 0; c + 1 < truth.cols; ++c) {
        if (truth.at<std::uint8_t>(r, c) == 255 || truth.at<std::uint8_t>(r, c + 1) == 255 ||
            truth.at<std::uint8_t>(r, c) == truth.at<std::uint8_t>(r, c + 1))
          continue;
        const cv::Vec3f a = original.at<cv::Vec3f>(r, c), b = original.at<cv::Vec3f>(r, c + 1);
        image.at<cv::Vec3f>(r, c) = (2.0f / 3.0f) * a + (1.0f / 3.0f) * b;
        image.at<cv::Vec3f>(r, c + 1) = (1.0f / 3.0f) * a + (2.0f / 3.0f) * b;
        blended.at<std::uint8_t>(r, c) = blended.at<std::uint8_t>(r, c + 1) = 1;
      }
  }
  ReflectanceMaps fit;
  const auto summary = FitReflectance({}, scene.stack, scene.truth.normals, scene.mask, &fit);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  int blends = 0, blends_flagged = 0, assigned = 0;
  for (int i = 0; i < static_cast<int>(blended.total()); ++i) {
    const bool mixed = fit.flags.at<std::uint8_t>(i) == static_cast<std::uint8_t>(PixelFlag::kMixed);
    assigned += mixed && fit.material.at<std::uint8_t>(i) < fit.materials.size();
    if (!blended.at<std::uint8_t>(i) || fit.flags.at<std::uint8_t>(i) == static_cast<std::uint8_t>(PixelFlag::kOutsideMask))
      continue;
    ++blends;
    blends_flagged += mixed;
  }
  EXPECT_GT(blends_flagged, 0.8 * blends);
  EXPECT_EQ(assigned, summary.pixels_mixed_assigned);
  EXPECT_GT(summary.pixels_mixed_assigned, 0);
  // The rim (whose window reaches off the object) and the blends, little else.
  EXPECT_LT(summary.pixels_mixed, 0.35 * (summary.pixels_fitted + summary.pixels_mixed));
  EXPECT_EQ(summary.materials, 2);
}

TEST(Svbrdf, AMatteObjectIsOneMaterialWithoutALobe) {
  SceneSpec spec;
  spec.materials = {Matte()};
  spec.band_colour = {Eigen::Vector3d(0.8, 0.7, 0.6)};
  const SvbrdfScene scene = MakeScene(spec);
  ReflectanceMaps fit;
  const auto summary = FitReflectance({}, scene.stack, scene.truth.normals, scene.mask, &fit);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  EXPECT_EQ(summary.materials, 1);
  EXPECT_EQ(fit.materials[0].model, brdf::Model::kLambertian);
  EXPECT_LT(AlbedoError(scene.truth, fit), 0.01);
}

TEST(Svbrdf, UnusablePixelsAreFlaggedNotGuessed) {
  SceneSpec spec = ThreeMaterials(1);
  SvbrdfScene scene = MakeScene(spec);
  cv::Mat normals = scene.truth.normals.clone();
  normals.at<cv::Vec3f>(32, 32) = cv::Vec3f(NAN, NAN, NAN);
  // A pixel every image shows dark: no usable sample.
  for (auto& image : scene.stack.images) image.ptr<float>(20)[20] = NAN;
  ReflectanceMaps fit;
  const auto summary = FitReflectance({}, scene.stack, normals, scene.mask, &fit);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  EXPECT_EQ(fit.flags.at<std::uint8_t>(32, 32), static_cast<std::uint8_t>(PixelFlag::kNoNormal));
  EXPECT_EQ(fit.flags.at<std::uint8_t>(20, 20), static_cast<std::uint8_t>(PixelFlag::kTooFewSamples));
  EXPECT_TRUE(std::isnan(fit.albedo.ptr<float>(20)[20]));
  EXPECT_EQ(fit.flags.at<std::uint8_t>(0, 0), static_cast<std::uint8_t>(PixelFlag::kOutsideMask));
  EXPECT_EQ(summary.pixels_no_normal, 1);
  EXPECT_EQ(summary.pixels_too_few_samples, 1);
}

TEST(Svbrdf, BadOptionsAndInputsEndWithoutAResult) {
  const SvbrdfScene scene = MakeScene(ThreeMaterials(1));
  ReflectanceMaps fit;
  ReflectanceOptions options;
  options.max_materials = 0;
  EXPECT_EQ(FitReflectance(options, scene.stack, scene.truth.normals, scene.mask, &fit).termination,
            solvers::core::Termination::kInvalidOptions);
  options = {};
  options.lobes = {brdf::Model::kLambertian};
  EXPECT_EQ(FitReflectance(options, scene.stack, scene.truth.normals, scene.mask, &fit).termination,
            solvers::core::Termination::kInvalidOptions);
  auto stack = scene.stack;
  stack.light_directions.pop_back();
  EXPECT_EQ(FitReflectance({}, stack, scene.truth.normals, scene.mask, &fit).termination,
            solvers::core::Termination::kInvalidInput);
  EXPECT_EQ(FitReflectance({}, scene.stack, cv::Mat(3, 3, CV_32FC3), scene.mask, &fit).termination,
            solvers::core::Termination::kInvalidInput);
  EXPECT_EQ(FitReflectance({}, scene.stack, scene.truth.normals, cv::Mat::zeros(scene.mask.size(), CV_8U), &fit)
                .termination,
            solvers::core::Termination::kFailure);
}

TEST(Svbrdf, RenderingAFlatPixelIsTheBrdfModel) {
  refl::ReflectanceMaps maps;
  maps.materials = {Ggx(0.5, 0.2)};
  maps.normals = cv::Mat(1, 1, CV_32FC3, cv::Scalar(0, 0, 1));
  maps.albedo = cv::Mat(1, 1, CV_32FC3, cv::Scalar(0.2, 0.4, 0.6));
  maps.material = cv::Mat(1, 1, CV_8U, cv::Scalar(0));
  maps.flags = cv::Mat(1, 1, CV_8U, cv::Scalar(0));
  const Eigen::Vector3d wi = Eigen::Vector3d(0.3, 0.2, 0.9).normalized(), wo = Eigen::Vector3d(-0.2, 0.1, 0.95).normalized();
  cv::Mat image;
  ASSERT_TRUE(refl::RenderReflectance(maps, wi, Eigen::Vector3d(1.0, 2.0, 3.0), wo, &image).IsSolutionUsable());
  const Eigen::Vector3d f = brdf::Evaluate({brdf::Model::kGgx, Eigen::Vector3d(0.2, 0.4, 0.6), Eigen::Vector3d::Constant(0.5), 0.2}, wi, wo);
  for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(image.at<cv::Vec3f>(0, 0)[ch], (ch + 1) * f[ch] * wi.z(), 1e-5);
}

// Through a pinhole every pixel has its own view: each pixel renders as the
// fixed-view render along its own line of sight does.
TEST(Svbrdf, RenderingAlongEachPixelsLineOfSightIsTheFixedViewRenderThere) {
  refl::ReflectanceMaps maps;
  maps.materials = {Phong(0.4, 30.0)};
  maps.normals = cv::Mat(1, 2, CV_32FC3, cv::Scalar(0.1, 0.0, 0.995));
  maps.albedo = cv::Mat(1, 2, CV_32FC1, cv::Scalar(0.5));
  maps.material = cv::Mat(1, 2, CV_8U, cv::Scalar(0));
  maps.flags = cv::Mat(1, 2, CV_8U, cv::Scalar(0));
  const Eigen::Vector3d light = Eigen::Vector3d(-0.2, 0.1, 0.97).normalized();
  const Eigen::Vector3d view[2] = {Eigen::Vector3d(0.25, 0.0, 0.97).normalized(), Eigen::Vector3d(-0.2, 0.1, 0.97).normalized()};
  cv::Mat views(1, 2, CV_32FC3), per_pixel;
  for (int c = 0; c < 2; ++c) views.at<cv::Vec3f>(0, c) = cv::Vec3f(float(view[c].x()), float(view[c].y()), float(view[c].z()));
  ASSERT_TRUE(refl::RenderReflectance(maps, light, Eigen::Vector3d::Ones(), views, &per_pixel).IsSolutionUsable());
  for (int c = 0; c < 2; ++c) {
    cv::Mat fixed;
    ASSERT_TRUE(refl::RenderReflectance(maps, light, Eigen::Vector3d::Ones(), view[c], &fixed).IsSolutionUsable());
    EXPECT_NEAR(per_pixel.at<float>(0, c), fixed.at<float>(0, c), 1e-6f * fixed.at<float>(0, c)) << c;
  }
  // The first line of sight meets the light's highlight (n . h = 0.996), the second does not (0.94).
  EXPECT_GT(per_pixel.at<float>(0, 0), 2.0f * per_pixel.at<float>(0, 1));
}

// A glossy sphere (17 mm, seen orthographically at 0.4 mm a pixel) under
// LEDs 80 mm from the origin: each point sees every LED along its own
// direction and with its own irradiance. Given the surface's points, the
// fit recovers the lobe; taking one direction per LED, it cannot.
TEST(Svbrdf, NearLedsAreSeenFromEachPixelsOwnPoint) {
  constexpr int kSize = 96;
  constexpr double kRadiusMm = 17.0, kPitchMm = 0.4, kDomeMm = 80.0, kAlbedo = 0.5;
  const refl::MaterialFit truth = Phong(0.3, 40.0);
  refl::ReflectanceStack stack;
  for (const Eigen::Vector3d& direction : DomeLights()) {
    stack.near_lights.push_back({kDomeMm * direction, -direction, 1.0});
    stack.light_directions.push_back(direction);
    stack.images.emplace_back(kSize, kSize, CV_32F, cv::Scalar(0));
  }
  stack.points_mm = cv::Mat(kSize, kSize, CV_32FC3, cv::Scalar::all(0));
  cv::Mat normals(kSize, kSize, CV_32FC3, cv::Scalar::all(std::nanf(""))), mask = cv::Mat::zeros(kSize, kSize, CV_8U);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.002);
  for (int r = 0; r < kSize; ++r)
    for (int c = 0; c < kSize; ++c) {
      const double x = (c + 0.5 - 0.5 * kSize) * kPitchMm, y = (0.5 * kSize - r - 0.5) * kPitchMm;
      if (x * x + y * y >= 0.95 * kRadiusMm * kRadiusMm) continue;
      const Eigen::Vector3d point(x, y, std::sqrt(kRadiusMm * kRadiusMm - x * x - y * y)), n = point / kRadiusMm;
      stack.points_mm.at<cv::Vec3f>(r, c) = cv::Vec3f(float(point.x()), float(point.y()), float(point.z()));
      normals.at<cv::Vec3f>(r, c) = cv::Vec3f(float(n.x()), float(n.y()), float(n.z()));
      mask.at<std::uint8_t>(r, c) = 255;
      Eigen::Vector3d t, b;
      const Eigen::Vector3d helper = std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
      t = helper.cross(n).normalized(), b = n.cross(t);
      const Eigen::Vector3d wo(t.z(), b.z(), n.z());  // the view, +z, in the point's frame
      for (std::size_t k = 0; k < stack.near_lights.size(); ++k) {
        Eigen::Vector3d towards;
        const double irradiance = stack.near_lights[k].RelativeIrradiance(point, &towards);
        const brdf::Geometry g = brdf::GeometryOf(Eigen::Vector3d(t.dot(towards), b.dot(towards), n.dot(towards)), wo);
        const double f = kAlbedo / M_PI + brdf::EvaluateLobe(truth.model, truth.specular[0], truth.shape, 0.0, g);
        stack.images[k].at<float>(r, c) = static_cast<float>(irradiance * f * std::max(0.0, g.cos_i) + noise(rng));
      }
    }
  stack.noise.read_sigma.setConstant(0.002);
  ReflectanceOptions options;
  options.max_materials = 1;
  ReflectanceMaps near, distant;
  ASSERT_TRUE(FitReflectance(options, stack, normals, mask, &near).IsSolutionUsable());
  ASSERT_EQ(near.materials.size(), 1u);
  EXPECT_EQ(near.materials[0].model, brdf::Model::kBlinnPhong);
  EXPECT_NEAR(near.materials[0].shape / truth.shape, 1.0, 0.03);
  EXPECT_NEAR(near.materials[0].specular[0] / truth.specular[0], 1.0, 0.03);
  ReflectanceMaps grey;  // the truth AlbedoError reads
  grey.albedo = cv::Mat(kSize, kSize, CV_32F, cv::Scalar(kAlbedo));
  grey.material = mask;
  EXPECT_LT(AlbedoError(grey, near), 0.01);
  // One direction per LED: the irradiance falls off unmodelled and the lobe is misplaced.
  refl::ReflectanceStack as_distant = stack;
  as_distant.near_lights.clear();
  as_distant.points_mm.release();
  ASSERT_TRUE(FitReflectance(options, as_distant, normals, mask, &distant).IsSolutionUsable());
  EXPECT_GT(distant.materials[0].rms_residual, 5.0 * near.materials[0].rms_residual);
}

}  // namespace
}  // namespace photorig::testing
