#include "photorig/solvers/ps/integration.h"

#include "poisson_multigrid.h"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <gtest/gtest.h>
#include <omp.h>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <random>

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

// A mask with what a multigrid must survive: odd sides, a disc with a hole
// and a one-pixel slit, a separate square, a one-pixel-wide line, a lone
// pixel and a diagonal-only pair, 9,000 pixels (above the size solved directly).
cv::Mat AwkwardMask() {
  cv::Mat mask = cv::Mat::zeros(131, 97, CV_8U);
  cv::circle(mask, cv::Point(45, 60), 44, cv::Scalar(255), cv::FILLED);
  cv::circle(mask, cv::Point(40, 55), 9, cv::Scalar(0), cv::FILLED);
  mask(cv::Rect(44, 70, 1, 35)).setTo(0);
  mask(cv::Rect(80, 110, 15, 18)).setTo(255);
  mask(cv::Rect(93, 2, 1, 60)).setTo(255);
  mask.at<std::uint8_t>(125, 5) = 255;
  mask.at<std::uint8_t>(2, 2) = mask.at<std::uint8_t>(3, 3) = 255;
  return mask;
}

// The normal equations L z = b of a mask's 4-neighbour pairs solved by a
// sparse factorisation, each region's constant fixed by holding one pixel
// at 0 (well conditioned, unlike a pull of every pixel towards 0), then
// each region's mean removed: the reference the multigrid must reproduce.
cv::Mat DirectSolve(const cv::Mat& mask, const cv::Mat& b) {
  cv::Mat labels;
  const int regions = cv::connectedComponents(mask, labels, 4, CV_32S);
  std::vector<bool> held(regions, false);
  cv::Mat index(mask.size(), CV_32S, cv::Scalar(-1));
  int n = 0;
  for (int r = 0; r < mask.rows; ++r)
    for (int c = 0; c < mask.cols; ++c)
      if (mask.at<std::uint8_t>(r, c)) {
        const int region = labels.at<int>(r, c);
        if (!held[region]) held[region] = true;  // this pixel stays at 0
        else index.at<int>(r, c) = n++;
      }
  std::vector<Eigen::Triplet<double>> triplets;
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n);
  for (int r = 0; r < mask.rows; ++r)
    for (int c = 0; c < mask.cols; ++c) {
      if (!mask.at<std::uint8_t>(r, c)) continue;
      const int a = index.at<int>(r, c);
      if (a >= 0) rhs[a] = b.at<double>(r, c);
      for (const cv::Point q : {cv::Point(c + 1, r), cv::Point(c, r + 1)}) {
        if (q.x >= mask.cols || q.y >= mask.rows || !mask.at<std::uint8_t>(q)) continue;
        const int other = index.at<int>(q);
        if (a >= 0) triplets.emplace_back(a, a, 1.0);
        if (other >= 0) triplets.emplace_back(other, other, 1.0);
        if (a >= 0 && other >= 0) triplets.emplace_back(a, other, -1.0), triplets.emplace_back(other, a, -1.0);
      }
    }
  Eigen::SparseMatrix<double> matrix(n, n);
  matrix.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> factor(matrix);
  const Eigen::VectorXd solution = factor.solve(rhs);
  cv::Mat z = cv::Mat::zeros(mask.size(), CV_64F);
  std::vector<double> sum(regions, 0.0), count(regions, 0.0);
  for (int r = 0; r < mask.rows; ++r)
    for (int c = 0; c < mask.cols; ++c)
      if (mask.at<std::uint8_t>(r, c)) {
        const int i = index.at<int>(r, c);
        z.at<double>(r, c) = i >= 0 ? solution[i] : 0.0;
        sum[labels.at<int>(r, c)] += z.at<double>(r, c), count[labels.at<int>(r, c)] += 1.0;
      }
  for (int r = 0; r < mask.rows; ++r)
    for (int c = 0; c < mask.cols; ++c)
      if (mask.at<std::uint8_t>(r, c)) z.at<double>(r, c) -= sum[labels.at<int>(r, c)] / count[labels.at<int>(r, c)];
  return z;
}

// A right-hand side A^T d of random pair differences d: consistent, as integration's are.
cv::Mat RandomRightHandSide(const cv::Mat& mask, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> slope(0.3, 1.0);
  cv::Mat b = cv::Mat::zeros(mask.size(), CV_64F);
  for (int r = 0; r < mask.rows; ++r)
    for (int c = 0; c < mask.cols; ++c)
      for (const cv::Point q : {cv::Point(c + 1, r), cv::Point(c, r + 1)}) {
        if (!mask.at<std::uint8_t>(r, c) || q.x >= mask.cols || q.y >= mask.rows || !mask.at<std::uint8_t>(q)) continue;
        const double d = slope(rng);
        b.at<double>(q) += d, b.at<double>(r, c) -= d;
      }
  return b;
}

