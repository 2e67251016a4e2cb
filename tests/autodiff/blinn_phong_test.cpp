#include "photorig/solvers/autodiff/blinn_phong.h"

#include <array>
#include <cmath>
#include <numbers>
#include <random>

#include <ceres/jet.h>
#include <Eigen/Core>
#include <gtest/gtest.h>

#include "photorig/solvers/autodiff/blinn_phong_jacobian.h"
#include "photorig/solvers/autodiff/blinn_phong_symbolic.h"
#include "photorig/solvers/autodiff/random_pixel.h"
#include "test_util.h"

namespace photorig::solvers::autodiff {
namespace {

using testing::ColumnRelativeError;

constexpr DerivativeMethod kAllMethods[] = {DerivativeMethod::kForward, DerivativeMethod::kReverse,
                                            DerivativeMethod::kSymbolic,
                                            DerivativeMethod::kCentralDifference};

struct Evaluation {
  bool ok;
  Eigen::VectorXd residuals;
  Eigen::MatrixXd jacobian;
};

Evaluation Evaluate(const BlinnPhongPixel& pixel, const double* parameters,
                    DerivativeMethod method) {
  Evaluation e;
  e.ok = BlinnPhongResidualsAndJacobian(pixel, parameters, method, &e.residuals, &e.jacobian);
  return e;
}

TEST(BlinnPhongTest, AllMethodsAgreeOnRandomPixels) {
  std::mt19937 rng(2024);
  Tape tape;  // Reused across pixels, as a fitter would.
  for (int trial = 0; trial < 40; ++trial) {
    const int num_lights = 1 + trial;
    const RandomPixel random = MakeRandomPixel(num_lights, rng);
    const double* x = random.parameters.data();
    const Evaluation symbolic = Evaluate(random.pixel, x, DerivativeMethod::kSymbolic);
    const Evaluation forward = Evaluate(random.pixel, x, DerivativeMethod::kForward);
    Evaluation reverse;
    reverse.ok = BlinnPhongResidualsAndJacobian(random.pixel, x, DerivativeMethod::kReverse,
                                                &reverse.residuals, &reverse.jacobian, &tape);
    const Evaluation central = Evaluate(random.pixel, x, DerivativeMethod::kCentralDifference);
    ASSERT_TRUE(symbolic.ok && forward.ok && reverse.ok && central.ok);
    ASSERT_EQ(symbolic.jacobian.rows(), num_lights);
    ASSERT_EQ(symbolic.jacobian.cols(), 6);

    // Values differ only by the order of the floating-point operations.
    const double tolerance = 1e-13 * (1.0 + symbolic.residuals.cwiseAbs().maxCoeff());
    EXPECT_LT((forward.residuals - symbolic.residuals).cwiseAbs().maxCoeff(), tolerance);
    EXPECT_LT((reverse.residuals - symbolic.residuals).cwiseAbs().maxCoeff(), tolerance);
    EXPECT_LT((central.residuals - symbolic.residuals).cwiseAbs().maxCoeff(), tolerance);

    EXPECT_LT(ColumnRelativeError(forward.jacobian, symbolic.jacobian), 1e-12) << trial;
    EXPECT_LT(ColumnRelativeError(reverse.jacobian, symbolic.jacobian), 1e-12) << trial;
    EXPECT_LT(ColumnRelativeError(reverse.jacobian, forward.jacobian), 1e-12) << trial;
    // Central differences: error ~ eps^(2/3) ~ 4e-11 times the ratio of third to first
    // derivatives, which reaches ~100 for exponents up to ~70 (observed worst: 5e-9).
    EXPECT_LT(ColumnRelativeError(central.jacobian, symbolic.jacobian), 1e-7) << trial;
  }
}

TEST(BlinnPhongTest, DualAgreesWithCeresJet) {
  std::mt19937 rng(99);
  const RandomPixel random = MakeRandomPixel(24, rng);
  using Jet = ceres::Jet<double, 6>;
  std::array<Jet, 6> jet_in;
  std::array<Dual<6>, 6> dual_in;
  for (int j = 0; j < 6; ++j) {
    jet_in[j] = Jet(random.parameters[j], j);
    dual_in[j] = Dual<6>(random.parameters[j], j);
  }
  std::vector<Jet> jet_out(24);
  std::vector<Dual<6>> dual_out(24);
  ASSERT_TRUE(random.pixel(jet_in.data(), jet_out.data()));
  ASSERT_TRUE(random.pixel(dual_in.data(), dual_out.data()));
  for (int i = 0; i < 24; ++i) {
    EXPECT_NEAR(dual_out[i].value, jet_out[i].a, 1e-15);
    for (int j = 0; j < 6; ++j) {
      EXPECT_NEAR(dual_out[i].tangent[j], jet_out[i].v[j],
                  1e-12 * (1.0 + std::abs(jet_out[i].v[j])));
    }
  }
}

// The hand-derived pixel gradient dL_o/dn (unit n, L_o = sum over lights) against forward mode
// applied to the same rendering without the normalisation.
TEST(BlinnPhongTest, SymbolicPixelGradientIsTheDerivativeOfTheRadiance) {
  std::mt19937 rng(5);
  const RandomPixel random = MakeRandomPixel(12, rng);
  const BlinnPhongPixel& pixel = random.pixel;
  const Eigen::Vector3d n =
      Eigen::Vector3d(random.parameters[0], random.parameters[1], random.parameters[2])
          .normalized();
  const double rho_d = random.parameters[3], rho_s = random.parameters[4], e = random.parameters[5];

  using D = Dual<6>;
  const Eigen::Matrix<D, 3, 1> nd(D(n.x(), 0), D(n.y(), 1), D(n.z(), 2));
  const BlinnPhongLobe<D> lobe(D(rho_d, 3), D(rho_s, 4), D(e, 5));
  D radiance(0.0);
  Eigen::Matrix<double, 6, 1> symbolic = Eigen::Matrix<double, 6, 1>::Zero();
  for (int i = 0; i < pixel.num_lights(); ++i) {
    radiance += pixel.light_intensity(i) *
                BlinnPhongShading(nd, lobe, pixel.light_direction(i), pixel.half_vector(i));
    const BlinnPhongLightGradient g =
        SymbolicBlinnPhongLightGradient(n, rho_d, rho_s, e, pixel.light_direction(i),
                                        pixel.half_vector(i), pixel.light_intensity(i));
    symbolic << symbolic.head<3>() + g.d_normal, symbolic[3] + g.d_diffuse_albedo,
        symbolic[4] + g.d_specular_albedo, symbolic[5] + g.d_exponent;
  }
  EXPECT_GT(symbolic.head<3>().norm(), 0.0);
  EXPECT_LT((radiance.tangent - symbolic).cwiseAbs().maxCoeff(),
            1e-13 * symbolic.cwiseAbs().maxCoeff());
}

// n = +z and w_i = +x: cos = 0 exactly. The light contributes nothing and every method except
// finite differences returns the zero subgradient; central differences straddle the kink and
// return the average of the two one-sided slopes.
TEST(BlinnPhongEdgeCaseTest, ExactlyGrazingLightHasZeroSubgradient) {
  Eigen::Matrix<double, Eigen::Dynamic, 3> lights(2, 3);
  lights << 1.0, 0.0, 0.0,  // Grazing.
      0.0, -0.6, 0.8;       // Lit, for contrast.
  const Eigen::Vector2d intensities(1.5, 1.0);
  const BlinnPhongPixel pixel(lights, intensities, Eigen::Vector3d::UnitZ(),
                              Eigen::Vector2d::Zero());
  const std::array<double, 6> x = {0.0, 0.0, 1.0, 0.5, 0.3, 10.0};

  for (const DerivativeMethod method :
       {DerivativeMethod::kForward, DerivativeMethod::kReverse, DerivativeMethod::kSymbolic}) {
    const Evaluation e = Evaluate(pixel, x.data(), method);
    ASSERT_TRUE(e.ok);
    EXPECT_EQ(e.residuals[0], 0.0) << ToString(method);
    EXPECT_EQ(e.jacobian.row(0), Eigen::RowVectorXd::Zero(6)) << ToString(method);
    EXPECT_GT(e.jacobian.row(1).norm(), 0.0) << ToString(method);
  }

  // From the lit side, dI/dm_x = L f_r (w_i . dn/dm_x) = L f_r with f_r at w_h = (1, 0, 1)/sqrt 2.
  const double k = (10.0 + 2.0) / (2.0 * std::numbers::pi);
  const double brdf = 0.5 / std::numbers::pi + 0.3 * k * std::pow(std::sqrt(0.5), 10.0);
  const Evaluation central = Evaluate(pixel, x.data(), DerivativeMethod::kCentralDifference);
  ASSERT_TRUE(central.ok);
  EXPECT_NEAR(central.jacobian(0, 0), 0.5 * 1.5 * brdf, 1e-6);
}

TEST(BlinnPhongEdgeCaseTest, LightBehindTheSurfaceHasZeroRow) {
  Eigen::Matrix<double, Eigen::Dynamic, 3> lights(1, 3);
  lights << 0.0, 0.6, -0.8;
  const BlinnPhongPixel pixel(lights, Eigen::VectorXd::Ones(1), Eigen::Vector3d::UnitZ(),
                              Eigen::VectorXd::Zero(1));
  const std::array<double, 6> x = {0.1, -0.2, 1.0, 0.5, 0.3, 10.0};
  for (const DerivativeMethod method : kAllMethods) {
    const Evaluation e = Evaluate(pixel, x.data(), method);
    ASSERT_TRUE(e.ok);
    EXPECT_EQ(e.jacobian.row(0), Eigen::RowVectorXd::Zero(6)) << ToString(method);
  }
}

// w_h . n == 0 exactly while the light is in front: the specular lobe sits at its clamp, where
// pow(0, e) must give finite, zero derivatives for any e > 0, including e < 1.
TEST(BlinnPhongEdgeCaseTest, HalfVectorPerpendicularToNormal) {
  Eigen::Matrix<double, Eigen::Dynamic, 3> lights(1, 3);
  lights << 0.0, 0.8, 0.6;
  const Eigen::Vector3d view(0.8, 0.0, -0.6);  // w_i + w_o = (0.8, 0.8, 0).
  const BlinnPhongPixel pixel(lights, Eigen::VectorXd::Ones(1), view, Eigen::VectorXd::Zero(1));
  ASSERT_EQ(pixel.half_vector(0).z(), 0.0);
  for (const double exponent : {0.5, 1.0, 2.5}) {
    const std::array<double, 6> x = {0.0, 0.0, 1.0, 0.5, 0.3, exponent};
    const Evaluation symbolic = Evaluate(pixel, x.data(), DerivativeMethod::kSymbolic);
    for (const DerivativeMethod method : {DerivativeMethod::kForward, DerivativeMethod::kReverse}) {
      const Evaluation e = Evaluate(pixel, x.data(), method);
      ASSERT_TRUE(e.ok);
      EXPECT_TRUE(e.jacobian.allFinite()) << ToString(method) << " e = " << exponent;
      EXPECT_EQ(e.jacobian(0, BlinnPhongPixel::kSpecularAlbedo), 0.0);
      EXPECT_EQ(e.jacobian(0, BlinnPhongPixel::kExponent), 0.0);
      EXPECT_LT((e.jacobian - symbolic.jacobian).cwiseAbs().maxCoeff(), 1e-15);
    }
  }
}

TEST(BlinnPhongEdgeCaseTest, DegenerateNormalFailsInsteadOfProducingNaN) {
  std::mt19937 rng(3);
  const RandomPixel random = MakeRandomPixel(8, rng);
  std::array<double, 6> x = random.parameters;
  x[0] = 1e-9;
  x[1] = -2e-9;
  x[2] = 0.0;
  for (const DerivativeMethod method : kAllMethods) {
    EXPECT_FALSE(Evaluate(random.pixel, x.data(), method).ok) << ToString(method);
  }
  std::vector<double> predicted(8);
  EXPECT_FALSE(random.pixel.Predict(x.data(), predicted.data()));
}

TEST(BlinnPhongTest, ResidualsAreScaleInvariantInTheNormal) {
  std::mt19937 rng(8);
  const RandomPixel random = MakeRandomPixel(10, rng);
  std::array<double, 6> scaled = random.parameters;
  for (int k = 0; k < 3; ++k) {
    scaled[k] *= 3.0;
  }
  const Evaluation a = Evaluate(random.pixel, random.parameters.data(), DerivativeMethod::kForward);
  const Evaluation b = Evaluate(random.pixel, scaled.data(), DerivativeMethod::kForward);
  EXPECT_LT((a.residuals - b.residuals).cwiseAbs().maxCoeff(), 1e-14);
  // The normal block of each row is orthogonal to the normal: rank 2, as documented.
  const Eigen::Vector3d m(random.parameters[0], random.parameters[1], random.parameters[2]);
  EXPECT_LT((a.jacobian.leftCols<3>() * m).cwiseAbs().maxCoeff(),
            1e-14 * a.jacobian.leftCols<3>().cwiseAbs().maxCoeff());
}

}  // namespace
}  // namespace photorig::solvers::autodiff
