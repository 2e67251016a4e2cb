// The lane kernels: their math against libm, the Blinn-Phong fitter's
// derivatives against forward-mode automatic differentiation, the trimming
// against known outliers, IRLS against a plain implementation of the same
// iteration, and `auto` in lanes against the per-pixel reference.
#include "kernels/held_lobe_fit.h"
#include "kernels/lobe_lane_fit.h"
#include "kernels/irls_lambertian_fit.h"
#include "kernels/lambertian_recheck.h"
#include "kernels/lane_math.h"
#include "kernels/trimmed_lambertian_fit.h"
#include "lambertian_tiles.h"
#include "per_pixel_fits.h"
#include "sample_reader.h"

#include "photorig/solvers/autodiff/blinn_phong_jacobian.h"
#include "photorig/solvers/autodiff/ggx.h"
#include "ps_test_scene.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

namespace photorig::solvers::ps {
namespace {

using internal::LaneLobe;
using internal::LobeLaneFitter;
using internal::LobeProblem;
using internal::LobeSolution;

// Options for the test stacks, which carry their complete noise model.
PhotometricStereoOptions LaneOptions(Method method) {
  PhotometricStereoOptions options;
  options.method = method;
  options.lambertian.shadow_threshold = 6.0;
  options.estimate_noise = false;
  return options;
}

PhotometricStereoOptions PerPixel(PhotometricStereoOptions options) {
  options.blinn_phong.fitter = BlinnPhongOptions::Fitter::kPerPixel;
  return options;
}

TEST(LaneMath, LogInverseAndExpAgreeWithLibmToAFewUlp) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> mantissa(1.0, 2.0);
  double worst_log = 0.0, worst_inverse = 0.0, worst_exp = 0.0;
  for (int i = 0; i < 200000; ++i) {
    // Over the range the lobe uses, [1e-300, 1], and beyond it up to 2^300.
    const double x = mantissa(rng) * std::pow(2.0, std::floor(-1000.0 + 1300.0 * (mantissa(rng) - 1.0)));
    double inverse = 0.0;
    const double log_x = internal::LaneLogAndInverse(x, &inverse);
    worst_log = std::max(worst_log, std::abs(log_x - std::log(x)) / std::max(std::abs(std::log(x)), 1e-3));
    worst_inverse = std::max(worst_inverse, std::abs(inverse * x - 1.0));
    const double y = -708.0 + 1417.0 * (mantissa(rng) - 1.0);
    worst_exp = std::max(worst_exp, std::abs(internal::LaneExp(y) / std::exp(y) - 1.0));
  }
  EXPECT_LT(worst_log, 1e-15);
  EXPECT_LT(worst_inverse, 1e-15);
  EXPECT_LT(worst_exp, 1e-15);
  // Near 1 the logarithm is small: its absolute error is what matters.
  double inverse = 0.0;
  EXPECT_EQ(internal::LaneLogAndInverse(1.0, &inverse), 0.0);
  EXPECT_EQ(inverse, 1.0);
  EXPECT_NEAR(internal::LaneLogAndInverse(1.0 + 1e-12, &inverse), std::log(1.0 + 1e-12), 1e-27);
  EXPECT_EQ(internal::LaneExp(0.0), 1.0);
  // Far below the range the result is clamped, not garbage.
  EXPECT_GT(internal::LaneExp(-1e6), 0.0);
  EXPECT_LT(internal::LaneExp(-1e6), 1e-300);
}

TEST(LaneMath, FloatLogInverseAndExpAgreeWithLibmToAFewUlp) {
  std::mt19937 rng(6);
  std::uniform_real_distribution<double> mantissa(1.0, 2.0);
  double worst_log = 0.0, worst_inverse = 0.0, worst_exp = 0.0;
  for (int i = 0; i < 200000; ++i) {
    // Over the range the lobe uses, [1e-30, 1], and beyond it up to 2^100.
    const float x = static_cast<float>(mantissa(rng) * std::pow(2.0, std::floor(-100.0 + 200.0 * (mantissa(rng) - 1.0))));
    float inverse = 0.0f;
    const double log_x = internal::LaneLogAndInverse(x, &inverse);
    const double exact_log = std::log(static_cast<double>(x));
    worst_log = std::max(worst_log, std::abs(log_x - exact_log) / std::max(std::abs(exact_log), 1e-3));
    worst_inverse = std::max(worst_inverse, std::abs(double(inverse) * x - 1.0));
    const float y = static_cast<float>(-80.0 + 168.0 * (mantissa(rng) - 1.0));
    worst_exp = std::max(worst_exp, std::abs(internal::LaneExp(y) / std::exp(double(y)) - 1.0));
  }
  EXPECT_LT(worst_log, 5e-7);
  EXPECT_LT(worst_inverse, 5e-7);
  EXPECT_LT(worst_exp, 5e-7);
  float inverse = 0.0f;
  EXPECT_EQ(internal::LaneLogAndInverse(1.0f, &inverse), 0.0f);
  EXPECT_EQ(inverse, 1.0f);
  EXPECT_EQ(internal::LaneExp(0.0f), 1.0f);
  // Clamped, not subnormal, far below the range.
  EXPECT_GE(internal::LaneExp(-1e6f), std::numeric_limits<float>::min());
  EXPECT_LT(internal::LaneExp(-1e6f), 1e-34f);
}

// A pixel seen by lights all around, some behind its horizon and some whose
// half vector is past 90 degrees, so every clamp of the model is exercised.
struct Pixel {
  std::vector<Eigen::Vector3d> lights;
  std::vector<double> observed, inverse_sigma;
  Eigen::Vector3d normal;
  Eigen::Vector3d view = Eigen::Vector3d::UnitZ();
};

Pixel RandomPixel(std::mt19937& rng, int light_count) {
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Pixel pixel;
  for (int k = 0; k < light_count; ++k) {
    Eigen::Vector3d w(gauss(rng), gauss(rng), gauss(rng) + 0.8);
    pixel.lights.push_back(w.normalized());
  }
  pixel.normal = Eigen::Vector3d(gauss(rng), gauss(rng), 0.3).normalized();
  for (int k = 0; k < light_count; ++k) {
    pixel.observed.push_back(0.5 * unit(rng));
    pixel.inverse_sigma.push_back(k % 7 == 3 ? 0.0 : 0.5 + unit(rng));  // some samples unusable
  }
  return pixel;
}

// The pixel as a point up to 10 mm from the dome's centre, its lights LEDs
// 80 mm out along its directions, its view tilted by up to 15 deg as through
// a pinhole: geometry of its own, as under a near dome.
void MoveUnderNearLights(std::mt19937& rng, Pixel* pixel) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Eigen::Vector3d point(20.0 * unit(rng) - 10.0, 20.0 * unit(rng) - 10.0, 0.0);
  for (Eigen::Vector3d& w : pixel->lights) w = (80.0 * w - point).normalized();
  const Eigen::Vector3d axis = Eigen::Vector3d(unit(rng) - 0.5, unit(rng) - 0.5, 0.0).normalized();
  pixel->view = Eigen::AngleAxisd(unit(rng) * 15.0 * M_PI / 180, axis) * Eigen::Vector3d::UnitZ();
}

