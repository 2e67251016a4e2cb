#include "photorig/solvers/autodiff/ggx.h"

#include <cmath>
#include <numbers>
#include <random>

#include <Eigen/Core>
#include <gtest/gtest.h>

#include "test_util.h"

namespace photorig::solvers::autodiff {
namespace {

using testing::ColumnRelativeError;

// The microfacet BRDF as sim/ writes it (brdf.h), its specular part only, with F = 1.
double GgxLobe(const Eigen::Vector3d& n, const Eigen::Vector3d& l, const Eigen::Vector3d& v, double a) {
  const double nl = n.dot(l), nv = n.dot(v), nh = n.dot((l + v).normalized()), a2 = a * a;
  const double t = nh * nh * (a2 - 1.0) + 1.0;
  auto g1 = [a2](double c) { return 2.0 * c / (c + std::sqrt(a2 + (1.0 - a2) * c * c)); };
  return a2 / (std::numbers::pi * t * t) * g1(nl) * g1(nv) / (4.0 * nl * nv);
}

// Lights 15-80 deg above the horizon, the normal within 50 deg of the view (+z).
struct Scene {
  Eigen::Matrix<double, Eigen::Dynamic, 3> lights;
  Eigen::Vector3d normal;
};
Scene RandomScene(int count, std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto direction = [&](double min_elevation_deg, double max_elevation_deg) {
    const double elevation = (min_elevation_deg + (max_elevation_deg - min_elevation_deg) * unit(rng)) *
                             std::numbers::pi / 180.0;
    const double azimuth = 2.0 * std::numbers::pi * unit(rng);
    return Eigen::Vector3d(std::cos(elevation) * std::cos(azimuth), std::cos(elevation) * std::sin(azimuth),
                           std::sin(elevation));
  };
  Scene scene;
  scene.lights.resize(count, 3);
  for (int i = 0; i < count; ++i) scene.lights.row(i) = direction(15.0, 80.0).transpose();
  scene.normal = direction(40.0, 90.0);
  return scene;
}

TEST(GgxTest, PredictsTheSimulatorsLobeTimesTheCosine) {
  std::mt19937 rng(7);
  const Scene scene = RandomScene(32, rng);
  const Eigen::Vector3d view = Eigen::Vector3d::UnitZ();
  const GgxPixel pixel(scene.lights, Eigen::VectorXd::Constant(32, 2.0), view, Eigen::VectorXd::Zero(32));
  const double rho_d = 0.6, rho_s = 0.3, a = 0.18;
  const double parameters[6] = {scene.normal.x(), scene.normal.y(), scene.normal.z(), rho_d, rho_s, a};
  Eigen::VectorXd predicted(32);
  ASSERT_TRUE(pixel.Predict(parameters, predicted.data()));
  int lit = 0;
  for (int i = 0; i < 32; ++i) {
    const Eigen::Vector3d l = scene.lights.row(i).transpose();
    const double cosine = scene.normal.dot(l);
    const double expected =
        cosine > 0.0 ? 2.0 * (rho_d / std::numbers::pi + rho_s * GgxLobe(scene.normal, l, view, a)) * cosine : 0.0;
    EXPECT_NEAR(predicted[i], expected, 1e-12 * (1.0 + expected)) << i;
    lit += cosine > 0.0;
  }
  EXPECT_GT(lit, 8);
}

TEST(GgxTest, ForwardReverseSymbolicAndCentralDifferencesAgree) {
  std::mt19937 rng(2024);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Tape tape;
  for (int trial = 0; trial < 20; ++trial) {
    const int count = 4 + trial;
    const Scene scene = RandomScene(count, rng);
    // Lights of unequal intensity, so that every method must scale each row by its own.
    const Eigen::VectorXd intensities = (Eigen::VectorXd::Random(count).array() * 0.5 + 1.0).matrix();
    const GgxPixel pixel(scene.lights, intensities, Eigen::Vector3d::UnitZ(), Eigen::VectorXd::Constant(count, 0.1));
    // An iterate: the normal unnormalised, the material anywhere in its range.
    const double scale = 0.5 + unit(rng);
    const double x[6] = {scale * scene.normal.x(), scale * scene.normal.y(), scale * scene.normal.z(),
                         0.2 + 0.6 * unit(rng), 0.05 + 0.5 * unit(rng), 0.05 + 0.6 * unit(rng)};
    Eigen::VectorXd rf, rr, rs, rc;
    Eigen::MatrixXd jf, jr, js, jc;
    ASSERT_TRUE(GgxResidualsAndJacobian(pixel, x, DerivativeMethod::kForward, &rf, &jf));
    ASSERT_TRUE(GgxResidualsAndJacobian(pixel, x, DerivativeMethod::kReverse, &rr, &jr, &tape));
    ASSERT_TRUE(GgxResidualsAndJacobian(pixel, x, DerivativeMethod::kSymbolic, &rs, &js));
    ASSERT_TRUE(GgxResidualsAndJacobian(pixel, x, DerivativeMethod::kCentralDifference, &rc, &jc));
    EXPECT_LT((rf - rr).cwiseAbs().maxCoeff(), 1e-13 * (1.0 + rf.cwiseAbs().maxCoeff()));
    EXPECT_LT((rf - rs).cwiseAbs().maxCoeff(), 1e-13 * (1.0 + rf.cwiseAbs().maxCoeff()));
    EXPECT_LT(ColumnRelativeError(jr, jf), 1e-12) << trial;
    EXPECT_LT(ColumnRelativeError(js, jf), 1e-12) << trial;
    EXPECT_LT(ColumnRelativeError(jc, jf), 1e-6) << trial;
  }
}

}  // namespace
}  // namespace photorig::solvers::autodiff
