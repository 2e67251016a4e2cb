// The low-frequency reflectance fit (kernels/low_frequency_fit.h) on single
// pixels rendered from its own model, with analytic answers, and where it
// must refuse; then the `low-frequency` method and `auto`'s step 7 on whole
// stacks.
#include "kernels/low_frequency_fit.h"
#include "per_pixel_fits.h"
#include "photorig/solvers/ps/evaluation.h"
#include "photorig/solvers/ps/photometric_stereo.h"
#include "ps_test_scene.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace photorig::solvers::ps {
namespace {

using internal::LowFrequencyFitter;
using internal::LowFrequencyProblem;
using internal::LowFrequencySolution;

// 96 lights on a dome within 60 deg of the view (+z), as a real dome's.
std::vector<Eigen::Vector3d> DomeLights() { return testing::RingLights(96, 30, 88, 5); }

struct Pixel {
  std::vector<double> wx, wy, wz, observed, inverse_sigma;
  LowFrequencyProblem Problem() const {
    return {.lights = static_cast<int>(observed.size()),
            .wx = wx.data(),
            .wy = wy.data(),
            .wz = wz.data(),
            .stride = 1,
            .view = Eigen::Vector3d::UnitZ(),
            .observed = observed.data(),
            .inverse_sigma = inverse_sigma.data()};
  }
};

// The model itself, I = max(0, n.l)(a0 + a1 c + a2 c^2 + a3 d), plus
// `spike` times a Blinn-Phong lobe of exponent 3000 (a highlight the model
// cannot make) and Gaussian noise of sigma `noise`.
Pixel Render(const Eigen::Vector3d& normal, const std::array<double, 4>& a, double spike, double noise,
             unsigned seed = 1) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  Pixel pixel;
  for (const Eigen::Vector3d& l : DomeLights()) {
    const Eigen::Vector3d h = (l + Eigen::Vector3d::UnitZ()).normalized();
    const double nl = std::max(0.0, normal.dot(l)), c = std::max(0.0, normal.dot(h)), d = l.dot(h);
    const double value = nl * (a[0] + a[1] * c + a[2] * c * c + a[3] * d + spike * std::pow(c, 3000.0));
    pixel.wx.push_back(l.x()), pixel.wy.push_back(l.y()), pixel.wz.push_back(l.z());
    pixel.observed.push_back(value + noise * gauss(rng));
    // Unlit samples are unusable, as the solver's shadow threshold makes them.
    pixel.inverse_sigma.push_back(nl > 0.05 ? 1.0 / std::max(noise, 1e-3) : 0.0);
  }
  return pixel;
}

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI;
}

const Eigen::Vector3d kTilted = Eigen::Vector3d(std::sin(0.5), 0.2, std::cos(0.5)).normalized();

TEST(LowFrequencyFit, RecoversItsOwnModelExactlyWithoutNoise) {
  const std::array<double, 4> a = {0.15, 0.05, 0.2, 0.03};
  const Pixel pixel = Render(kTilted, a, 0.0, 0.0);
  LowFrequencyFitter fitter(0.0);
  const LowFrequencySolution fit = fitter.Fit(pixel.Problem());
  ASSERT_TRUE(fit.ok);
  EXPECT_EQ(fit.left_out, 0);
  EXPECT_LT(AngleDeg(fit.normal, kTilted), 1e-3);
  // The four terms are nearly collinear over a dome's half vectors: the
  // curve, not each coefficient, is what the samples fix.
  for (int k = 0; k < pixel.Problem().lights; ++k) {
    if (pixel.inverse_sigma[k] == 0.0) continue;
    const Eigen::Vector3d l(pixel.wx[k], pixel.wy[k], pixel.wz[k]), h = (l + Eigen::Vector3d::UnitZ()).normalized();
    const double c = std::max(0.0, fit.normal.dot(h));
    const double predicted = std::max(0.0, fit.normal.dot(l)) * (fit.a[0] + fit.a[1] * c + fit.a[2] * c * c + fit.a[3] * l.dot(h));
    EXPECT_NEAR(predicted, pixel.observed[k], 1e-6 * (1.0 + pixel.observed[k]));
  }
}