// The lanes' normal equations at random points against those built from the
// forward-mode Jacobian of `Model` (autodiff::BlinnPhongPixel or GgxPixel)
// over (m, rho_d, rho_s, shape) at |m| = 1; a tangent step t moves m by t, so
// its column is J_m t. shape_of draws e or a from a uniform number. With
// own_geometry, each pixel brings its own (MoveUnderNearLights) to one fitter
// made without shared lights.
template <typename Model, typename Jacobian, typename Shape>
void ExpectNormalEquationsMatchForwardMode(LaneLobe lobe, Jacobian residuals_and_jacobian, Shape shape_of,
                                          double tolerance, bool own_geometry = false) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int lights_past_horizon = 0;
  constexpr int kLights = 24;
  LobeLaneFitter own_geometry_fitter(kLights, BlinnPhongOptions{}, lobe);
  std::mt19937 geometry_rng(13);  // the pixels and points the same as with shared lights
  for (int trial = 0; trial < 40; ++trial) {
    Pixel pixel = RandomPixel(rng, kLights);
    if (own_geometry) MoveUnderNearLights(geometry_rng, &pixel);
    const int n = static_cast<int>(pixel.lights.size());
    const double rho_d = 0.2 + unit(rng), rho_s = unit(rng), shape = shape_of(unit(rng), unit(rng));
    std::vector<double> towards_light, geometry(6 * n);
    for (const Eigen::Vector3d& w : pixel.lights) towards_light.insert(towards_light.end(), w.data(), w.data() + 3);
    internal::BlinnPhongGeometry(n, towards_light.data(), pixel.view, geometry.data());
    LobeLaneFitter shared_fitter(pixel.lights, pixel.view, BlinnPhongOptions{}, lobe);
    LobeLaneFitter& fitter = own_geometry ? own_geometry_fitter : shared_fitter;
    LobeProblem problem{pixel.observed.data(), pixel.inverse_sigma.data(), pixel.normal, rho_d};
    problem.geometry = geometry.data();
    problem.view = pixel.view;
    const auto lanes = fitter.Linearize(problem, pixel.normal, rho_d, rho_s, shape);

    Eigen::Matrix<double, Eigen::Dynamic, 3> directions(n, 3);
    for (int k = 0; k < n; ++k) directions.row(k) = pixel.lights[k].transpose();
    const Model model(directions, Eigen::VectorXd::Ones(n), pixel.view,
                      Eigen::Map<const Eigen::VectorXd>(pixel.observed.data(), n));
    const double parameters[6] = {pixel.normal.x(), pixel.normal.y(), pixel.normal.z(), rho_d, rho_s, shape};
    Eigen::VectorXd residuals;
    Eigen::MatrixXd jacobian;
    ASSERT_TRUE(residuals_and_jacobian(model, parameters, solvers::autodiff::DerivativeMethod::kForward, &residuals,
                                       &jacobian, nullptr));
    Eigen::MatrixXd j(n, 5);
    j.col(0) = jacobian.leftCols<3>() * lanes.tangent[0];
    j.col(1) = jacobian.leftCols<3>() * lanes.tangent[1];
    j.rightCols<3>() = jacobian.rightCols<3>();
    const Eigen::VectorXd weights = Eigen::Map<const Eigen::VectorXd>(pixel.inverse_sigma.data(), n);
    const Eigen::MatrixXd jw = weights.asDiagonal() * j;
    const Eigen::VectorXd rw = residuals.cwiseProduct(weights);
    const Eigen::MatrixXd hessian = jw.transpose() * jw;
    const Eigen::VectorXd gradient = jw.transpose() * rw;

    // A wrong term of a derivative is off by its whole size; float rounding
    // by `tolerance`. The gradient J^T r sums terms of both signs: its
    // rounding scales with |J| |r|.
    EXPECT_NEAR(lanes.cost, rw.squaredNorm(), tolerance * rw.squaredNorm());
    EXPECT_LT((lanes.hessian - hessian).norm(), tolerance * hessian.norm()) << "trial " << trial;
    EXPECT_LT((lanes.gradient - gradient).norm(), tolerance * (gradient.norm() + jw.norm() * rw.norm()))
        << "trial " << trial;
    EXPECT_NEAR(lanes.tangent[0].dot(pixel.normal), 0.0, 1e-12);
    EXPECT_NEAR(lanes.tangent[1].dot(pixel.normal), 0.0, 1e-12);
    EXPECT_NEAR(lanes.tangent[0].dot(lanes.tangent[1]), 0.0, 1e-12);
    for (int k = 0; k < n; ++k) lights_past_horizon += pixel.lights[k].dot(pixel.normal) <= 0.0;
  }
  // The horizon clamp was exercised, not just the smooth interior. (The lobe
  // clamp h <= 0 with c > 0 needs a normal facing away from the camera.)
  EXPECT_GT(lights_past_horizon, 20);
}

TEST(BlinnPhongLanes, NormalEquationsMatchForwardModeAutodiff) {
  // Float: h^e moves by e times the rounding of h (e <= 201 here, float
  // epsilon 6e-8), so they agree to about 1e-5.
  ExpectNormalEquationsMatchForwardMode<solvers::autodiff::BlinnPhongPixel>(
      LaneLobe::kBlinnPhong, &solvers::autodiff::BlinnPhongResidualsAndJacobian,
      [](double u, double v) { return 1.0 + 200.0 * u * v; }, 2e-5);
}

TEST(GgxLanes, NormalEquationsMatchForwardModeAutodiff) {
  // Roughness 0.03-0.7, the range step 6 starts from. Float: 1 / t^2 with
  // t = 1 - h^2 (1 - a^2) loses h's rounding over a^2 near the peak.
  ExpectNormalEquationsMatchForwardMode<solvers::autodiff::GgxPixel>(
      LaneLobe::kGgx, &solvers::autodiff::GgxResidualsAndJacobian,
      [](double u, double) { return 0.03 + 0.67 * u; }, 2e-5);
}

// The same with each pixel's own lights and view, as under a near dome: the
// lanes read the pixel's half vectors and its v . n.
TEST(GgxLanes, PerLaneNormalEquationsMatchForwardModeAutodiff) {
  ExpectNormalEquationsMatchForwardMode<solvers::autodiff::GgxPixel>(
      LaneLobe::kGgx, &solvers::autodiff::GgxResidualsAndJacobian,
      [](double u, double) { return 0.03 + 0.67 * u; }, 2e-5, true);
}

// Fits noise-free problems and expects every pixel's true normal (within
// 1e-4 deg) and exponent or roughness (0.1 %), each within the iteration
// limit; returns the solutions.
std::vector<LobeSolution> ExpectTrueParameters(LobeLaneFitter* fitter, const std::vector<LobeProblem>& problems,
                                               const std::vector<Eigen::Vector3d>& normals,
                                               const std::vector<double>& exponents) {
  std::vector<LobeSolution> solutions(problems.size());
  fitter->Fit(problems, solutions);
  double worst_deg = 0.0, worst_exponent = 0.0;
  for (std::size_t p = 0; p < problems.size(); ++p) {
    EXPECT_TRUE(solutions[p].ok) << p;
    worst_deg = std::max(worst_deg, std::acos(std::min(1.0, solutions[p].normal.dot(normals[p]))) * 180 / M_PI);
    worst_exponent = std::max(worst_exponent, std::abs(solutions[p].exponent / exponents[p] - 1.0));
    EXPECT_LT(solutions[p].iterations, BlinnPhongOptions{}.max_iterations);
  }
  EXPECT_LT(worst_deg, 1e-4);
  EXPECT_LT(worst_exponent, 1e-3);
  return solutions;
}

