#include "photorig/solvers/autodiff/dual.h"

#include <cmath>
#include <limits>
#include <random>

#include <ceres/jet.h>
#include <Eigen/Core>
#include <gtest/gtest.h>

#include "photorig/solvers/autodiff/finite_difference.h"
#include "photorig/solvers/autodiff/jacobian.h"
#include "photorig/solvers/autodiff/vector.h"
#include "test_util.h"

namespace photorig::solvers::autodiff {
namespace {

using testing::AllOperations;
using testing::ColumnRelativeError;

constexpr double kInf = std::numeric_limits<double>::infinity();

TEST(DualTest, AllOperationsMatchFiniteDifferencesAndJet) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> x_dist(0.5, 2.0);
  std::uniform_real_distribution<double> y_dist(-1.0, 1.0);
  const AllOperations f;
  for (int trial = 0; trial < 50; ++trial) {
    const double x[2] = {x_dist(rng), y_dist(rng)};
    Eigen::VectorXd value, fd_value;
    Eigen::MatrixXd jacobian, fd_jacobian;
    ASSERT_TRUE(ForwardJacobian<2>(f, x, &value, &jacobian));
    ASSERT_TRUE(FiniteDifferenceJacobian(f, x, {}, &fd_value, &fd_jacobian));
    EXPECT_LT((value - fd_value).cwiseAbs().maxCoeff(),
              1e-15 * (1.0 + value.cwiseAbs().maxCoeff()));
    EXPECT_LT(ColumnRelativeError(jacobian, fd_jacobian), 1e-7)
        << "x = " << x[0] << ", y = " << x[1];

    // ceres::Jet is the reference implementation of the same idea.
    using Jet = ceres::Jet<double, 2>;
    const Jet jet_in[2] = {Jet(x[0], 0), Jet(x[1], 1)};
    Jet jet_out[4];
    f(jet_in, jet_out);
    for (int i = 0; i < 4; ++i) {
      EXPECT_NEAR(jet_out[i].a, value[i], 1e-14 * std::abs(value[i]));
      for (int j = 0; j < 2; ++j) {
        EXPECT_NEAR(jet_out[i].v[j], jacobian(i, j), 1e-13 * std::abs(jacobian(i, j)) + 1e-15);
      }
    }
  }
}

TEST(DualTest, DynamicAndChunkedForwardMatchFixedSize) {
  const AllOperations f;
  const double x[2] = {1.3, -0.4};
  Eigen::VectorXd value_fixed, value_dynamic, value_chunked;
  Eigen::MatrixXd fixed, dynamic, chunked;
  ASSERT_TRUE(ForwardJacobian<2>(f, x, &value_fixed, &fixed));
  ASSERT_TRUE(ForwardJacobian<kDynamic>(f, x, &value_dynamic, &dynamic));
  ASSERT_TRUE(ForwardJacobian<1>(f, x, &value_chunked, &chunked));  // Two passes.
  EXPECT_EQ(value_fixed, value_dynamic);
  EXPECT_EQ(value_fixed, value_chunked);
  EXPECT_EQ(fixed, dynamic);
  EXPECT_EQ(fixed, chunked);
}

TEST(DualTest, DynamicConstantsHaveEmptyTangentsAndMixWithVariables) {
  const DynamicDual constant(3.0);
  const DynamicDual x(2.0, 1, 3);  // Input 1 of 3.
  EXPECT_EQ(constant.tangent.size(), 0);
  EXPECT_EQ((constant * constant).tangent.size(), 0);
  const DynamicDual y = constant * x + constant;
  EXPECT_DOUBLE_EQ(y.value, 9.0);
  ASSERT_EQ(y.tangent.size(), 3);
  EXPECT_EQ(y.tangent, Eigen::Vector3d(0.0, 3.0, 0.0));
  const DynamicDual z = constant / x - x / constant;
  EXPECT_DOUBLE_EQ(z.tangent[1], -3.0 / 4.0 - 1.0 / 3.0);
}

TEST(DualTest, EigenDotNormAndNormalizedMatchClosedForm) {
  using D = Dual<3>;
  const Eigen::Vector3d v(0.3, -1.2, 0.7);
  const Eigen::Matrix<D, 3, 1> vd(D(v.x(), 0), D(v.y(), 1), D(v.z(), 2));

  const D dot = vd.dot(vd);
  EXPECT_DOUBLE_EQ(dot.value, v.squaredNorm());
  EXPECT_TRUE(dot.tangent.isApprox(2.0 * v, 1e-15));

  const D norm = vd.norm();
  EXPECT_DOUBLE_EQ(norm.value, v.norm());
  EXPECT_TRUE(norm.tangent.isApprox(v / v.norm(), 1e-15));

  // d(v / |v|) / dv = (I - n n^T) / |v|; column j of it is the tangent w.r.t. input j.
  const Eigen::Matrix<D, 3, 1> n = vd.normalized();
  const Eigen::Vector3d unit = v.normalized();
  const Eigen::Matrix3d expected =
      (Eigen::Matrix3d::Identity() - unit * unit.transpose()) / v.norm();
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(n[i].value, unit[i], 1e-16);
    EXPECT_TRUE(n[i].tangent.isApprox(expected.row(i).transpose(), 1e-14));
  }

