#include "photorig/solvers/ps/integration.h"

#include <gtest/gtest.h>

#include <cmath>

namespace photorig::solvers::ps {
namespace {

// A hemisphere of radius R pixels centred in the image, and its height.
void Sphere(int size, double radius, cv::Mat* normals, cv::Mat* height, cv::Mat* mask) {
  *normals = cv::Mat(size, size, CV_32FC3, cv::Scalar::all(NAN));
  *height = cv::Mat(size, size, CV_32F, cv::Scalar(NAN));
  *mask = cv::Mat::zeros(size, size, CV_8U);
  for (int r = 0; r < size; ++r)
    for (int c = 0; c < size; ++c) {
      const double x = c + 0.5 - size / 2.0, y = size / 2.0 - r - 0.5;
      const double d2 = x * x + y * y;
      if (d2 >= radius * radius * 0.9) continue;  // stay away from grazing slopes
      const double z = std::sqrt(radius * radius - d2);
      normals->at<cv::Vec3f>(r, c) = cv::Vec3f(float(x / radius), float(y / radius), float(z / radius));
      height->at<float>(r, c) = static_cast<float>(z);
      mask->at<std::uint8_t>(r, c) = 255;
    }
}

double RmsAfterRemovingMean(const cv::Mat& depth, const cv::Mat& truth, const cv::Mat& mask) {
  const double offset = cv::mean(truth, mask)[0] - cv::mean(depth, mask)[0];
  double sum = 0.0;
  int count = 0;
  for (int r = 0; r < depth.rows; ++r)
    for (int c = 0; c < depth.cols; ++c)
      if (mask.at<std::uint8_t>(r, c)) {
        const double e = depth.at<float>(r, c) + offset - truth.at<float>(r, c);
        sum += e * e, ++count;
      }
  return std::sqrt(sum / count);
}

TEST(IntegrateNormals, PoissonRecoversASphereOnItsMask) {
  cv::Mat normals, height, mask, depth;
  Sphere(96, 40.0, &normals, &height, &mask);
  IntegrationOptions options;
  const IntegrationSummary summary = IntegrateNormals(options, normals, mask, &depth);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  EXPECT_EQ(summary.pixels, static_cast<std::size_t>(cv::countNonZero(mask)));
  // Trapezoidal slopes on a curved surface: error well under a pixel of a 40-pixel sphere.
  EXPECT_LT(RmsAfterRemovingMean(depth, height, mask), 0.15);
  EXPECT_TRUE(std::isnan(depth.at<float>(0, 0)));
  EXPECT_NEAR(cv::mean(depth, mask)[0], 0.0, 1e-4);
}

TEST(IntegrateNormals, BlocksGiveTheSurfaceSmoothedOverABlock) {
  cv::Mat normals, height, mask, depth;
  Sphere(96, 40.0, &normals, &height, &mask);
  IntegrationOptions options;
  options.block_px = 3;
  const IntegrationSummary summary = IntegrateNormals(options, normals, mask, &depth);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  // Every pixel of the mask gets a height, interpolated between blocks.
  EXPECT_EQ(summary.pixels, static_cast<std::size_t>(cv::countNonZero(mask)));
  // Smoothing a sphere of radius R over b pixels moves it by about b^2 / (8 R)
  // (0.03 px) inside; the rim's blocks, part outside the mask, by more: 0.34 px
  // RMS in all, against 0.15 px at every pixel.
  EXPECT_LT(RmsAfterRemovingMean(depth, height, mask), 0.4);
  EXPECT_NEAR(cv::mean(depth, mask)[0], 0.0, 1e-4);
  options.block_px = 0;
  EXPECT_FALSE(IntegrateNormals(options, normals, mask, &depth).IsSolutionUsable());
}

TEST(IntegrateNormals, FrankotChellappaIsExactOnPeriodicSurfacesAndBendsAtMaskBorders) {
  // z = 3 sin(2 pi x / 64) cos(2 pi y / 32): periodic on a 64 x 64 image.
  const int n = 64;
  cv::Mat normals(n, n, CV_32FC3), truth(n, n, CV_32F);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      const double x = c, y = -r;
      const double z = 3 * std::sin(2 * M_PI * x / 64) * std::cos(2 * M_PI * y / 32);
      const double zx = 3 * 2 * M_PI / 64 * std::cos(2 * M_PI * x / 64) * std::cos(2 * M_PI * y / 32);
      const double zy = -3 * 2 * M_PI / 32 * std::sin(2 * M_PI * x / 64) * std::sin(2 * M_PI * y / 32);
      const cv::Vec3d v = cv::normalize(cv::Vec3d(-zx, -zy, 1.0));
      normals.at<cv::Vec3f>(r, c) = cv::Vec3f(v);
      truth.at<float>(r, c) = static_cast<float>(z);
    }
  const cv::Mat all(n, n, CV_8U, cv::Scalar(255));
  IntegrationOptions options;
  options.integrator = Integrator::kFrankotChellappa;
  cv::Mat depth;
  ASSERT_TRUE(IntegrateNormals(options, normals, cv::Mat(), &depth).IsSolutionUsable());
  // Spectral differentiation of a band-limited field: exact but for the sampling of the slopes.
  EXPECT_LT(RmsAfterRemovingMean(depth, truth, all), 0.05);