// Noise-free shiny pixels: the lane fit must land where the per-pixel
// reference fit (forward-mode autodiff) lands, at the true parameters.
TEST(BlinnPhongLanes, FitsAgreeWithThePerPixelReference) {
  const auto lights = testing::RingLights(40, 25, 80);
  const auto truth = testing::RandomSurface(10, 7, 40.0, 13);  // 70 pixels: not a multiple of the lane count
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const int pixels = truth.normals.rows * truth.normals.cols, n = static_cast<int>(lights.size());
  std::vector<double> observed(pixels * n), inverse_sigma(pixels * n, 100.0);
  std::vector<LobeProblem> problems;
  std::vector<Eigen::Vector3d> normals;
  std::vector<double> exponents;
  for (int p = 0; p < pixels; ++p) {
    const cv::Vec3f t = truth.normals.ptr<cv::Vec3f>()[p];
    const Eigen::Vector3d normal = Eigen::Vector3d(t[0], t[1], t[2]).normalized();  // unit in double
    const double rho_d = truth.albedo.ptr<float>()[p], rho_s = 0.2 + 0.5 * unit(rng), e = 10.0 + 40.0 * unit(rng);
    for (int k = 0; k < n; ++k) {
      const Eigen::Vector3d half = (lights[k] + Eigen::Vector3d::UnitZ()).normalized();
      const double c = std::max(0.0, lights[k].dot(normal)), h = std::max(0.0, half.dot(normal));
      observed[p * n + k] = (rho_d / M_PI + rho_s * (e + 2) / (2 * M_PI) * std::pow(h, e)) * c;
    }
    // Start 3 degrees off, as a trimmed Lambertian estimate would be. (From
    // much further, a lobe narrower than the light spacing can settle between
    // the lights with a huge rho_s: the model, not the fitter, is ambiguous there.)
    const Eigen::Vector3d start = (normal + 0.05 * normal.unitOrthogonal()).normalized();
    problems.push_back({&observed[p * n], &inverse_sigma[p * n], start, rho_d});
    normals.push_back(normal);
    exponents.push_back(e);
  }
  LobeLaneFitter fitter(lights, Eigen::Vector3d::UnitZ(), BlinnPhongOptions{});
  ExpectTrueParameters(&fitter, problems, normals, exponents);

  // The whole solver with either fitter on a noisy stack: the same answer to
  // within a small fraction of the error either makes.
  const auto stack = testing::RenderShinyStack(truth, lights, 2000.0, testing::Specular{0.4, 40.0}, 20.0f, 2.0);
  const PhotometricStereoOptions lanes_options = LaneOptions(Method::kBlinnPhong);
  const PhotometricStereoOptions reference_options = PerPixel(lanes_options);
  NormalMap lanes_map, reference_map;
  ASSERT_TRUE(SolvePhotometricStereo(lanes_options, stack, &lanes_map).IsSolutionUsable());
  ASSERT_TRUE(SolvePhotometricStereo(reference_options, stack, &reference_map).IsSolutionUsable());
  int compared = 0;
  for (int p = 0; p < pixels; ++p) {
    const cv::Vec3f a = lanes_map.normals.ptr<cv::Vec3f>()[p], b = reference_map.normals.ptr<cv::Vec3f>()[p];
    if (!(std::isfinite(a[0]) && std::isfinite(b[0]))) continue;
    // Where the model cannot explain a pixel (its confidence is tiny) each
    // fitter stops in some poor local minimum; those need not agree.
    if (reference_map.confidence.ptr<float>()[p] < 0.1f) continue;
    EXPECT_GT(a.dot(b), std::cos(0.05 * M_PI / 180)) << "pixel " << p;
    EXPECT_NEAR(lanes_map.albedo.ptr<float>()[p], reference_map.albedo.ptr<float>()[p], 1e-3) << "pixel " << p;
    ++compared;
  }
  EXPECT_GE(compared, pixels * 8 / 10);
}

// Step 5's held lobe in lanes straight from the planes: on noise-free pixels
// it lands on the true normal and rho_d from 3 deg off; on noisy ones it
// lands where the general lane fitter lands with the same lobe held (from
// rows read as step 5 reads them), and its Lambertian fit on the usable
// samples is LambertianOnRow's.
TEST(HeldLobeLanes, LandsWhereTheLaneFitterLandsWithTheLobeHeld) {
  const auto lights = testing::RingLights(40, 25, 80);
  const auto truth = testing::RandomSurface(9, 5, 40.0, 21);  // 45 pixels: not a multiple of the lane count
  const testing::Specular lobe{0.4, 40.0};
  const int pixels = truth.normals.rows * truth.normals.cols, n = static_cast<int>(lights.size());
  LambertianOptions thresholds;
  thresholds.shadow_threshold = 6.0;
  for (const double noise : {0.0, 2.0}) {
    SCOPED_TRACE(noise);
    PhotometricStack stack = testing::RenderShinyStack(truth, lights, 2000.0, lobe, 20.0f, noise);
    stack.noise.read_sigma = std::max(noise, 0.5);  // a finite weight for the noise-free stack
    std::vector<internal::HeldLobeProblem> problems;
    std::vector<Eigen::Vector3d> normals;
    for (int p = 0; p < pixels; ++p) {
      const cv::Vec3f t = truth.normals.ptr<cv::Vec3f>()[p];
      const Eigen::Vector3d normal = Eigen::Vector3d(t[0], t[1], t[2]).normalized();
      const Eigen::Vector3d start = (normal + 0.05 * normal.unitOrthogonal()).normalized();
      const double albedo = truth.albedo.ptr<float>()[p];
      problems.push_back({.pixel = p,
                          .start_normal = start,
                          .start_albedo = albedo,
                          .specular_albedo = lobe.albedo,
                          .exponent = lobe.exponent,
                          .kept_x = start * albedo / M_PI});
      normals.push_back(normal);
    }
    std::vector<internal::HeldLobeSolution> held(pixels);
    internal::HeldLobeLanes(stack, thresholds, BlinnPhongOptions{}).Fit(problems, held);

    const internal::SampleReader reader(stack, thresholds);
    std::vector<double> observed(pixels * n), inverse_sigma(pixels * n);
    std::vector<LobeProblem> rows;
    for (int p = 0; p < pixels; ++p) {
      int usable = 0;
      reader.Row(p, problems[p].kept_x, &observed[p * n], &inverse_sigma[p * n], &usable);
      LobeProblem row{&observed[p * n], &inverse_sigma[p * n], problems[p].start_normal, problems[p].start_albedo};
      row.shared_specular_albedo = lobe.albedo, row.shared_exponent = lobe.exponent;
      rows.push_back(row);
      EXPECT_EQ(held[p].used, usable) << p;
      const internal::PixelFit on_row =
          internal::LambertianOnRow(reader, &observed[p * n], &inverse_sigma[p * n], problems[p].kept_x);
      EXPECT_EQ(held[p].lambertian_ok, on_row.ok) << p;
      EXPECT_NEAR(held[p].lambertian_chi2, on_row.chi2, 1e-4 * on_row.chi2 + 1e-3) << p;
      EXPECT_LT((held[p].lambertian_x - on_row.normal * on_row.albedo / M_PI).norm(), 1e-5 * on_row.albedo) << p;
    }
    std::vector<LobeSolution> reference(pixels);
    LobeLaneFitter(lights, Eigen::Vector3d::UnitZ(), BlinnPhongOptions{}).Fit(rows, reference);
    for (int p = 0; p < pixels; ++p) {
      ASSERT_TRUE(held[p].ok) << p;
      ASSERT_TRUE(reference[p].ok) << p;
      const double from_truth = std::atan2(held[p].normal.cross(normals[p]).norm(), held[p].normal.dot(normals[p]));
      const double apart = std::atan2(held[p].normal.cross(reference[p].normal).norm(),
                                      held[p].normal.dot(reference[p].normal));
      if (noise == 0.0) {
        EXPECT_LT(from_truth * 180 / M_PI, 1e-3) << p;
        EXPECT_NEAR(held[p].diffuse_albedo, truth.albedo.ptr<float>()[p], 1e-4) << p;
      }
      // The reference stops where a step changes chi-square by under 1e-5 of
      // it, the held fit where it changes by under 0.003 (its normal within
      // 0.055 sigma of the minimum's): both far within the noise's scatter of
      // the normal (about 0.1 deg here).
      EXPECT_LT(apart * 180 / M_PI, 0.01) << p;
      EXPECT_NEAR(held[p].diffuse_albedo, reference[p].diffuse_albedo, 1e-3 * reference[p].diffuse_albedo) << p;
      // Noise-free, both stop at float's floor: chi-square a few thousandths.
      EXPECT_NEAR(held[p].chi2, reference[p].chi2, 1e-3 * reference[p].chi2 + 0.01) << p;
      EXPECT_LT(held[p].iterations, BlinnPhongOptions{}.max_iterations) << p;
    }
  }
  // A pixel in cast shadow under every light has nothing to fit: no usable
  // sample and no Lambertian fit, which step 5 reads as "keep what it has".
  PhotometricStack dark = testing::RenderShinyStack(truth, lights, 2000.0, lobe, 20.0f, 2.0);
  for (cv::Mat& image : dark.images) image.ptr<float>()[0] = 20.0f;
  const internal::HeldLobeProblem shadowed{.pixel = 0, .start_normal = Eigen::Vector3d::UnitZ(), .start_albedo = 0.5,
                                           .specular_albedo = lobe.albedo, .exponent = lobe.exponent};
  std::vector<internal::HeldLobeSolution> none(1);
  internal::HeldLobeLanes(dark, thresholds, BlinnPhongOptions{}).Fit({&shadowed, 1}, none);
  EXPECT_EQ(none[0].used, 0);
  EXPECT_FALSE(none[0].lambertian_ok);
  EXPECT_EQ(none[0].chi2, 0.0);
}

