#include "photorig/solvers/lighting/inverse_lighting.h"
#include "photorig/solvers/lighting/nnls.h"
#include "photorig/solvers/lighting/relight.h"
#include "photorig/solvers/lighting/spherical_harmonics.h"
#include "solver_output.h"
#include "synthetic_sphere.h"

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <random>

namespace photorig::solvers::lighting {
namespace {

using testing::OutputOf;

TEST(SphericalHarmonics, MatchesClosedFormsAndIsOrthonormal) {
  const Eigen::Vector3d d = Eigen::Vector3d(0.3, -0.5, 0.8).normalized();
  const Eigen::VectorXd y = EvaluateSh(2, d);
  EXPECT_NEAR(y(0), 0.282095, 1e-6);
  EXPECT_NEAR(y(1), 0.488603 * d.y(), 1e-6);
  EXPECT_NEAR(y(2), 0.488603 * d.z(), 1e-6);
  EXPECT_NEAR(y(3), 0.488603 * d.x(), 1e-6);
  EXPECT_NEAR(y(4), 1.092548 * d.x() * d.y(), 1e-6);
  EXPECT_NEAR(y(6), 0.315392 * (3 * d.z() * d.z() - 1), 1e-6);
  EXPECT_NEAR(y(8), 0.546274 * (d.x() * d.x() - d.y() * d.y()), 1e-6);
  EXPECT_NEAR(LambertianKernel(2), M_PI / 4, 1e-12);
  EXPECT_NEAR(LambertianKernel(4), -M_PI / 24, 1e-12);
  EXPECT_EQ(LambertianKernel(3), 0.0);
  // Gram matrix over a fine latitude-longitude grid.
  Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(25, 25);
  const int rows = 200, cols = 400;
  for (int i = 0; i < rows; ++i) {
    const double theta = M_PI * (i + 0.5) / rows;
    for (int j = 0; j < cols; ++j) {
      const double phi = 2 * M_PI * (j + 0.5) / cols;
      const Eigen::VectorXd v = EvaluateSh(4, {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)});
      gram += v * v.transpose() * (std::sin(theta) * M_PI / rows * 2 * M_PI / cols);
    }
  }
  EXPECT_LT((gram - Eigen::MatrixXd::Identity(25, 25)).cwiseAbs().maxCoeff(), 1e-3);
}

TEST(Nnls, MatchesBruteForceOverActiveSets) {
  std::mt19937 rng(5);
  std::normal_distribution<double> normal;
  Eigen::MatrixXd a(30, 5);
  Eigen::VectorXd b(30);
  for (int i = 0; i < 30; ++i) {
    b(i) = normal(rng);
    for (int j = 0; j < 5; ++j) a(i, j) = normal(rng);
  }
  Eigen::VectorXd x;
  ASSERT_EQ(SolveNnls(a, b, &x).termination, solvers::core::Termination::kSuccess);
  EXPECT_GE(x.minCoeff(), 0.0);
  double best = HUGE_VAL;
  for (int set = 0; set < 32; ++set) {  // every subset: unconstrained solve, keep feasible ones
    std::vector<int> index;
    for (int j = 0; j < 5; ++j) if (set & (1 << j)) index.push_back(j);
    Eigen::MatrixXd sub(30, index.size());
    for (std::size_t k = 0; k < index.size(); ++k) sub.col(static_cast<Eigen::Index>(k)) = a.col(index[k]);
    const Eigen::VectorXd s = index.empty() ? Eigen::VectorXd() : Eigen::VectorXd(sub.colPivHouseholderQr().solve(b));
    if (!index.empty() && s.minCoeff() < 0) continue;
    best = std::min(best, index.empty() ? b.squaredNorm() : (sub * s - b).squaredNorm());
  }
  EXPECT_NEAR((a * x - b).squaredNorm(), best, 1e-9);
}

class InverseLighting : public ::testing::Test {
 protected:
  void SetUp() override {
    testing::SphereNormals(160, 0.95, &normals_, &mask_);
    albedo_ = cv::Mat(normals_.size(), CV_32F);
    for (int r = 0; r < albedo_.rows; ++r)
      for (int c = 0; c < albedo_.cols; ++c) albedo_.at<float>(r, c) = ((r / 16 + c / 16) % 2) ? 0.8f : 0.4f;
    truth_ = Eigen::MatrixXd(9, 3);
    truth_ << 2.0, 1.8, 1.5,   0.4, 0.3, 0.2,   0.9, 0.8, 0.9,   -0.3, -0.2, -0.4,  0.15, 0.1, 0.12,
              -0.1, -0.12, -0.05,  0.2, 0.25, 0.18,  0.12, 0.1, 0.08,  -0.15, -0.1, -0.2;
  }
  cv::Mat normals_, mask_, albedo_;
  Eigen::MatrixXd truth_;
};

TEST_F(InverseLighting, RecoversBandTwoCoefficientsWithinTwoPercentAndPicksTheBand) {
  const cv::Mat image = OutputOf<cv::Mat>([&](cv::Mat* out) { return RenderShLighting(normals_, albedo_, truth_, out); });
  const ShLightingSummary fit = FitShLighting(normals_, albedo_, image, mask_);
  ASSERT_TRUE(fit.IsSolutionUsable()) << fit.message;
  EXPECT_EQ(fit.band, 2);
  ASSERT_EQ(fit.coefficients.rows(), 9);
  EXPECT_LT((fit.coefficients - truth_).cwiseAbs().maxCoeff() / truth_.cwiseAbs().maxCoeff(), 0.02);
  for (int i = 0; i < 9; ++i)
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(fit.coefficients(i, c), truth_(i, c), 0.02 * std::abs(truth_(i, c)) + 1e-6);
  EXPECT_LT(fit.relative_rms_residual, 1e-4);
}

TEST_F(InverseLighting, NoisyFrontalLightNeedsOnlyTheLowBands) {
  // Band 1 lighting plus noise: held-out residual and BIC both decline band 2 and 4.
  Eigen::MatrixXd band1 = Eigen::MatrixXd::Zero(4, 1);
  band1 << 2.0, 0.3, 0.8, -0.2;
  cv::Mat image = OutputOf<cv::Mat>([&](cv::Mat* out) { return RenderShLighting(normals_, albedo_, band1, out); });
  cv::Mat noise(image.size(), CV_32F);
  cv::randn(noise, 0.0, 0.01);
  image += noise;
  for (auto selection : {ShFitOptions::Selection::kHeldOut, ShFitOptions::Selection::kBic}) {
    ShFitOptions options;
    options.selection = selection;
    const ShLightingSummary fit = FitShLighting(normals_, albedo_, image, mask_, options);
    ASSERT_TRUE(fit.IsSolutionUsable());
    EXPECT_EQ(fit.band, 1);
    EXPECT_EQ(fit.candidates.size(), 4u);
  }
}

// Normals within 25 deg of the view pin the lighting down there and leave the
// rest of the hemisphere to extrapolation: band 2 then misses the hemisphere's
// irradiance by 4 % RMS (band 4 by 250 %, docs/lighting.md), and the summary
// says so with its predicted uncertainty; the whole sphere's normals do not.
TEST_F(InverseLighting, ANarrowCapOfNormalsSaysTheRestOfTheHemisphereIsExtrapolated) {
  cv::Mat image = OutputOf<cv::Mat>([&](cv::Mat* out) { return RenderShLighting(normals_, albedo_, truth_, out); });
  cv::Mat noise(image.size(), CV_32FC3);
  cv::randn(noise, 0.0, 0.01);
  image += noise;
  const ShLightingSummary whole = FitShLighting(normals_, albedo_, image, mask_);
  ASSERT_TRUE(whole.IsSolutionUsable()) << whole.message;
  EXPECT_LT(whole.hemisphere_relative_sigma, 0.01);
  EXPECT_EQ(whole.message, "band 2 selected");
  cv::Mat cap = mask_.clone();
  for (int r = 0; r < cap.rows; ++r)
    for (int c = 0; c < cap.cols; ++c)
      if (normals_.at<cv::Vec3f>(r, c)[2] < std::cos(25.0 * M_PI / 180.0)) cap.at<std::uint8_t>(r, c) = 0;
  ShFitOptions band2;
  band2.selection = ShFitOptions::Selection::kFixed;
  band2.fixed_band = 2;
  const ShLightingSummary narrow = FitShLighting(normals_, albedo_, image, cap, band2);
  ASSERT_TRUE(narrow.IsSolutionUsable()) << narrow.message;  // right on the normals it saw
  EXPECT_GT(narrow.hemisphere_relative_sigma, 0.05);
  EXPECT_NE(narrow.message.find("the rest of the visible hemisphere is extrapolated"), std::string::npos)
      << narrow.message;
}

TEST_F(InverseLighting, LedWeightsRecoverADomeMixtureAndImageBasedRelightingMatches) {
  const std::vector<Eigen::Vector3d> dome = testing::DomeDirections();
  std::vector<double> intensities(dome.size());
  for (std::size_t k = 0; k < dome.size(); ++k) intensities[k] = 0.9 + 0.01 * static_cast<double>(k % 20);
  std::vector<cv::Mat> frames;
  for (std::size_t k = 0; k < dome.size(); ++k) {
    frames.push_back(
        OutputOf<cv::Mat>([&](cv::Mat* out) { return RenderDirectionalLights(normals_, albedo_, {dome[k]}, {intensities[k]}, out); }));
  }
  Eigen::MatrixXd truth = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(dome.size()), 1);
  truth(3, 0) = 0.7;
  truth(20, 0) = 1.3;
  truth(44, 0) = 0.5;
  const cv::Mat image = OutputOf<cv::Mat>([&](cv::Mat* out) { return RelightFromFrames(frames, truth, out); });
  const LedWeightsSummary fit = FitLedWeights(normals_, albedo_, image, mask_, dome, intensities);
  ASSERT_TRUE(fit.IsSolutionUsable()) << fit.message;
  EXPECT_LT((fit.weights - truth).cwiseAbs().maxCoeff(), 1e-3);
  EXPECT_EQ(fit.active_leds, 3);
  EXPECT_LT(fit.relative_rms_residual, 1e-4);
  // A light the dome cannot make (below the horizon) leaves a residual that is reported.
  const cv::Mat below = OutputOf<cv::Mat>([&](cv::Mat* out) {
    return RenderDirectionalLights(normals_, albedo_, {Eigen::Vector3d(0, -0.9, -0.44).normalized()}, {1.0}, out);
  });
  const LedWeightsSummary poor = FitLedWeights(normals_, albedo_, below, mask_, dome, intensities);
  EXPECT_GT(poor.relative_rms_residual, 0.02);