TEST(LowFrequencyFit, ALambertianPixelIsA0Alone) {
  const Pixel pixel = Render(kTilted, {0.3, 0.0, 0.0, 0.0}, 0.0, 0.0);
  LowFrequencyFitter fitter(0.1);
  const LowFrequencySolution fit = fitter.Fit(pixel.Problem());
  ASSERT_TRUE(fit.ok);
  EXPECT_LT(AngleDeg(fit.normal, kTilted), 1e-3);
  EXPECT_NEAR(fit.a[0] + fit.a[3], 0.3, 1e-6);  // cos theta_d is 1 at most: a3 can stand in for a0 only where d = 1
  EXPECT_NEAR(fit.a[1] + fit.a[2], 0.0, 1e-6);
  EXPECT_LT(fit.chi2, 1e-12 * fit.used);
}

// Step 7's measure of how far a Blinn-Phong lobe moves its samples is the
// chi-square the fit's own model gives the lobe alone against samples of 0
// (its normalisation rho_s (e + 2) / (2 pi) included). A sharp lobe with a
// light's half vector at its peak moves that sample far beyond the noise;
// the same lobe peaking between the half vectors moves none.
TEST(LowFrequencyFit, ALobesTermChiSquareIsItsOwnModelsAndVanishesBetweenTheLights) {
  Pixel pixel = Render(kTilted, {0.2, 0.0, 0.0, 0.0}, 0.0, 0.01);
  const int lights = static_cast<int>(pixel.observed.size());
  std::vector<int> all(lights);
  for (int k = 0; k < lights; ++k) all[k] = k;
  std::fill(pixel.observed.begin(), pixel.observed.end(), 0.0);
  std::fill(pixel.inverse_sigma.begin(), pixel.inverse_sigma.end(), 100.0);
  std::vector<Eigen::Vector3d> halves;
  for (int k = 0; k < lights; ++k)
    halves.push_back((Eigen::Vector3d(pixel.wx[k], pixel.wy[k], pixel.wz[k]) + Eigen::Vector3d::UnitZ()).normalized());
  // The normal within 30 deg of the view farthest from every half vector.
  Eigen::Vector3d between = Eigen::Vector3d::UnitZ();
  double gap_deg = 0.0;
  for (double tilt = 0.0; tilt <= 30.0; tilt += 0.5)
    for (double azimuth = 0.0; azimuth < 360.0; azimuth += 2.0) {
      const double t = tilt * M_PI / 180.0, a = azimuth * M_PI / 180.0;
      const Eigen::Vector3d n(std::sin(t) * std::cos(a), std::sin(t) * std::sin(a), std::cos(t));
      double nearest = 180.0;
      for (const Eigen::Vector3d& h : halves) nearest = std::min(nearest, AngleDeg(n, h));
      if (nearest > gap_deg) gap_deg = nearest, between = n;
    }
  ASSERT_GT(gap_deg, 3.0);
  internal::PixelFit lobe{.ok = true, .normal = halves[0], .albedo = 0.0, .specular_albedo = 0.3,
                          .exponent = 2000.0, .parameters = 5, .model = PixelModel::kBlinnPhong};
  for (const Eigen::Vector3d& normal : {halves[0], between}) {
    lobe.normal = normal;
    const internal::PixelFit alone =
        internal::KeptOnLights(lobe, all, pixel.wx.data(), pixel.wy.data(), pixel.wz.data(), 1,
                               Eigen::Vector3d::UnitZ(), pixel.observed.data(), pixel.inverse_sigma.data());
    ASSERT_TRUE(alone.ok);
    EXPECT_NEAR(internal::BlinnPhongTermChi2(lobe, pixel.Problem()), alone.chi2, 1e-9 * alone.chi2);
  }
  // e = 2000 falls to half its peak 1.5 deg from it.
  lobe.normal = halves[0];
  EXPECT_GT(internal::BlinnPhongTermChi2(lobe, pixel.Problem()), 1e4);
  lobe.normal = between;
  EXPECT_LT(internal::BlinnPhongTermChi2(lobe, pixel.Problem()), 1.0) << gap_deg << " deg from every half vector";
}

// A spike the model cannot make, on the samples nearest the mirror
// direction: left out with the brightest 10 %, it does not tilt the normal,
// where the fit of every sample is tilted by degrees.
TEST(LowFrequencyFit, TheBrightestSamplesLeftOutTakeASpikeWithThem) {
  const Eigen::Vector3d normal = Eigen::Vector3d(0.15, -0.1, 1.0).normalized();
  const Pixel pixel = Render(normal, {0.2, 0.0, 0.1, 0.0}, 20.0, 0.0);
  LowFrequencyFitter with_spike(0.0), without(0.1);
  const LowFrequencySolution all = with_spike.Fit(pixel.Problem()), kept = without.Fit(pixel.Problem());
  ASSERT_TRUE(all.ok);
  ASSERT_TRUE(kept.ok);
  EXPECT_EQ(kept.left_out, static_cast<int>(0.1 * (kept.used + kept.left_out)));
  EXPECT_GT(AngleDeg(all.normal, normal), 0.5);
  EXPECT_LT(AngleDeg(kept.normal, normal), 0.05);
}