// Step 6 judges the fit a pixel kept in lanes (HeldLobeLanes::Judge): the
// same chi-square as the per-pixel judgement through the autodiff model
// (PerPixelFits::KeptOnUsable), for a kept lobe and for a kept Lambertian fit.
TEST(HeldLobeLanes, JudgesAKeptFitAsThePerPixelJudgement) {
  const auto lights = testing::RingLights(40, 25, 80);
  const auto truth = testing::RandomSurface(7, 5, 40.0, 23);  // 35 pixels
  const testing::Specular lobe{0.4, 40.0};
  const int pixels = truth.normals.rows * truth.normals.cols;
  const PhotometricStack stack = testing::RenderShinyStack(truth, lights, 2000.0, lobe, 20.0f, 2.0, 9);
  LambertianOptions thresholds;
  thresholds.shadow_threshold = 6.0;
  const internal::ModelLadder ladder(Method::kAuto, ModelSelectionOptions{}, static_cast<int>(lights.size()));
  const internal::SampleReader reader(stack, thresholds);
  const internal::PerPixelFits per_pixel(ladder, reader, stack.view_direction, BlinnPhongOptions{});
  const internal::HeldLobeLanes lanes(stack, thresholds, BlinnPhongOptions{});
  internal::PixelScratch scratch;
  for (const bool kept_lobe : {true, false}) {
    SCOPED_TRACE(kept_lobe);
    std::vector<internal::PixelFit> kept(pixels);
    std::vector<internal::HeldLobeProblem> problems;
    for (int p = 0; p < pixels; ++p) {
      const cv::Vec3f t = truth.normals.ptr<cv::Vec3f>()[p];
      // A fit 2 deg off the truth, so that the chi-squares are well above the noise.
      const Eigen::Vector3d n = Eigen::Vector3d(t[0], t[1], t[2]).normalized();
      kept[p].ok = true;
      kept[p].normal = (n + 0.035 * n.unitOrthogonal()).normalized();
      kept[p].albedo = truth.albedo.ptr<float>()[p];
      kept[p].model = kept_lobe ? PixelModel::kBlinnPhong : PixelModel::kLambertian;
      kept[p].specular_albedo = kept_lobe ? lobe.albedo : 0.0;
      kept[p].exponent = kept_lobe ? lobe.exponent : 1.0;
      problems.push_back({.pixel = p,
                          .start_normal = kept[p].normal,
                          .start_albedo = kept[p].albedo,
                          .specular_albedo = kept[p].specular_albedo,
                          .exponent = kept[p].exponent,
                          .kept_x = kept[p].normal * kept[p].albedo / M_PI});
    }
    std::vector<internal::HeldLobeSolution> judged(pixels);
    lanes.Judge(problems, judged);
    for (int p = 0; p < pixels; ++p) {
      const internal::PixelFit reference = per_pixel.KeptOnUsable(p, kept[p], false, &scratch);
      EXPECT_EQ(judged[p].used, reference.used) << p;
      EXPECT_EQ(judged[p].iterations, 0) << p;
      EXPECT_GT(judged[p].normal.dot(kept[p].normal), 1.0 - 1e-6) << p;  // not moved
      if (kept_lobe) {
        EXPECT_TRUE(judged[p].ok) << p;
        EXPECT_NEAR(judged[p].chi2, reference.chi2, 1e-4 * reference.chi2) << p;
      } else {
        EXPECT_EQ(judged[p].lambertian_ok, reference.ok) << p;
        EXPECT_NEAR(judged[p].lambertian_chi2, reference.chi2, 1e-4 * reference.chi2) << p;
        EXPECT_NEAR(M_PI * judged[p].lambertian_x.norm(), reference.albedo, 1e-5 * reference.albedo) << p;
      }
    }
  }
}

// Noise-free GGX pixels (autodiff::GgxPixel renders them), started 3 deg off
// as step 6 starts from the kept fit: the lanes land on the true normal and
// roughness from the roughness grid's start.
TEST(GgxLanes, NoiseFreePixelsAreFittedToTheTruth) {
  const auto lights = testing::RingLights(40, 25, 80);
  const auto truth = testing::RandomSurface(10, 7, 40.0, 19);  // 70 pixels: not a multiple of the lane count
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const int pixels = truth.normals.rows * truth.normals.cols, n = static_cast<int>(lights.size());
  Eigen::Matrix<double, Eigen::Dynamic, 3> directions(n, 3);
  for (int k = 0; k < n; ++k) directions.row(k) = lights[k].transpose();
  const solvers::autodiff::GgxPixel model(directions, Eigen::VectorXd::Ones(n), Eigen::Vector3d::UnitZ(),
                                          Eigen::VectorXd::Zero(n));
  std::vector<double> observed(pixels * n), inverse_sigma(pixels * n, 100.0);
  std::vector<LobeProblem> problems;
  std::vector<Eigen::Vector3d> normals;
  std::vector<double> roughness;
  for (int p = 0; p < pixels; ++p) {
    const cv::Vec3f t = truth.normals.ptr<cv::Vec3f>()[p];
    const Eigen::Vector3d normal = Eigen::Vector3d(t[0], t[1], t[2]).normalized();
    const double a = 0.08 + 0.4 * unit(rng);
    const double parameters[6] = {normal.x(), normal.y(), normal.z(), truth.albedo.ptr<float>()[p],
                                  0.2 + 0.5 * unit(rng), a};
    ASSERT_TRUE(model.Predict(parameters, &observed[p * n]));
    const Eigen::Vector3d start = (normal + 0.05 * normal.unitOrthogonal()).normalized();
    problems.push_back({&observed[p * n], &inverse_sigma[p * n], start, parameters[3]});
    normals.push_back(normal);
    roughness.push_back(a);
  }
  LobeLaneFitter fitter(lights, Eigen::Vector3d::UnitZ(), BlinnPhongOptions{}, LaneLobe::kGgx);
  ExpectTrueParameters(&fitter, problems, normals, roughness);
}

// Noise-free pixels that each see their own lights and their own line of
// sight (near LEDs, a perspective camera): the ring tilted by up to 10 deg
// about a random axis, the view by up to 15 deg. render(lights, view, normal,
// observed) draws the pixel's material from rng, writes its samples and
// returns the material; each problem starts 3 deg off its normal.
struct OwnGeometryScene {
  int lights = 0;
  std::vector<double> observed, inverse_sigma, geometry;
  std::vector<LobeProblem> problems;
  std::vector<Eigen::Vector3d> normals;
  std::vector<internal::BlinnPhongMaterial> materials;