  // Under 1 % noise the least squares spreads the three LEDs' light over
  // their neighbours; the simplest set the image supports is the mixture.
  cv::Mat noisy = image.clone(), noise(image.size(), CV_32F);
  cv::theRNG().state = 11;
  cv::randn(noise, 0.0, 0.01 * cv::mean(image, mask_)[0]);
  noisy += noise;
  const LedWeightsSummary simplest = FitLedWeights(normals_, albedo_, noisy, mask_, dome, intensities);
  ASSERT_TRUE(simplest.IsSolutionUsable()) << simplest.message;
  EXPECT_EQ(simplest.active_leds, 3);
  EXPECT_GT(simplest.leds_dropped, 0);
  EXPECT_LT((simplest.weights - truth).cwiseAbs().maxCoeff(), 0.005);
  LedWeightsOptions every_led;
  every_led.simplest_led_set = false;
  const LedWeightsSummary all = FitLedWeights(normals_, albedo_, noisy, mask_, dome, intensities, every_led);
  ASSERT_TRUE(all.IsSolutionUsable()) << all.message;
  EXPECT_GT(all.active_leds, 3);
  EXPECT_EQ(all.leds_dropped, 0);
  EXPECT_GT((all.weights - truth).cwiseAbs().maxCoeff(), 2.0 * (simplest.weights - truth).cwiseAbs().maxCoeff());
}