  // Mixed double/Dual products use the scalar-times-Dual operators.
  const Eigen::Vector3d w(1.0, 2.0, 4.0);
  const D mixed = w.dot(vd);
  EXPECT_NEAR(mixed.value, w.dot(v), 1e-15);
  EXPECT_EQ(mixed.tangent, w);
}

TEST(DualEdgeCaseTest, PowAtZeroBase) {
  using D = Dual<2>;
  const D zero(0.0, 0);  // Seeded in component 0; component 1 is another input.

  const D steep = pow(zero, 2.5);  // e > 1: derivative 0, not NaN.
  EXPECT_EQ(steep.value, 0.0);
  EXPECT_EQ(steep.tangent, Eigen::Vector2d(0.0, 0.0));

  const D linear = pow(zero, 1.0);  // e == 1: derivative 1.
  EXPECT_EQ(linear.tangent, Eigen::Vector2d(1.0, 0.0));

  const D root = pow(zero, 0.5);  // 0 < e < 1: the slope is unbounded.
  EXPECT_EQ(root.tangent[0], kInf);
  EXPECT_EQ(root.tangent[1], 0.0) << "an input the base does not depend on must stay 0";

  const D constant_one = pow(zero, 0.0);  // x^0 == 1 everywhere.
  EXPECT_EQ(constant_one.value, 1.0);
  EXPECT_EQ(constant_one.tangent, Eigen::Vector2d(0.0, 0.0));

  // Both variable: d/de x^e = x^e log x -> 0 as x -> 0 for e > 0 (not 0 * -inf = NaN).
  const D both = pow(zero, D(2.5, 1));
  EXPECT_EQ(both.value, 0.0);
  EXPECT_EQ(both.tangent, Eigen::Vector2d(0.0, 0.0));

  // A negative base with a constant integer exponent is fine.
  const D negative = pow(D(-2.0, 0), 3.0);
  EXPECT_EQ(negative.value, -8.0);
  EXPECT_EQ(negative.tangent[0], 12.0);
}

TEST(DualEdgeCaseTest, SqrtAtZeroOnlyAffectsDependentComponents) {
  using D = Dual<2>;
  const D root = sqrt(D(0.0, 0));
  EXPECT_EQ(root.value, 0.0);
  EXPECT_EQ(root.tangent[0], kInf);
  EXPECT_EQ(root.tangent[1], 0.0);
  // ceres::Jet multiplies the whole tangent by inf: the unrelated component becomes NaN.
  const ceres::Jet<double, 2> jet_root = sqrt(ceres::Jet<double, 2>(0.0, 0));
  EXPECT_TRUE(std::isnan(jet_root.v[1]));
}