  std::vector<double> Shapes() const {
    std::vector<double> shapes;
    for (const auto& material : materials) shapes.push_back(material.exponent);
    return shapes;
  }
  // The largest relative error of rho_d or rho_s.
  double WorstAlbedoError(const std::vector<LobeSolution>& solutions) const {
    double worst = 0.0;
    for (std::size_t p = 0; p < materials.size(); ++p)
      worst = std::max({worst, std::abs(solutions[p].diffuse_albedo / materials[p].diffuse_albedo - 1.0),
                        std::abs(solutions[p].specular_albedo / materials[p].specular_albedo - 1.0)});
    return worst;
  }
};
template <typename Render>
OwnGeometryScene RenderOwnGeometry(std::mt19937& rng, Render render) {
  const auto ring = testing::RingLights(40, 25, 80);
  const int pixels = 37, n = static_cast<int>(ring.size());  // 37: not a multiple of the lane count
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  OwnGeometryScene scene;
  scene.lights = n;
  scene.observed.resize(pixels * n), scene.geometry.resize(6 * pixels * n);
  scene.inverse_sigma.assign(pixels * n, 100.0);
  for (int p = 0; p < pixels; ++p) {
    const Eigen::Vector3d axis = Eigen::Vector3d(unit(rng) - 0.5, unit(rng) - 0.5, 0.0).normalized();
    const Eigen::Matrix3d tilt = Eigen::AngleAxisd(unit(rng) * 10.0 * M_PI / 180, axis).toRotationMatrix();
    const Eigen::Vector3d view =
        Eigen::AngleAxisd(unit(rng) * 15.0 * M_PI / 180, axis.unitOrthogonal()).toRotationMatrix() * Eigen::Vector3d::UnitZ();
    std::vector<Eigen::Vector3d> lights;
    std::vector<double> towards;
    for (const Eigen::Vector3d& light : ring) {
      lights.push_back(tilt * light);
      towards.insert(towards.end(), lights.back().data(), lights.back().data() + 3);
    }
    internal::BlinnPhongGeometry(n, towards.data(), view, &scene.geometry[6 * p * n]);
    const Eigen::Vector3d normal =
        (Eigen::Vector3d::UnitZ() + 0.4 * Eigen::Vector3d(unit(rng) - 0.5, unit(rng) - 0.5, 0.0)).normalized();
    const internal::BlinnPhongMaterial material = render(lights, view, normal, &scene.observed[p * n]);
    LobeProblem problem{&scene.observed[p * n], &scene.inverse_sigma[p * n],
                        (normal + 0.05 * normal.unitOrthogonal()).normalized(), material.diffuse_albedo};
    problem.geometry = &scene.geometry[6 * p * n];
    problem.view = view;
    scene.problems.push_back(problem);
    scene.normals.push_back(normal);
    scene.materials.push_back(material);
  }
  return scene;
}

// The lanes read each pixel's geometry and land on its true parameters, as
// with shared lights.
TEST(BlinnPhongLanes, EachPixelsOwnLightsAndViewAreFittedToTheTruth) {
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const OwnGeometryScene scene = RenderOwnGeometry(rng, [&](const std::vector<Eigen::Vector3d>& lights,
                                                            const Eigen::Vector3d& view, const Eigen::Vector3d& normal,
                                                            double* observed) {
    const double rho_d = 0.3 + 0.4 * unit(rng), rho_s = 0.2 + 0.5 * unit(rng), e = 10.0 + 40.0 * unit(rng);
    for (std::size_t k = 0; k < lights.size(); ++k) {
      const Eigen::Vector3d half = (lights[k] + view).normalized();
      const double c = std::max(0.0, lights[k].dot(normal)), h = std::max(0.0, half.dot(normal));
      observed[k] = (rho_d / M_PI + rho_s * (e + 2) / (2 * M_PI) * std::pow(h, e)) * c;
    }
    return internal::BlinnPhongMaterial{rho_d, rho_s, e};
  });
  LobeLaneFitter fitter(scene.lights, BlinnPhongOptions{});
  ExpectTrueParameters(&fitter, scene.problems, scene.normals, scene.Shapes());
}

// The same for GGX (autodiff::GgxPixel renders each pixel under its own
// lights and view). A wrong view changes only S(v . n), the factor the lobe
// takes from the view, which rho_s absorbs at the true normal: rho_s shows it.
TEST(GgxLanes, EachPixelsOwnLightsAndViewAreFittedToTheTruth) {
  std::mt19937 rng(23);  // the Blinn-Phong test's pixels and geometry
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  OwnGeometryScene scene = RenderOwnGeometry(rng, [&](const std::vector<Eigen::Vector3d>& lights,
                                                      const Eigen::Vector3d& view, const Eigen::Vector3d& normal,
                                                      double* observed) {
    const int n = static_cast<int>(lights.size());
    Eigen::Matrix<double, Eigen::Dynamic, 3> directions(n, 3);
    for (int k = 0; k < n; ++k) directions.row(k) = lights[k].transpose();
    const solvers::autodiff::GgxPixel model(directions, Eigen::VectorXd::Ones(n), view, Eigen::VectorXd::Zero(n));
    const internal::BlinnPhongMaterial material{0.3 + 0.4 * unit(rng), 0.2 + 0.5 * unit(rng), 0.08 + 0.4 * unit(rng)};
    const double parameters[6] = {normal.x(), normal.y(), normal.z(), material.diffuse_albedo,
                                  material.specular_albedo, material.exponent};
    EXPECT_TRUE(model.Predict(parameters, observed));
    return material;
  });
  LobeLaneFitter fitter(scene.lights, BlinnPhongOptions{}, LaneLobe::kGgx);
  const auto solutions = ExpectTrueParameters(&fitter, scene.problems, scene.normals, scene.Shapes());
  EXPECT_LT(scene.WorstAlbedoError(solutions), 1e-4);

  for (LobeProblem& problem : scene.problems) problem.view = Eigen::Vector3d::UnitZ();
  std::vector<LobeSolution> wrong(scene.problems.size());
  fitter.Fit(scene.problems, wrong);
  EXPECT_GT(scene.WorstAlbedoError(wrong), 1e-2);
}

TEST(BlinnPhongLanes, SamplesWithoutWeightAreIgnored) {
  const auto lights = testing::RingLights(16, 30, 70);
  const int n = static_cast<int>(lights.size());
  std::vector<double> observed(n, 0.1), inverse_sigma(n, 0.0);
  BlinnPhongOptions options;
  LobeLaneFitter fitter(lights, Eigen::Vector3d::UnitZ(), options);
  // No usable sample: the cost is 0 and no step can lower it.
  std::vector<LobeProblem> problems{{observed.data(), inverse_sigma.data(), Eigen::Vector3d::UnitZ(), 0.5}};
  std::vector<LobeSolution> solutions(1);
  fitter.Fit(problems, solutions);
  EXPECT_EQ(solutions[0].chi2, 0.0);
  EXPECT_EQ(solutions[0].iterations, 0);
  // An absurd value on an unweighted sample adds nothing.
  std::fill(inverse_sigma.begin(), inverse_sigma.end(), 1.0);
  const auto clean = fitter.Linearize(problems[0], Eigen::Vector3d::UnitZ(), 0.5, 0.1, 20.0);
  inverse_sigma[3] = 0.0;
  observed[3] = 1e300;
  const auto masked = fitter.Linearize(problems[0], Eigen::Vector3d::UnitZ(), 0.5, 0.1, 20.0);
  EXPECT_TRUE(std::isfinite(masked.cost));
  EXPECT_LT(masked.cost, clean.cost);
}

using internal::TrimmedLambertianLanes;
using internal::TrimSolution;

// Rows of samples (pixels x lights, in solver units with sigma 1) as a stack
// one pixel high, light scales 1 and read noise 1: the trimmer sees exactly
// these values and weights.
PhotometricStack RowStack(const std::vector<Eigen::Vector3d>& lights, const std::vector<double>& observed) {
  const int n = static_cast<int>(lights.size()), pixels = static_cast<int>(observed.size()) / n;
  PhotometricStack stack;
  for (int k = 0; k < n; ++k) {
    cv::Mat plane(1, pixels, CV_32F);
    for (int p = 0; p < pixels; ++p) plane.at<float>(0, p) = static_cast<float>(observed[p * n + k]);
    stack.images.push_back(plane);
  }
  stack.light_directions = lights;
  stack.light_scales.assign(n, 1.0);
  stack.noise.read_sigma = 1.0;
  return stack;
}

// The first `count` pixels' samples as the trimmer takes them.
std::vector<float> Rows(const TrimmedLambertianLanes& trimmer, int count) {
  std::vector<float> rows(static_cast<std::size_t>(count) * trimmer.row_length());
  for (int p = 0; p < count; ++p) trimmer.CopySamples(p, &rows[p * trimmer.row_length()]);
  return rows;
}

// Chi-square 0.999 quantiles are not needed here: a threshold per dof that
// accepts a fit whose residuals are at the noise level (sigma = 1).
std::vector<double> Thresholds(int lights) {
  std::vector<double> quantile(lights + 1);
  for (int dof = 0; dof <= lights; ++dof) quantile[dof] = 2.0 * dof + 10.0;
  return quantile;
}

