#include "photorig/solvers/ps/evaluation.h"

#include <gtest/gtest.h>

#include <cmath>

namespace photorig::solvers::ps {
namespace {

cv::Vec3f Tilted(double degrees) {
  return cv::Vec3f(static_cast<float>(std::sin(degrees * M_PI / 180)), 0.0f,
                   static_cast<float>(std::cos(degrees * M_PI / 180)));
}

TEST(CompareNormals, ReportsKnownAnglesAndUnresolvedPixels) {
  cv::Mat truth(1, 5, CV_32FC3, cv::Scalar(0, 0, 1));
  cv::Mat estimate(1, 5, CV_32FC3);
  estimate.at<cv::Vec3f>(0, 0) = Tilted(1.0);
  estimate.at<cv::Vec3f>(0, 1) = Tilted(4.0);
  estimate.at<cv::Vec3f>(0, 2) = Tilted(12.0);
  estimate.at<cv::Vec3f>(0, 3) = Tilted(20.0);
  estimate.at<cv::Vec3f>(0, 4) = cv::Vec3f(NAN, NAN, NAN);
  cv::Mat error;
  const AngularErrorStats stats = CompareNormals(estimate, truth, cv::Mat(), &error);
  EXPECT_EQ(stats.pixels_with_truth, 5u);
  EXPECT_EQ(stats.pixels_evaluated, 4u);
  EXPECT_EQ(stats.pixels_unresolved, 1u);
  EXPECT_NEAR(stats.mean_deg, (1 + 4 + 12 + 20) / 4.0, 1e-4);
  EXPECT_NEAR(stats.median_deg, 8.0, 1e-4);
  EXPECT_NEAR(stats.max_deg, 20.0, 1e-4);
  EXPECT_DOUBLE_EQ(stats.fraction_under_5deg, 0.5);
  EXPECT_DOUBLE_EQ(stats.fraction_under_15deg, 0.75);
  EXPECT_NEAR(error.at<float>(0, 2), 12.0f, 1e-4);
  EXPECT_TRUE(std::isnan(error.at<float>(0, 4)));
}

// No pixel with both a normal and a truth gives no figure, not a perfect 0 deg.
TEST(CompareNormals, NoPixelToCompareGivesNaNFigures) {
  const cv::Mat truth(2, 2, CV_32FC3, cv::Scalar(0, 0, 1));
  const cv::Mat estimate(2, 2, CV_32FC3, cv::Scalar(NAN, NAN, NAN));
  const AngularErrorStats stats = CompareNormals(estimate, truth);
  EXPECT_EQ(stats.pixels_evaluated, 0u);
  EXPECT_EQ(stats.pixels_unresolved, 4u);
  for (const double figure : {stats.mean_deg, stats.median_deg, stats.max_deg, stats.fraction_under_5deg})
    EXPECT_TRUE(std::isnan(figure)) << figure;
}

TEST(CompareNormals, SmallAnglesKeepTheirPrecision) {
  cv::Mat truth(1, 1, CV_32FC3, cv::Scalar(0, 0, 1));
  cv::Mat estimate(1, 1, CV_32FC3);
  estimate.at<cv::Vec3f>(0, 0) = Tilted(0.001);
  EXPECT_NEAR(CompareNormals(estimate, truth).mean_deg, 0.001, 1e-5);
  // Maps that cannot be compared say so instead of throwing.
  const AngularErrorStats mismatched = CompareNormals(estimate, cv::Mat(2, 2, CV_32FC3));
  EXPECT_EQ(mismatched.termination, solvers::core::Termination::kInvalidInput);
  EXPECT_EQ(mismatched.pixels_with_truth, 0u);
}

}  // namespace
}  // namespace photorig::solvers::ps