TEST(DualEdgeCaseTest, SelectionTiesAndKinks) {
  using D = Dual<1>;
  const D at_zero(0.0, 0);
  // max(0, c) at c == 0 returns the constant: the zero subgradient of a clamp.
  EXPECT_EQ(max(D(0.0), at_zero).tangent[0], 0.0);
  // Ties return the first argument, as std::max does.
  EXPECT_EQ(max(at_zero, D(0.0)).tangent[0], 1.0);
  EXPECT_EQ(min(at_zero, D(0.0)).tangent[0], 1.0);
  // Past the clamp the derivative is 0; inside, 1; clamp at its bound returns x.
  EXPECT_EQ(max(D(0.0), D(-1e-300, 0)).tangent[0], 0.0);
  EXPECT_EQ(max(D(0.0), D(1e-300, 0)).tangent[0], 1.0);
  EXPECT_EQ(clamp(D(1.0, 0), D(0.0), D(1.0)).tangent[0], 1.0);
  EXPECT_EQ(clamp(D(1.5, 0), D(0.0), D(1.0)).tangent[0], 0.0);
  // abs at 0 and atan2 at the origin: zero partials, not NaN.
  EXPECT_EQ(abs(at_zero).tangent[0], 0.0);
  const D angle = atan2(at_zero, D(0.0, 0));
  EXPECT_EQ(angle.value, 0.0);
  EXPECT_EQ(angle.tangent[0], 0.0);
}

TEST(NormalizeGuardedTest, FlagsNearZeroVectorsInsteadOfReturningNaN) {
  using D = Dual<3>;
  const auto seeded = [](const Eigen::Vector3d& v) {
    return Eigen::Matrix<D, 3, 1>(D(v.x(), 0), D(v.y(), 1), D(v.z(), 2));
  };

  const auto ok = NormalizeGuarded(seeded(Eigen::Vector3d(0.0, 3.0, 4.0)));
  EXPECT_TRUE(ok.valid);
  EXPECT_DOUBLE_EQ(ok.direction[2].value, 0.8);

  for (const double scale : {1e-9, 1e-200, 0.0}) {
    const auto tiny = NormalizeGuarded(seeded(scale * Eigen::Vector3d(1.0, -1.0, 2.0)));
    EXPECT_FALSE(tiny.valid) << scale;
    for (int i = 0; i < 3; ++i) {
      EXPECT_EQ(tiny.direction[i].value, 0.0);
      EXPECT_EQ(tiny.direction[i].tangent, Eigen::Vector3d::Zero());
    }
  }

  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(NormalizeGuarded(Eigen::Vector3d(nan, 0.0, 1.0)).valid);
  EXPECT_TRUE(NormalizeGuarded(Eigen::Vector3d(2e-8, 0.0, 0.0)).valid);
}

TEST(NormalizeGuardedTest, DocumentsWhatPlainEigenDoesNearZero) {
  using D = Dual<3>;
  // Exactly zero: Eigen returns the input unchanged, a zero "direction" with its tangent.
  const Eigen::Matrix<D, 3, 1> zero(D(0.0, 0), D(0.0, 1), D(0.0, 2));
  const Eigen::Matrix<D, 3, 1> n = zero.normalized();
  EXPECT_EQ(n[0].value, 0.0);
  EXPECT_EQ(n[0].tangent, Eigen::Vector3d(1.0, 0.0, 0.0));
  // norm() of the zero vector: value 0 and, by the tangent masking of sqrt, derivative 0.
  const D length = zero.norm();
  EXPECT_EQ(length.value, 0.0);
  EXPECT_EQ(length.tangent, Eigen::Vector3d::Zero());
  // Below ~1e-154 the squared norm underflows and Eigen hands back a non-unit vector.
  const Eigen::Matrix<D, 3, 1> tiny(D(1e-170, 0), D(0.0, 1), D(0.0, 2));
  EXPECT_EQ(tiny.normalized()[0].value, 1e-170);
}

}  // namespace
}  // namespace photorig::solvers::autodiff
