// Joint refinement of normals and reflectance against the scene's truth:
// perturbed normals come back, true normals stay, and a normal that would
// have to move too far is held and counted, not moved.
#include "svbrdf_scene.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace photorig::testing {
namespace {

// Mean angle (degrees) to the true normals over the scene's object.
double MeanErrorDeg(const SvbrdfScene& scene, const cv::Mat& normals) {
  double sum = 0.0;
  int count = 0;
  for (int i = 0; i < static_cast<int>(scene.mask.total()); ++i) {
    if (!scene.mask.data[i]) continue;
    const cv::Vec3f& a = normals.at<cv::Vec3f>(i);
    const cv::Vec3f& b = scene.truth.normals.at<cv::Vec3f>(i);
    sum += std::acos(std::clamp(static_cast<double>(a.dot(b)) / (cv::norm(a) * cv::norm(b)), -1.0, 1.0)) * 180.0 / M_PI;
    ++count;
  }
  return sum / count;
}

// The true normals tilted by `tilt_deg` in a random direction per pixel.
cv::Mat Perturbed(const SvbrdfScene& scene, double tilt_deg, unsigned seed) {
  cv::Mat out = scene.truth.normals.clone();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> azimuth(0.0, 2.0 * M_PI);
  for (int i = 0; i < static_cast<int>(out.total()); ++i) {
    if (!scene.mask.data[i]) continue;
    const cv::Vec3f& v = out.at<cv::Vec3f>(i);
    const Eigen::Vector3d n(v[0], v[1], v[2]);
    const Eigen::Vector3d a = std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
    const Eigen::Vector3d t = a.cross(n).normalized(), b = n.cross(t);
    const double phi = azimuth(rng), tilt = tilt_deg * M_PI / 180.0;
    const Eigen::Vector3d m = std::cos(tilt) * n + std::sin(tilt) * (std::cos(phi) * t + std::sin(phi) * b);
    out.at<cv::Vec3f>(i) = cv::Vec3f(static_cast<float>(m.x()), static_cast<float>(m.y()), static_cast<float>(m.z()));
  }
  return out;
}

TEST(NormalRefinement, TiltedNormalsComeBackAndTheNoiseModelHolds) {
  const SvbrdfScene scene = MakeScene(ThreeMaterials());
  const cv::Mat tilted = Perturbed(scene, 3.0, 11);
  refl::NormalRefinementOptions options;
  options.fit.max_materials = 3;
  cv::Mat refined;
  refl::ReflectanceMaps maps;
  const auto summary = refl::RefineNormalsAndReflectance(options, scene.stack, tilted, scene.mask, &refined, &maps);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  const double before = MeanErrorDeg(scene, tilted), after = MeanErrorDeg(scene, refined);
  // Measured: 3.00 -> 0.23 degrees, the estimate's own noise (refining the
  // true normals ends at 0.20, next test); reduced chi-square 4.88 -> 0.54
  // (0.46 with the true normals).
  EXPECT_NEAR(before, 3.0, 0.01);
  EXPECT_LT(after, 0.3);
  EXPECT_LT(summary.reduced_chi_square_after, 0.2 * summary.reduced_chi_square_before);
  EXPECT_EQ(summary.reflectance.materials, 3);
  EXPECT_GE(summary.rounds, 1);
  EXPECT_EQ(summary.median_change_deg.size(), static_cast<std::size_t>(summary.rounds));
  EXPECT_EQ(maps.normals.size(), refined.size());
}

TEST(NormalRefinement, TrueNormalsStayWhereTheyAre) {
  const SvbrdfScene scene = MakeScene(ThreeMaterials());
  refl::NormalRefinementOptions options;
  options.fit.max_materials = 3;
  cv::Mat refined;
  refl::ReflectanceMaps maps;
  const auto summary =
      refl::RefineNormalsAndReflectance(options, scene.stack, scene.truth.normals, scene.mask, &refined, &maps);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  // Noise moves them a little (measured median 0.14 degrees, mean error
  // after 0.20: each pixel's normal estimated from its own noisy samples);
  // nothing drifts, and the fit is no worse.
  ASSERT_FALSE(summary.median_change_deg.empty());
  EXPECT_LT(summary.median_change_deg.front(), 0.25);
  EXPECT_LT(MeanErrorDeg(scene, refined), 0.3);
  EXPECT_LE(summary.reduced_chi_square_after, summary.reduced_chi_square_before + 0.02);
}

// Normals 25 degrees off, in one block: moving them back needs more than
// max_change_deg (10), so they are held, counted and left as given.
TEST(NormalRefinement, ANormalThatWouldMoveTooFarIsHeldAndCounted) {
  const SvbrdfScene scene = MakeScene(ThreeMaterials());
  cv::Mat normals = scene.truth.normals.clone();
  const cv::Mat far = Perturbed(scene, 25.0, 5);
  const cv::Rect block(20, 20, 6, 6);
  far(block).copyTo(normals(block));
  refl::NormalRefinementOptions options;
  options.fit.max_materials = 3;
  options.rounds = 1;
  cv::Mat refined;
  refl::ReflectanceMaps maps;
  const auto summary = refl::RefineNormalsAndReflectance(options, scene.stack, normals, scene.mask, &refined, &maps);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  int unchanged = 0, fitted = 0;
  for (int r = block.y; r < block.y + block.height; ++r)
    for (int c = block.x; c < block.x + block.width; ++c) {
      if (maps.material.at<std::uint8_t>(r, c) == 255) continue;
      ++fitted;
      unchanged += refined.at<cv::Vec3f>(r, c) == normals.at<cv::Vec3f>(r, c);
    }
  ASSERT_GT(fitted, 0);
  EXPECT_EQ(unchanged, fitted);
  EXPECT_GE(summary.pixels_held, fitted);
}

TEST(NormalRefinement, BadOptionsEndWithoutAResult) {
  const SvbrdfScene scene = MakeScene(ThreeMaterials());
  refl::NormalRefinementOptions options;
  options.rounds = 0;
  cv::Mat refined;
  refl::ReflectanceMaps maps;
  EXPECT_EQ(refl::RefineNormalsAndReflectance(options, scene.stack, scene.truth.normals, scene.mask, &refined, &maps)
                .termination,
            solvers::Termination::kInvalidOptions);
  options.rounds = 2;
  options.max_change_deg = 0.0;
  EXPECT_EQ(refl::RefineNormalsAndReflectance(options, scene.stack, scene.truth.normals, scene.mask, &refined, &maps)
                .termination,
            solvers::Termination::kInvalidOptions);
  EXPECT_TRUE(refined.empty());
}

}  // namespace
}  // namespace photorig::testing