TEST(TrimmedLambertianLanes, DropsExactlyTheOutliersAndNothingElse) {
  const auto lights = testing::RingLights(32, 25, 80);
  const int n = static_cast<int>(lights.size()), pixels = 21;  // not a multiple of the lane count
  std::mt19937 rng(23);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::uniform_int_distribution<int> pick(0, n - 1);
  std::vector<double> observed(pixels * n);
  std::vector<Eigen::Vector3d> truth;
  std::vector<int> outliers;
  for (int p = 0; p < pixels; ++p) {
    const Eigen::Vector3d x = Eigen::Vector3d(0.2 * noise(rng), 0.2 * noise(rng), 1.0).normalized() * 150.0;
    truth.push_back(x);
    for (int k = 0; k < n; ++k) observed[p * n + k] = lights[k].dot(x) + noise(rng);
    // Pixel p gets p % 4 highlights, each far above the noise.
    std::vector<int> hit;
    while (static_cast<int>(hit.size()) < p % 4) {
      const int k = pick(rng);
      if (std::find(hit.begin(), hit.end(), k) != hit.end()) continue;
      hit.push_back(k);
      observed[p * n + k] += 80.0 + 20.0 * hit.size();
    }
    outliers.push_back(p % 4);
  }
  // One pixel whose residuals are broad, not a few outliers: trimming must
  // give up within its allowance and say so.
  for (int k = 0; k < n; ++k) observed[5 * n + k] += 30.0 * std::sin(1.7 * k);
  outliers[5] = -1;
  const PhotometricStack stack = RowStack(lights, observed);
  TrimmedLambertianLanes trimmer(stack, LambertianOptions{}, 25.0, 6.0 / n);  // at most 6 samples
  std::vector<TrimSolution> solutions(pixels);
  const std::vector<double> thresholds = Thresholds(n);
  trimmer.Fit(Rows(trimmer, pixels), thresholds, solutions);
  for (int p = 0; p < pixels; ++p) {
    const TrimSolution& s = solutions[p];
    ASSERT_TRUE(s.ok) << p;
    if (outliers[p] < 0) {
      EXPECT_LE(s.rejected, 6) << p;
      EXPECT_GT(s.chi2, thresholds[s.used - 3]) << p;
      continue;
    }
    EXPECT_EQ(s.rejected, outliers[p]) << p;
    EXPECT_EQ(s.used, n - outliers[p]) << p;
    EXPECT_LE(s.chi2, thresholds[s.used - 3]) << p;
    EXPECT_LT((s.x - truth[p]).norm(), 2.0) << p;  // a few noise sigmas over ~30 samples
  }
}

// `auto` copies a doubtful pixel's samples while its tile is in cache and
// rechecks it later from the copy: the same test, bit for bit, as from the
// planes, for pixels that pass, fail, and are refitted without a sample in
// attached shadow.
TEST(RecheckLanes, ReadsCopiedSamplesAsThePlanes) {
  const auto lights = testing::RingLights(32, 25, 80);
  const int n = static_cast<int>(lights.size()), pixels = 21;  // not a multiple of the lane count
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<double> observed(pixels * n);
  std::vector<Eigen::Vector3d> x;
  for (int p = 0; p < pixels; ++p) {
    const Eigen::Vector3d normal = Eigen::Vector3d(0.6 * noise(rng), 0.6 * noise(rng), 1.0).normalized();
    x.push_back(normal * 100.0);
    for (int k = 0; k < n; ++k) observed[p * n + k] = std::max(0.0, lights[k].dot(x.back())) + noise(rng);
    if (p % 3 == 1) observed[p * n + p % n] += 60.0;  // an outlier
  }
  const PhotometricStack stack = RowStack(lights, observed);
  const internal::RecheckLanes recheck(stack, LambertianOptions{});
  std::vector<int> indices(pixels);
  std::vector<float> copies(static_cast<std::size_t>(pixels) * n);
  for (int p = 0; p < pixels; ++p) indices[p] = p;
  recheck.CopySamples(indices, copies.data());
  std::vector<internal::Recheck> from_planes(pixels), from_copies(pixels);
  recheck.Check(indices, x, from_planes);
  recheck.Check(indices, x, from_copies, copies.data());
  int refitted = 0;
  for (int p = 0; p < pixels; ++p) {
    EXPECT_EQ(from_copies[p].chi2, from_planes[p].chi2) << p;
    EXPECT_EQ(from_copies[p].used, from_planes[p].used) << p;
    EXPECT_EQ(from_copies[p].unlit, from_planes[p].unlit) << p;
    EXPECT_EQ(from_copies[p].refitted, from_planes[p].refitted) << p;
    EXPECT_EQ(from_copies[p].lit_x, from_planes[p].lit_x) << p;
    EXPECT_EQ(from_copies[p].lit_chi2, from_planes[p].lit_chi2) << p;
    EXPECT_GT(from_planes[p].used, 0) << p;
    refitted += from_planes[p].refitted;
  }
  EXPECT_GT(refitted, 0);  // the refit path is exercised too
  // Pixels in any order, over more than one block: each row is its pixel's.
  const std::vector<int> scrambled = {20, 3, 3, 17, 0, 9, 12, 1, 19, 5, 8, 14, 2, 11, 6, 16, 4, 7};
  std::vector<float> rows(scrambled.size() * n);
  recheck.CopySamples(scrambled, rows.data());
  for (std::size_t j = 0; j < scrambled.size(); ++j)
    for (int k = 0; k < n; ++k) ASSERT_EQ(rows[j * n + k], stack.images[k].ptr<float>()[scrambled[j]]) << j << " " << k;
}

// A lone bad sample leaves alone; gross ones leave together with everything
// within a factor 2 of the worst residual, and nothing below the gross level.
TEST(TrimThreshold, GreedyBelowTheGrossLevelTogetherAboveIt) {
  EXPECT_EQ(internal::TrimThreshold(16.0, 25.0), 16.0);     // only the worst
  EXPECT_EQ(internal::TrimThreshold(400.0, 25.0), 100.0);   // within 2x of a 20-sigma residual
  EXPECT_EQ(internal::TrimThreshold(64.0, 25.0), 25.0);     // never below the gross level
  EXPECT_EQ(internal::TrimThreshold(0.0, 25.0), 0.0);       // nothing stands out
}

// A highlight spread over more lights than the allowance: the first round
// sees more gross samples than may be dropped, so the pixel hands over its
// untrimmed fit at once instead of trimming its whole allowance first.
TEST(TrimmedLambertianLanes, HandsOverAtOnceWhenGrossSamplesExceedTheAllowance) {
  const auto lights = testing::RingLights(32, 25, 80);
  const int n = static_cast<int>(lights.size());
  const Eigen::Vector3d x = Eigen::Vector3d(0.1, -0.2, 1.0).normalized() * 150.0;
  std::vector<double> observed(n);
  for (int k = 0; k < n; ++k) observed[k] = lights[k].dot(x) + (k < 12 ? 200.0 : 0.0);  // 12 bright samples
  const PhotometricStack stack = RowStack(lights, observed);
  std::vector<TrimSolution> solutions(1);
  const std::vector<double> thresholds = Thresholds(n);
  TrimmedLambertianLanes at_gross(stack, LambertianOptions{}, 25.0, 6.0 / n);
  at_gross.Fit(Rows(at_gross, 1), thresholds, solutions);
  ASSERT_TRUE(solutions[0].ok);
  EXPECT_EQ(solutions[0].rejected, 0);
  EXPECT_GT(solutions[0].chi2, thresholds[n - 3]);
  // With a gross level above every residual the same pixel trims one sample
  // per round and stops at its allowance, still inadequate.
  TrimmedLambertianLanes never_gross(stack, LambertianOptions{}, 1e12, 6.0 / n);
  never_gross.Fit(Rows(never_gross, 1), thresholds, solutions);
  EXPECT_EQ(solutions[0].rejected, 6);
  EXPECT_GT(solutions[0].chi2, thresholds[solutions[0].used - 3]);
}