  cv::Mat sphere_normals, height, mask, fc_depth, poisson_depth;
  Sphere(96, 40.0, &sphere_normals, &height, &mask);
  ASSERT_TRUE(IntegrateNormals(options, sphere_normals, mask, &fc_depth).IsSolutionUsable());
  ASSERT_TRUE(IntegrateNormals(IntegrationOptions{}, sphere_normals, mask, &poisson_depth).IsSolutionUsable());
  EXPECT_GT(RmsAfterRemovingMean(fc_depth, height, mask), 2 * RmsAfterRemovingMean(poisson_depth, height, mask));
}

TEST(IntegrateNormals, AWorkspaceFactorsOncePerSetOfPixelsAndChangesNoAnswer) {
  cv::Mat normals, height, mask, alone, kept;
  Sphere(64, 26.0, &normals, &height, &mask);
  IntegrationWorkspace workspace;
  ASSERT_TRUE(IntegrateNormals(IntegrationOptions{}, normals, mask, &alone).IsSolutionUsable());
  ASSERT_TRUE(IntegrateNormals(IntegrationOptions{}, normals, mask, &kept, &workspace).IsSolutionUsable());
  EXPECT_EQ(workspace.reuses(), 0);
  // Other normals on the same pixels: the factorisation is kept, and the
  // depth is the one a fresh solve gives, to the bit.
  cv::Mat tilted = normals.clone();
  tilted.forEach<cv::Vec3f>([](cv::Vec3f& n, const int*) {
    if (n == n) n = cv::normalize(n + cv::Vec3f(0.2f, -0.1f, 0.0f));
  });
  ASSERT_TRUE(IntegrateNormals(IntegrationOptions{}, tilted, mask, &alone).IsSolutionUsable());
  ASSERT_TRUE(IntegrateNormals(IntegrationOptions{}, tilted, mask, &kept, &workspace).IsSolutionUsable());
  EXPECT_EQ(workspace.reuses(), 1);
  EXPECT_EQ(cv::norm(alone, kept, cv::NORM_INF, mask), 0.0);
  // One pixel less: factored anew, and still the fresh answer.
  mask.at<std::uint8_t>(32, 32) = 0;
  ASSERT_TRUE(IntegrateNormals(IntegrationOptions{}, tilted, mask, &alone).IsSolutionUsable());
  ASSERT_TRUE(IntegrateNormals(IntegrationOptions{}, tilted, mask, &kept, &workspace).IsSolutionUsable());
  EXPECT_EQ(workspace.reuses(), 1);
  EXPECT_EQ(cv::norm(alone, kept, cv::NORM_INF, mask), 0.0);
  EXPECT_TRUE(std::isnan(kept.at<float>(32, 32)));
}

TEST(IntegrateNormals, SeparateRegionsAndHolesAreHandled) {
  cv::Mat normals(40, 80, CV_32FC3, cv::Scalar(0.0, 0.0, 1.0));
  // Left block: plane rising to the right with slope 0.5; right block: flat.
  const cv::Vec3d tilted = cv::normalize(cv::Vec3d(-0.5, 0.0, 1.0));
  normals(cv::Rect(0, 0, 30, 40)).setTo(cv::Scalar(tilted[0], tilted[1], tilted[2]));
  cv::Mat mask = cv::Mat::zeros(40, 80, CV_8U);
  mask(cv::Rect(0, 0, 30, 40)).setTo(255);
  mask(cv::Rect(45, 0, 35, 40)).setTo(255);
  mask(cv::Rect(10, 15, 8, 8)).setTo(0);  // a hole
  cv::Mat depth;
  const IntegrationSummary summary = IntegrateNormals(IntegrationOptions{}, normals, mask, &depth);
  ASSERT_TRUE(summary.IsSolutionUsable());
  EXPECT_LT(summary.residual_rms, 1e-5);
  EXPECT_NEAR(depth.at<float>(5, 25) - depth.at<float>(5, 5), 10.0, 1e-3);
  EXPECT_NEAR(depth.at<float>(30, 70) - depth.at<float>(5, 50), 0.0, 1e-3);
  EXPECT_TRUE(std::isnan(depth.at<float>(18, 12)));
}

TEST(IntegrateNormals, GrazingNormalsAreDroppedAndEmptyInputIsAnError) {
  cv::Mat normals(8, 8, CV_32FC3, cv::Scalar(0.0, 0.0, 1.0));
  normals.at<cv::Vec3f>(3, 3) = cv::Vec3f(1.0f, 0.0f, 0.0f);
  cv::Mat depth;
  const IntegrationSummary summary = IntegrateNormals(IntegrationOptions{}, normals, cv::Mat(), &depth);
  ASSERT_TRUE(summary.IsSolutionUsable());
  EXPECT_EQ(summary.pixels_dropped, 1u);
  EXPECT_TRUE(std::isnan(depth.at<float>(3, 3)));
  const cv::Mat nothing(8, 8, CV_32FC3, cv::Scalar::all(NAN));
  const IntegrationSummary empty = IntegrateNormals(IntegrationOptions{}, nothing, cv::Mat(), &depth);
  EXPECT_EQ(empty.termination, solvers::core::Termination::kFailure);
  EXPECT_NE(empty.message.find("no pixel"), std::string::npos);
  IntegrationOptions flat;
  flat.min_normal_z = 1.5;
  EXPECT_EQ(IntegrateNormals(flat, nothing, cv::Mat(), &depth).termination, solvers::core::Termination::kInvalidOptions);
  EXPECT_EQ(IntegrateNormals(IntegrationOptions{}, cv::Mat(8, 8, CV_32F), cv::Mat(), &depth).termination,
            solvers::core::Termination::kInvalidInput);
}

}  // namespace
}  // namespace photorig::solvers::ps