// With noise the normal's error follows the noise: statistically, over 200
// draws, its mean is within the spread the noise allows (sigma 0.002 on
// samples of 0.1-0.3 gives tenths of a degree, far below a degree).
TEST(LowFrequencyFit, NoiseMovesTheNormalByItsOwnMeasure) {
  LowFrequencyFitter fitter(0.1);
  double sum_deg = 0.0;
  int ok = 0;
  for (unsigned seed = 1; seed <= 200; ++seed) {
    const Pixel pixel = Render(kTilted, {0.25, 0.02, 0.1, 0.0}, 0.0, 0.002, seed);
    const LowFrequencySolution fit = fitter.Fit(pixel.Problem());
    if (!fit.ok) continue;
    ++ok;
    sum_deg += AngleDeg(fit.normal, kTilted);
    // chi-square over its degrees of freedom near 1 for a fit at the noise.
    EXPECT_LT(fit.chi2 / (fit.used - internal::kLowFrequencyParameters), 2.0);
  }
  EXPECT_EQ(ok, 200);
  EXPECT_GT(sum_deg / ok, 0.01);
  EXPECT_LT(sum_deg / ok, 1.0);
}

// The normal's information (inverse covariance along its two tangents)
// measures its noise: over 400 draws the deviation from the truth in it is
// chi-square with two degrees of freedom, mean 2, above the 0.999
// quantile (13.8) about once in a thousand.
TEST(LowFrequencyFit, TheNormalsInformationMeasuresItsNoise) {
  LowFrequencyFitter fitter(0.1);
  double sum = 0.0;
  int beyond = 0, ok = 0;
  for (unsigned seed = 1; seed <= 400; ++seed) {
    const Pixel pixel = Render(kTilted, {0.25, 0.02, 0.1, 0.03}, 0.0, 0.002, seed);
    const LowFrequencySolution fit = fitter.Fit(pixel.Problem());
    if (!fit.ok) continue;
    ++ok;
    const Eigen::Vector2d off = fit.tangents.transpose() * (kTilted - fit.normal);
    const double chi2 = off.dot(fit.normal_information * off);
    sum += chi2;
    beyond += chi2 > 13.8;
  }
  ASSERT_EQ(ok, 400);
  EXPECT_GT(sum / ok, 1.5);
  EXPECT_LT(sum / ok, 2.6);
  EXPECT_LE(beyond, 4);
}

// The misfit of the model at `normal` over the pixel's usable samples, its
// non-negative a found by trying every support (independent of the
// fitter's active-set order).
double MisfitAt(const Pixel& pixel, const Eigen::Vector3d& normal) {
  std::vector<std::array<double, 4>> columns;
  std::vector<double> values;
  for (std::size_t k = 0; k < pixel.observed.size(); ++k) {
    if (pixel.inverse_sigma[k] == 0.0) continue;
    const Eigen::Vector3d l(pixel.wx[k], pixel.wy[k], pixel.wz[k]), h = (l + Eigen::Vector3d::UnitZ()).normalized();
    const double nl = std::max(0.0, normal.dot(l)), c = std::max(0.0, normal.dot(h));
    columns.push_back({nl, nl * c, nl * c * c, nl * l.dot(h)});
    values.push_back(pixel.observed[k]);
  }
  const int n = static_cast<int>(values.size());
  const Eigen::Map<const Eigen::VectorXd> b(values.data(), n);
  double best = b.squaredNorm();
  for (int support = 1; support < 16; ++support) {
    std::vector<int> index;
    for (int j = 0; j < 4; ++j)
      if (support >> j & 1) index.push_back(j);
    Eigen::MatrixXd A(n, index.size());
    for (int i = 0; i < n; ++i)
      for (std::size_t j = 0; j < index.size(); ++j) A(i, j) = columns[i][index[j]];
    const Eigen::VectorXd a = A.colPivHouseholderQr().solve(b);
    if ((a.array() < 0.0).any()) continue;
    best = std::min(best, (A * a - b).squaredNorm());
  }
  return best;
}