// Weights 1 / sigma^2 in solver units reach 1e12 with a light scale of 1e6
// and unit read noise: float normal equations of such weights overflow (their
// determinant is ~1e39). The trimmer scales them and still solves the pixel,
// to float precision, with its two gross outliers gone.
TEST(TrimmedLambertianLanes, SolvesPixelsWhateverTheScaleOfTheirWeights) {
  const auto lights = testing::RingLights(32, 25, 80);
  const int n = static_cast<int>(lights.size());
  const double scale = 1e6;
  const Eigen::Vector3d x = Eigen::Vector3d(0.1, -0.2, 1.0).normalized() * 0.5;
  std::vector<double> observed(n);
  for (int k = 0; k < n; ++k) observed[k] = scale * lights[k].dot(x) + (k == 3 || k == 17 ? 0.2 * scale : 0.0);
  PhotometricStack stack = RowStack(lights, observed);
  stack.light_scales.assign(n, scale);
  TrimmedLambertianLanes trimmer(stack, LambertianOptions{}, 25.0, 6.0 / n);
  std::vector<TrimSolution> solutions(1);
  trimmer.Fit(Rows(trimmer, 1), Thresholds(n), solutions);
  ASSERT_TRUE(solutions[0].ok);
  EXPECT_GE(solutions[0].rejected, 2);
  EXPECT_LT((solutions[0].x - x).norm(), 1e-5 * x.norm()) << solutions[0].x.transpose();
}

// IRLS written the plain way, one pixel, usable samples only: the iteration
// irls_lambertian_fit.h documents.
internal::RobustSolution PlainIrls(const std::vector<Eigen::Vector3d>& lights, const double* observed,
                                   const double* inverse_sigma, Eigen::Vector3d x, const RobustOptions& options) {
  std::vector<int> usable;
  for (int k = 0; k < static_cast<int>(lights.size()); ++k)
    if (inverse_sigma[k] > 0.0) usable.push_back(k);
  const int n = static_cast<int>(usable.size());
  std::vector<double> weight(n, 1.0), residual(n), magnitude(n);
  int iteration = 0;
  while (iteration < options.max_iterations) {
    const bool warmup = iteration < options.warmup_iterations;
    const RobustOptions::Loss loss = warmup ? RobustOptions::Loss::kCauchy : options.loss;
    for (int i = 0; i < n; ++i) {
      residual[i] = observed[usable[i]] - lights[usable[i]].dot(x);
      magnitude[i] = std::abs(residual[i]);
    }
    std::nth_element(magnitude.begin(), magnitude.begin() + n / 2, magnitude.end());
    const double spread = 1.4826 * magnitude[n / 2];
    Eigen::Matrix3d normal_matrix = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    for (int i = 0; i < n; ++i) {
      const double sigma = 1.0 / inverse_sigma[usable[i]];
      const double u = std::abs(residual[i]) / std::max(sigma, spread);
      if (loss == RobustOptions::Loss::kCauchy) weight[i] = 1.0 / (1.0 + (u / 2.385) * (u / 2.385));
      if (loss == RobustOptions::Loss::kHuber) weight[i] = u <= 1.345 ? 1.0 : 1.345 / u;
      if (loss == RobustOptions::Loss::kTukey) weight[i] = u < 4.685 ? std::pow(1.0 - (u / 4.685) * (u / 4.685), 2) : 0.0;
      const Eigen::Vector3d& w = lights[usable[i]];
      const double c = weight[i] / (sigma * sigma);
      normal_matrix += c * w * w.transpose();
      rhs += c * observed[usable[i]] * w;
    }
    const Eigen::Vector3d next = normal_matrix.ldlt().solve(rhs);
    const double step = (next - x).norm();
    x = next;
    ++iteration;
    if (!warmup && step <= options.relative_tolerance * x.norm()) break;
  }
  internal::RobustSolution solution;
  solution.x = x;
  solution.iterations = iteration;
  for (int i = 0; i < n; ++i) {
    if (weight[i] < options.inlier_weight) {
      ++solution.rejected;
      continue;
    }
    const double r = observed[usable[i]] - lights[usable[i]].dot(x);
    solution.chi2 += r * r * inverse_sigma[usable[i]] * inverse_sigma[usable[i]];
    ++solution.used;
  }
  solution.ok = solution.used >= 3;
  return solution;
}

// Pixels with highlights, shadowed (unusable) samples and per-sample noise,
// fitted in lanes with each loss, against the plain iteration. Ties between
// the float and double weights decide nothing: both agree to 1e-6 relative.
TEST(RobustLambertianLanes, MatchesThePlainIterationForEveryLoss) {
  const auto lights = testing::RingLights(40, 20, 80);
  const int n = static_cast<int>(lights.size()), pixels = 29;  // not a multiple of the lane count
  std::mt19937 rng(41);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::vector<double> observed(pixels * n), inverse_sigma(pixels * n);
  std::vector<Eigen::Vector3d> starts;
  for (int p = 0; p < pixels; ++p) {
    const Eigen::Vector3d x = Eigen::Vector3d(0.4 * noise(rng), 0.4 * noise(rng), 1.0).normalized() * 120.0;
    for (int k = 0; k < n; ++k) {
      const double signal = lights[k].dot(x);
      const double sigma = std::sqrt(4.0 + 0.5 * std::max(signal, 0.0));
      const bool usable = signal > 5.0 && uniform(rng) > 0.1;
      inverse_sigma[p * n + k] = usable ? 1.0 / sigma : 0.0;
      observed[p * n + k] = usable ? signal + sigma * noise(rng) + (uniform(rng) < 0.15 ? 150.0 : 0.0) : 0.0;
    }
    starts.push_back(x + Eigen::Vector3d(10.0 * noise(rng), 10.0 * noise(rng), 10.0 * noise(rng)));
  }
  for (const auto loss : {RobustOptions::Loss::kCauchy, RobustOptions::Loss::kHuber, RobustOptions::Loss::kTukey}) {
    RobustOptions options;
    options.loss = loss;
    std::vector<internal::RobustProblem> problems;
    for (int p = 0; p < pixels; ++p) problems.push_back({&observed[p * n], &inverse_sigma[p * n], starts[p]});
    std::vector<internal::RobustSolution> solutions(pixels);
    internal::RobustLambertianLanes(lights, options).Fit(problems, solutions);
    for (int p = 0; p < pixels; ++p) {
      const auto plain = PlainIrls(lights, &observed[p * n], &inverse_sigma[p * n], starts[p], options);
      const auto& lanes = solutions[p];
      ASSERT_TRUE(plain.ok && lanes.ok) << "loss " << int(loss) << " pixel " << p;
      EXPECT_LT((lanes.x - plain.x).norm(), 1e-6 * plain.x.norm()) << "loss " << int(loss) << " pixel " << p;
      EXPECT_EQ(lanes.used, plain.used) << "loss " << int(loss) << " pixel " << p;
      EXPECT_EQ(lanes.rejected, plain.rejected) << "loss " << int(loss) << " pixel " << p;
      EXPECT_NEAR(lanes.chi2, plain.chi2, 1e-6 * plain.chi2 + 1e-9) << "loss " << int(loss) << " pixel " << p;
      EXPECT_NEAR(lanes.iterations, plain.iterations, 1) << "loss " << int(loss) << " pixel " << p;
    }
  }
}

