#include "photorig/solvers/ps/fill_unresolved.h"

#include "photorig/solvers/ps/evaluation.h"

#include <gtest/gtest.h>

#include <cmath>

namespace photorig::solvers::ps {
namespace {

constexpr int kSize = 96;
constexpr double kRadiusPx = 44.0;
constexpr float kSolvedConfidence = 0.9f;

// A solved sphere: every pixel inside the disc kSolved with its exact normal,
// the rest outside the mask.
NormalMap SolvedSphere() {
  NormalMap map;
  map.normals.create(kSize, kSize, CV_32FC3);
  map.normals.setTo(cv::Scalar::all(NAN));
  map.flags = cv::Mat(kSize, kSize, CV_8U, cv::Scalar(static_cast<int>(PixelFlag::kOutsideMask)));
  map.confidence = cv::Mat::zeros(kSize, kSize, CV_32F);
  for (int r = 0; r < kSize; ++r)
    for (int c = 0; c < kSize; ++c) {
      const double x = (c + 0.5 - kSize / 2.0) / kRadiusPx, y = (r + 0.5 - kSize / 2.0) / kRadiusPx;
      if (x * x + y * y >= 0.98) continue;
      map.normals.at<cv::Vec3f>(r, c) = cv::Vec3f(static_cast<float>(x), static_cast<float>(y),
                                                  static_cast<float>(std::sqrt(1.0 - x * x - y * y)));
      map.flags.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(PixelFlag::kSolved);
      map.confidence.at<float>(r, c) = kSolvedConfidence;
    }
  return map;
}

// Unresolves a square of the map, 2 half_px + 1 wide (as a solve that found
// too few lit samples there).
void Unresolve(NormalMap* map, cv::Point centre, int half_px, PixelFlag why) {
  cv::Mat disc = cv::Mat::zeros(map->flags.size(), CV_8U);
  disc(cv::Rect(centre.x - half_px, centre.y - half_px, 2 * half_px + 1, 2 * half_px + 1)).setTo(255);
  disc &= map->flags == static_cast<int>(PixelFlag::kSolved);
  map->flags.setTo(static_cast<int>(why), disc);
  map->normals.setTo(cv::Scalar::all(NAN), disc);
  map->confidence.setTo(0.0, disc);
}

TEST(FillUnresolvedNormals, HolesInASmoothSurfaceGetNormalsCloseToTheTruthFlaggedFilled) {
  const NormalMap truth = SolvedSphere();
  NormalMap map = SolvedSphere();
  Unresolve(&map, {30, 40}, 4, PixelFlag::kTooFewLights);
  Unresolve(&map, {60, 55}, 3, PixelFlag::kRejectedByModel);
  Unresolve(&map, {48, 70}, 2, PixelFlag::kIllConditioned);
  const cv::Mat holes =
      (map.flags != static_cast<int>(PixelFlag::kSolved)) & (map.flags != static_cast<int>(PixelFlag::kOutsideMask));
  const int hole_pixels = cv::countNonZero(holes);
  ASSERT_GT(hole_pixels, 70);

  const FillSummary summary = FillUnresolvedNormals(FillOptions{}, &map);
  ASSERT_EQ(summary.termination, core::Termination::kSuccess) << summary.message;
  EXPECT_EQ(summary.pixels_filled, static_cast<std::size_t>(hole_pixels));
  EXPECT_EQ(summary.pixels_left, 0u);
  EXPECT_EQ(cv::countNonZero(map.flags == static_cast<int>(PixelFlag::kFilled)), hole_pixels);
  // The sphere's x and y components are harmonic, z nearly so: the filled
  // normals are the truth to a fraction of a degree.
  const AngularErrorStats error = CompareNormals(map.normals, truth.normals, holes);
  EXPECT_EQ(error.pixels_unresolved, 0u);
  EXPECT_EQ(error.pixels_evaluated, static_cast<std::size_t>(hole_pixels));
  EXPECT_LT(error.max_deg, 0.5);
  // Solved pixels and those outside the mask are untouched.
  const cv::Mat solved = map.flags == static_cast<int>(PixelFlag::kSolved);
  EXPECT_EQ(CompareNormals(map.normals, truth.normals, solved).max_deg, 0.0);
  EXPECT_EQ(cv::countNonZero(map.flags == static_cast<int>(PixelFlag::kOutsideMask)),
            cv::countNonZero(truth.flags == static_cast<int>(PixelFlag::kOutsideMask)));
}

TEST(FillUnresolvedNormals, ConfidenceFallsWithTheDistanceFromTheData) {
  NormalMap map = SolvedSphere();
  Unresolve(&map, {48, 48}, 5, PixelFlag::kTooFewLights);
  const FillSummary summary = FillUnresolvedNormals(FillOptions{}, &map);
  ASSERT_EQ(summary.termination, core::Termination::kSuccess);
  EXPECT_EQ(summary.max_distance_px, 6);  // the centre of an 11-pixel square, in 4-neighbour steps
  // Every solved neighbour has the same confidence, so its interpolation is
  // that everywhere: beside a solved pixel it is kept, 6 steps in a sixth.
  EXPECT_NEAR(map.confidence.at<float>(48, 43), kSolvedConfidence, 1e-5);
  EXPECT_NEAR(map.confidence.at<float>(48, 48), kSolvedConfidence / 6, 1e-5);
  EXPECT_LT(summary.mean_confidence, kSolvedConfidence);
  EXPECT_GT(summary.mean_confidence, kSolvedConfidence / 6);
}

TEST(FillUnresolvedNormals, PixelsOutOfReachOrCutOffFromTheDataKeepTheirFlag) {
  NormalMap map = SolvedSphere();
  Unresolve(&map, {48, 48}, 6, PixelFlag::kTooFewLights);
  // An island: unresolved pixels that only the unmasked background touches.
  map.flags.at<std::uint8_t>(2, 2) = static_cast<std::uint8_t>(PixelFlag::kTooFewLights);
  map.flags.at<std::uint8_t>(2, 3) = static_cast<std::uint8_t>(PixelFlag::kTooFewLights);
  FillOptions options;
  options.max_distance_px = 3;
  const FillSummary summary = FillUnresolvedNormals(options, &map);
  ASSERT_EQ(summary.termination, core::Termination::kSuccess);
  EXPECT_EQ(summary.max_distance_px, 3);
  EXPECT_GT(summary.pixels_left, 2u);
  EXPECT_EQ(map.flags.at<std::uint8_t>(48, 48), static_cast<std::uint8_t>(PixelFlag::kTooFewLights));
  EXPECT_TRUE(std::isnan(map.normals.at<cv::Vec3f>(48, 48)[0]));
  EXPECT_EQ(map.flags.at<std::uint8_t>(2, 2), static_cast<std::uint8_t>(PixelFlag::kTooFewLights));
  EXPECT_EQ(map.flags.at<std::uint8_t>(48, 42), static_cast<std::uint8_t>(PixelFlag::kFilled));
  EXPECT_EQ(map.flags.at<std::uint8_t>(48, 45), static_cast<std::uint8_t>(PixelFlag::kTooFewLights));
  EXPECT_EQ(summary.pixels_filled + summary.pixels_left,
            static_cast<std::size_t>(cv::countNonZero(map.flags == static_cast<int>(PixelFlag::kTooFewLights)) +
                                     cv::countNonZero(map.flags == static_cast<int>(PixelFlag::kFilled))));
}

TEST(FillUnresolvedNormals, RefusesBadOptionsAndMapsWithoutTheirPlanes) {
  NormalMap map = SolvedSphere();
  FillOptions options;
  options.max_distance_px = 0;
  EXPECT_EQ(FillUnresolvedNormals(options, &map).termination, core::Termination::kInvalidOptions);
  map.confidence.release();
  const FillSummary summary = FillUnresolvedNormals(FillOptions{}, &map);
  EXPECT_EQ(summary.termination, core::Termination::kInvalidInput);
  EXPECT_NE(summary.message.find("confidence"), std::string::npos);
}

}  // namespace
}  // namespace photorig::solvers::ps