// The search stops once a step would move the normal by less than a
// hundredth of its own standard error: on pixels the model cannot fit
// exactly (a narrow highlight kept in the fit, noise), no normal within a
// tenth of a standard error of the answer, on a grid of a hundredth, has a
// misfit lower by more than a step of that size could gain.
TEST(LowFrequencyFit, StopsWithinAHundredthOfItsStandardErrorOfTheMinimum) {
  LowFrequencyFitter fitter(0.0);
  for (unsigned seed = 1; seed <= 20; ++seed) {
    const Pixel pixel = Render(kTilted, {0.2, 0.03, 0.1, 0.02}, 0.3, 0.003, seed);
    const LowFrequencySolution fit = fitter.Fit(pixel.Problem());
    ASSERT_TRUE(fit.ok) << seed;
    // Unit steps along the tangents in standard errors: the information's
    // eigenvectors scaled by 1 / sqrt(eigenvalue).
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(fit.normal_information);
    ASSERT_GT(eigen.eigenvalues().minCoeff(), 0.0);
    const double at_fit = MisfitAt(pixel, fit.normal);
    // The misfit grows as `variance` times the squared distance in standard
    // errors (the information is J^T J over the variance the fit takes, its
    // residual's or at least the noise's): a tenth of a standard error off
    // costs 1e-2 of it, a thirtieth about 1e-3.
    const double variance = std::max(at_fit / (fit.used - internal::kLowFrequencyParameters), 0.003 * 0.003);
    double lowest = at_fit;
    for (int i = -10; i <= 10; ++i) {
      for (int j = -10; j <= 10; ++j) {
        Eigen::Vector2d angles = Eigen::Vector2d::Zero();
        for (int e = 0; e < 2; ++e)
          angles += (e == 0 ? i : j) * 0.01 * eigen.eigenvectors().col(e) / std::sqrt(eigen.eigenvalues()[e]);
        const Eigen::Vector3d normal = (fit.normal + fit.tangents * angles).normalized();
        lowest = std::min(lowest, MisfitAt(pixel, normal));
      }
    }
    EXPECT_GT(lowest, at_fit - 1e-3 * variance) << seed;
  }
}

// FitSameSamples fits the last Fit's samples (its spike left out by the
// first values' brightness) with other values: the fit of another pixel
// seen under the same lights, exactly where no sample is left out.
TEST(LowFrequencyFit, FitSameSamplesIsTheFitOfTheOtherValues) {
  const Pixel first = Render(kTilted, {0.3, 0.0, 0.1, 0.0}, 0.0, 0.0);
  const Pixel second = Render(kTilted, {0.1, 0.05, 0.3, 0.02}, 0.0, 0.001, 5);
  LowFrequencyFitter fitter(0.0), reference(0.0);
  ASSERT_TRUE(fitter.Fit(first.Problem()).ok);
  std::vector<double> values;
  for (int k : fitter.used_lights()) values.push_back(second.observed[k]);
  const LowFrequencySolution same = fitter.FitSameSamples(values);
  const LowFrequencySolution direct = reference.Fit(second.Problem());
  ASSERT_TRUE(same.ok);
  ASSERT_TRUE(direct.ok);
  EXPECT_LT(AngleDeg(same.normal, direct.normal), 1e-9);
  for (int j = 0; j < 4; ++j) EXPECT_NEAR(same.a[j], direct.a[j], 1e-9);
  EXPECT_EQ(same.used, direct.used);
}

// Where it breaks: with no more usable samples than parameters nothing
// tests the fit, and it says so rather than pass a curve through them.
TEST(LowFrequencyFit, RefusesWhatItsSamplesCannotDetermine) {
  const Pixel pixel = Render(kTilted, {0.3, 0.0, 0.1, 0.0}, 0.0, 0.0);
  auto keep_usable = [&](int count) {
    Pixel fewer = pixel;
    int seen = 0;
    for (double& w : fewer.inverse_sigma)
      if (w > 0.0 && ++seen > count) w = 0.0;
    return fewer;
  };
  LowFrequencyFitter fitter(0.1);
  const Pixel seven = keep_usable(7), six = keep_usable(6), none = keep_usable(0);
  const LowFrequencySolution enough = fitter.Fit(seven.Problem());  // 10 % of 7 rounds to none left out
  EXPECT_TRUE(enough.ok);
  EXPECT_EQ(enough.used, 7);
  const LowFrequencySolution too_few = fitter.Fit(six.Problem());
  EXPECT_FALSE(too_few.ok);
  EXPECT_EQ(too_few.used, 6);
  const LowFrequencySolution empty = fitter.Fit(none.Problem());
  EXPECT_FALSE(empty.ok);
  EXPECT_EQ(empty.used, 0);
}

}  // namespace
}  // namespace photorig::solvers::ps