// Fewer than three usable samples cannot be solved: the lane says so, and
// the lanes beside it are not disturbed.
TEST(RobustLambertianLanes, FlagsUnsolvablePixelsWithoutDisturbingTheOthers) {
  const auto lights = testing::RingLights(24, 30, 70);
  const int n = static_cast<int>(lights.size());
  const Eigen::Vector3d x(10.0, -20.0, 100.0);
  std::vector<double> observed(3 * n), inverse_sigma(3 * n, 0.0);
  for (int p = 0; p < 3; ++p)
    for (int k = 0; k < n; ++k) observed[p * n + k] = lights[k].dot(x);
  for (int k = 0; k < n; ++k) inverse_sigma[k] = inverse_sigma[2 * n + k] = 1.0;  // pixels 0 and 2: every sample
  inverse_sigma[n] = inverse_sigma[n + 1] = 1.0;                                  // pixel 1: two samples
  std::vector<internal::RobustProblem> problems;
  for (int p = 0; p < 3; ++p) problems.push_back({&observed[p * n], &inverse_sigma[p * n], Eigen::Vector3d(0, 0, 90)});
  std::vector<internal::RobustSolution> solutions(3);
  internal::RobustLambertianLanes(lights, RobustOptions{}).Fit(problems, solutions);
  EXPECT_FALSE(solutions[1].ok);
  for (int p : {0, 2}) {
    EXPECT_TRUE(solutions[p].ok) << p;
    EXPECT_LT((solutions[p].x - x).norm(), 1e-6 * x.norm()) << p;
    EXPECT_EQ(solutions[p].used, n) << p;
  }
}

using testing::AngleDeg;

// `auto` through the lanes and through the per-pixel reference on the same
// shiny stack: the same models for (nearly) every pixel, the same normals
// where both trimmed, close ones where both fitted Blinn-Phong.
// `auto` in lanes against the per-pixel pipeline on the same stack: the same
// model for >= 98 % of pixels, the same trimmed normals (on at least
// `min_trimmed` pixels), Blinn-Phong normals within 0.1 deg where the model fits.
// Every pixel fits its own lobe in both: the lattice lobes are a choice of
// the lane pipeline's, tested on their own (PhotometricStereo.LatticeLobes*).
void ExpectAutoLanesMatchThePerPixelReference(const PhotometricStack& stack, int min_trimmed) {
  PhotometricStereoOptions lanes_options = LaneOptions(Method::kAuto);
  lanes_options.selection.lattice_lobes = false;
  const PhotometricStereoOptions reference_options = PerPixel(lanes_options);
  NormalMap lanes_map, reference_map;
  const SolverSummary lanes = SolvePhotometricStereo(lanes_options, stack, &lanes_map);
  const SolverSummary reference = SolvePhotometricStereo(reference_options, stack, &reference_map);
  ASSERT_TRUE(lanes.IsSolutionUsable()) << lanes.message;
  ASSERT_TRUE(reference.IsSolutionUsable()) << reference.message;
  ASSERT_GE(reference.pixels_trimmed, std::size_t(min_trimmed));
  ASSERT_GT(reference.pixels_blinn_phong, 50u);
  const double pixels = double(reference.pixels_solved);
  EXPECT_LE(std::abs(double(lanes.pixels_trimmed) - double(reference.pixels_trimmed)), 0.005 * pixels);
  EXPECT_LE(std::abs(double(lanes.pixels_blinn_phong) - double(reference.pixels_blinn_phong)), 0.01 * pixels);
  int same_model = 0, trimmed = 0;
  for (int p = 0; p < stack.width() * stack.height(); ++p) {
    const auto model = lanes_map.model.ptr<std::uint8_t>()[p];
    if (model != reference_map.model.ptr<std::uint8_t>()[p]) continue;
    ++same_model;
    const cv::Vec3f a = lanes_map.normals.ptr<cv::Vec3f>()[p], b = reference_map.normals.ptr<cv::Vec3f>()[p];
    if (model == static_cast<std::uint8_t>(PixelModel::kTrimmed)) {
      ++trimmed;
      EXPECT_LT(AngleDeg(a, b), 1e-3) << "pixel " << p;  // the same algorithm
    } else if (model == static_cast<std::uint8_t>(PixelModel::kBlinnPhong) &&
               reference_map.confidence.ptr<float>()[p] > 0.1f) {
      EXPECT_LT(AngleDeg(a, b), 0.1) << "pixel " << p;
    }
  }
  EXPECT_GE(same_model, 0.98 * pixels);
  EXPECT_GE(trimmed, min_trimmed);
}

// The noise estimate's per-pixel fits through the tile kernel, against the
// same least squares in double: usable counts exactly, the sums over the
// usable samples to float precision, the residual to the kernel's documented
// precision.
TEST(PixelResiduals, MatchLeastSquaresInDouble) {
  const auto truth = testing::RandomSurface(64, 32, 70.0, 5);
  const auto lights = testing::RingLights(24, 20, 70);
  const double scale = 1500.0;
  const float dark = 15.0f;
  const PhotometricStack stack = testing::RenderShinyStack(truth, lights, scale, {}, dark, 2.0);
  LambertianOptions options;
  options.shadow_threshold = 8.0;
  const internal::PixelResiduals fitter(options, stack);
  ASSERT_TRUE(fitter.ok());
  const std::vector<internal::PixelResiduals::Run> runs = {{0, 32}, {100, 7}, {1000, 256}, {2000, 48}};
  std::vector<internal::PixelResidual> fits(32 + 7 + 256 + 48);
  fitter.Fit(runs, fits.data());
  std::size_t index = 0, checked = 0;
  for (const auto& run : runs) {
    for (int p = run.begin; p < run.begin + run.count; ++p, ++index) {
      const internal::PixelResidual& fit = fits[index];
      const testing::UsableLeastSquares reference =
          testing::SolveUsableInDouble(stack, p, scale, dark, options.shadow_threshold);
      ASSERT_EQ(fit.usable, reference.usable) << "pixel " << p;
      if (fit.usable < 4 || !fit.conditioned) continue;
      EXPECT_NEAR(fit.sum_inverse_scale2, reference.sum_inverse_scale2, 1e-6 * reference.sum_inverse_scale2);
      EXPECT_NEAR(fit.sum_signal_inverse_scale2, reference.sum_signal_inverse_scale2,
                  1e-5 * reference.sum_signal_inverse_scale2);
      EXPECT_NEAR(fit.rss, reference.rss, 0.04 * reference.rss) << "pixel " << p;
      ++checked;
    }
  }
  EXPECT_GT(checked, 250u);
}

TEST(PhotometricStereoLanes, AutoMatchesThePerPixelReference) {
  const auto truth = testing::RandomSurface(40, 30, 45.0, 29);
  const auto lights = testing::RingLights(36, 20, 80);
  // Every pixel glossy: wherever trimming drops samples the lobe fit explains
  // the pixel better, so no pixel keeps the trimmed fit.
  ExpectAutoLanesMatchThePerPixelReference(
      testing::RenderShinyStack(truth, lights, 2500.0, testing::Specular{0.3, 120.0}, 20.0f, 2.0), 0);
}

// Few doubtful pixels per tile: the lane stages' queues then carry pixels
// (and their copied samples) from tile to tile before a batch is full, and
// the rows of the pixels still queued are moved up after each batch.
TEST(PhotometricStereoLanes, AutoMatchesThePerPixelReferenceWithFewDoubtfulPixelsPerTile) {
  const auto truth = testing::RandomSurface(128, 128, 45.0, 31);
  const auto lights = testing::RingLights(36, 20, 80);
  PhotometricStack stack = testing::RenderShinyStack(truth, lights, 2500.0, {}, 20.0f, 2.0);
  const PhotometricStack shiny =
      testing::RenderShinyStack(truth, lights, 2500.0, testing::Specular{0.3, 120.0}, 20.0f, 2.0);
  // One pixel in twelve is glossy: about 85 per 1024-pixel tile, of which only
  // some need trimming or the Blinn-Phong fit.
  for (int p = 0; p < stack.width() * stack.height(); p += 12)
    for (std::size_t k = 0; k < lights.size(); ++k) stack.images[k].ptr<float>()[p] = shiny.images[k].ptr<float>()[p];
  // One matte pixel in twelve has two spikes no lobe explains (as from
  // inter-reflection): those keep the trimmed fit.
  for (int p = 6; p < stack.width() * stack.height(); p += 12)
    for (int k : {p % 36, (p / 36 + 7) % 36}) stack.images[k].ptr<float>()[p] *= 3.0f;
  ExpectAutoLanesMatchThePerPixelReference(stack, 50);
}

}  // namespace
}  // namespace photorig::solvers::ps
