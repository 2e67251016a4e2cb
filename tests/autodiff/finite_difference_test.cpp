#include "photorig/solvers/autodiff/finite_difference.h"

#include <cmath>
#include <limits>

#include <Eigen/Core>
#include <gtest/gtest.h>

namespace photorig::solvers::autodiff {
namespace {

constexpr double kEpsilon = std::numeric_limits<double>::epsilon();

// f(x) = exp(x) sin(3x): f, f'' and f''' are of order 1 to 30 on [-1, 1].
struct Wave {
  int num_inputs() const { return 1; }
  int num_outputs() const { return 1; }
  template <typename T>
  bool operator()(const T* x, T* y) const {
    y[0] = std::exp(x[0]) * std::sin(3.0 * x[0]);
    return true;
  }
  static double Derivative(double x) {
    return std::exp(x) * (std::sin(3.0 * x) + 3.0 * std::cos(3.0 * x));
  }
};

double MaxError(DifferenceScheme scheme, double relative_step) {
  const Wave f;
  double worst = 0.0;
  for (double x = -1.0; x <= 1.0; x += 0.05) {
    Eigen::VectorXd value;
    Eigen::MatrixXd jacobian;
    EXPECT_TRUE(FiniteDifferenceJacobian(
        f, &x, FiniteDifferenceOptions{.scheme = scheme, .relative_step = relative_step}, &value,
        &jacobian));
    worst = std::max(worst, std::abs(jacobian(0, 0) - Wave::Derivative(x)));
  }
  return worst;
}

TEST(FiniteDifferenceTest, DefaultStepsAreSqrtAndCbrtOfEpsilon) {
  EXPECT_EQ(DefaultRelativeStep(DifferenceScheme::kForward), std::sqrt(kEpsilon));
  EXPECT_EQ(DefaultRelativeStep(DifferenceScheme::kCentral), std::cbrt(kEpsilon));
}

TEST(FiniteDifferenceTest, ErrorsAtDefaultStepsAreAsPredicted) {
  const double forward = MaxError(DifferenceScheme::kForward, 0.0);
  const double central = MaxError(DifferenceScheme::kCentral, 0.0);
  // Scale of f, f'', f''' here is ~30: forward ~ sqrt(eps), central ~ eps^(2/3), times that.
  EXPECT_LT(forward, 30.0 * std::sqrt(kEpsilon));
  EXPECT_LT(central, 30.0 * std::pow(kEpsilon, 2.0 / 3.0));
  EXPECT_LT(central, forward / 100.0);
}

TEST(FiniteDifferenceTest, ErrorIsVShapedInTheStep) {
  for (const DifferenceScheme scheme : {DifferenceScheme::kForward, DifferenceScheme::kCentral}) {
    const double best = MaxError(scheme, 0.0);
    EXPECT_LT(10.0 * best, MaxError(scheme, 1e-3)) << "truncation side";
    EXPECT_LT(10.0 * best, MaxError(scheme, 1e-13)) << "rounding side";
  }
}

TEST(FiniteDifferenceTest, StepIsRelativeForLargeInputs) {
  struct Square {
    int num_inputs() const { return 1; }
    int num_outputs() const { return 1; }
    bool operator()(const double* x, double* y) const {
      y[0] = x[0] * x[0];
      return true;
    }
  };
  const double x = 1e6;
  Eigen::VectorXd value;
  Eigen::MatrixXd jacobian;
  ASSERT_TRUE(FiniteDifferenceJacobian(Square(), &x, {}, &value, &jacobian));
  // An absolute step of cbrt(eps) would leave an error of ~eps x^2 / h ~ 40 here.
  EXPECT_NEAR(jacobian(0, 0), 2e6, 1e-9 * 2e6);
  // A negative step is not a step: refused before any evaluation.
  FiniteDifferenceOptions negative;
  negative.relative_step = -1e-6;
  std::string why;
  EXPECT_FALSE(negative.IsValid(&why));
  EXPECT_NE(why.find("relative_step"), std::string::npos);
  EXPECT_FALSE(FiniteDifferenceJacobian(Square(), &x, negative, &value, &jacobian));
}

TEST(FiniteDifferenceTest, FailedEvaluationIsReported) {
  struct PositiveOnly {
    int num_inputs() const { return 1; }
    int num_outputs() const { return 1; }
    bool operator()(const double* x, double* y) const {
      y[0] = std::sqrt(x[0]);
      return x[0] > 0.0;
    }
  };
  Eigen::VectorXd value;
  Eigen::MatrixXd jacobian;
  const double inside = 1.0;
  const double at_edge = 1e-9;  // The backward step of a central difference leaves the domain.
  EXPECT_TRUE(FiniteDifferenceJacobian(PositiveOnly(), &inside, {}, &value, &jacobian));
  EXPECT_FALSE(FiniteDifferenceJacobian(PositiveOnly(), &at_edge, {}, &value, &jacobian));
  EXPECT_TRUE(FiniteDifferenceJacobian(
      PositiveOnly(), &at_edge, FiniteDifferenceOptions{.scheme = DifferenceScheme::kForward},
      &value, &jacobian));
}

}  // namespace
}  // namespace photorig::solvers::autodiff