TEST_F(InverseLighting, RejectsMismatchedInputs) {
  const ShLightingSummary fit = FitShLighting(normals_, albedo_, cv::Mat::zeros(10, 10, CV_32F), mask_);
  EXPECT_EQ(fit.termination, solvers::core::Termination::kInvalidInput);
  EXPECT_NE(fit.message.find("image"), std::string::npos);
  ShFitOptions bad;
  bad.pixel_stride = 0;
  EXPECT_EQ(FitShLighting(normals_, albedo_, normals_, mask_, bad).termination, solvers::core::Termination::kInvalidOptions);
  // Relighting with mismatched inputs says what is wrong and leaves the output alone.
  cv::Mat untouched;
  const solvers::core::Summary render = RenderShLighting(normals_, albedo_, Eigen::MatrixXd::Zero(5, 1), &untouched);
  EXPECT_EQ(render.termination, solvers::core::Termination::kInvalidInput);
  EXPECT_NE(render.message.find("5 SH coefficients"), std::string::npos) << render.message;
  EXPECT_EQ(RelightFromFrames({albedo_}, Eigen::MatrixXd::Ones(2, 1), &untouched).termination,
            solvers::core::Termination::kInvalidInput);
  EXPECT_EQ(RenderDirectionalLights(normals_, albedo_, {Eigen::Vector3d::UnitZ()}, {}, &untouched).termination,
            solvers::core::Termination::kInvalidInput);
  EXPECT_TRUE(untouched.empty());
  // NNLS: an iteration limit is a usable, unconverged result; sizes that disagree are invalid input.
  Eigen::VectorXd x;
  EXPECT_EQ(SolveNnls(Eigen::MatrixXd::Identity(3, 3), Eigen::VectorXd::Ones(2), &x).termination,
            solvers::core::Termination::kInvalidInput);
  NnlsOptions one_step;
  one_step.max_iterations = 1;
  const NnlsSummary limited = SolveNnls(Eigen::MatrixXd::Identity(3, 3), Eigen::VectorXd::Ones(3), &x, one_step);
  EXPECT_EQ(limited.termination, solvers::core::Termination::kNoConvergence);
  EXPECT_TRUE(limited.IsSolutionUsable());
}

}  // namespace
}  // namespace photorig::solvers::lighting