TEST(PoissonMultigrid, ReproducesTheFactoredSolutionOnAnAwkwardMask) {
  const cv::Mat mask = AwkwardMask();
  ASSERT_GT(cv::countNonZero(mask), internal::PoissonMultigrid::kCoarsestUnknowns);
  const cv::Mat b = RandomRightHandSide(mask, 7);
  internal::PoissonMultigrid multigrid(mask);
  cv::Mat z;
  const internal::PoissonMultigrid::Result result = multigrid.Solve(b, 1e-10, 100, &z);
  ASSERT_TRUE(result.converged) << result.iterations << " iterations, residual " << result.relative_residual;
  // About ten iterations whatever the size: the preconditioner works.
  EXPECT_LE(result.iterations, 20);
  const cv::Mat reference = DirectSolve(mask, b);
  double range_min, range_max;
  cv::minMaxLoc(reference, &range_min, &range_max, nullptr, nullptr, mask);
  EXPECT_LT(cv::norm(z, reference, cv::NORM_INF, mask), 1e-6 * (range_max - range_min));
  EXPECT_EQ(cv::countNonZero((z != 0.0) & (mask == 0)), 0);  // nothing off the mask
}

TEST(PoissonMultigrid, SaysSoWhenItStopsShortAndAnswersAlikeOnAnyThreadCount) {
  const cv::Mat mask = AwkwardMask();
  const cv::Mat b = RandomRightHandSide(mask, 8);
  internal::PoissonMultigrid multigrid(mask);
  cv::Mat z, one_thread, two_threads;
  const internal::PoissonMultigrid::Result short_of_it = multigrid.Solve(b, 1e-10, 2, &z);
  EXPECT_FALSE(short_of_it.converged);
  EXPECT_EQ(short_of_it.iterations, 2);
  EXPECT_GT(short_of_it.relative_residual, 1e-10);
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  ASSERT_TRUE(multigrid.Solve(b, 1e-10, 100, &one_thread).converged);
  omp_set_num_threads(2);
  ASSERT_TRUE(multigrid.Solve(b, 1e-10, 100, &two_threads).converged);
  omp_set_num_threads(threads);
  EXPECT_EQ(cv::norm(one_thread, two_threads, cv::NORM_INF), 0.0);
}

TEST(IntegrateNormals, ALargeMaskIsIntegratedByMultigridToTheFactoredAccuracy) {
  // 160 x 160, a sphere of radius 70: 14,000 pixels, above the direct size.
  cv::Mat normals, height, mask, depth, kept;
  Sphere(160, 70.0, &normals, &height, &mask);
  const IntegrationSummary summary = IntegrateNormals(IntegrationOptions{}, normals, mask, &depth);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  EXPECT_GT(summary.iterations, 0);
  EXPECT_LE(summary.iterations, 20);
  // The trapezoidal error of a curved surface, as on the smaller sphere.
  EXPECT_LT(RmsAfterRemovingMean(depth, height, mask), 0.15);
  // The same as the factored solution of the same equations.
  cv::Mat g = cv::Mat::zeros(mask.size(), CV_64F);
  for (int r = 0; r < mask.rows; ++r)
    for (int c = 0; c < mask.cols; ++c) {
      if (!mask.at<std::uint8_t>(r, c)) continue;
      const cv::Vec3f n = normals.at<cv::Vec3f>(r, c);
      if (c + 1 < mask.cols && mask.at<std::uint8_t>(r, c + 1)) {
        const cv::Vec3f m = normals.at<cv::Vec3f>(r, c + 1);
        const double d = 0.5 * (-n[0] / n[2] - m[0] / m[2]);
        g.at<double>(r, c + 1) += d, g.at<double>(r, c) -= d;
      }
      if (r + 1 < mask.rows && mask.at<std::uint8_t>(r + 1, c)) {
        const cv::Vec3f m = normals.at<cv::Vec3f>(r + 1, c);
        const double d = -0.5 * (-n[1] / n[2] - m[1] / m[2]);
        g.at<double>(r + 1, c) += d, g.at<double>(r, c) -= d;
      }
    }
  const cv::Mat reference = DirectSolve(mask, g);
  cv::Mat depth64;
  depth.convertTo(depth64, CV_64F);
  EXPECT_LT(cv::norm(depth64, reference, cv::NORM_INF, mask), 1e-4);  // float depth of a 65-pixel-high sphere
  // A workspace keeps the levels: the same pixels again cost the iterations alone, same answer.
  IntegrationWorkspace workspace;
  ASSERT_TRUE(IntegrateNormals(IntegrationOptions{}, normals, mask, &kept, &workspace).IsSolutionUsable());
  ASSERT_TRUE(IntegrateNormals(IntegrationOptions{}, normals, mask, &kept, &workspace).IsSolutionUsable());
  EXPECT_EQ(workspace.reuses(), 1);
  EXPECT_EQ(cv::norm(depth, kept, cv::NORM_INF, mask), 0.0);
}

}  // namespace
}  // namespace photorig::solvers::ps
