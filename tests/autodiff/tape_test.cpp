#include "photorig/solvers/autodiff/tape.h"

#include <cmath>
#include <limits>
#include <random>
#include <string>

#include <Eigen/Core>
#include <gtest/gtest.h>

#include "photorig/solvers/autodiff/jacobian.h"
#include "test_util.h"

namespace photorig::solvers::autodiff {
namespace {

using testing::AllOperations;
using testing::ColumnRelativeError;

TEST(TapeTest, ReverseJacobianMatchesForwardOnAllOperations) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> x_dist(0.5, 2.0);
  std::uniform_real_distribution<double> y_dist(-1.0, 1.0);
  const AllOperations f;
  Tape tape;
  for (int trial = 0; trial < 50; ++trial) {
    const double x[2] = {x_dist(rng), y_dist(rng)};
    Eigen::VectorXd forward_value, reverse_value;
    Eigen::MatrixXd forward, reverse;
    ASSERT_TRUE(ForwardJacobian<2>(f, x, &forward_value, &forward));
    ASSERT_TRUE(ReverseJacobian(f, x, &tape, &reverse_value, &reverse));
    EXPECT_EQ(forward_value, reverse_value);
    EXPECT_LT(ColumnRelativeError(reverse, forward), 1e-14);
  }
}

TEST(TapeTest, ResetKeepsMemoryAndReusedTapeGivesFreshGradients) {
  Tape tape(Tape::Options{.initial_capacity = 64});
  const auto gradient_at = [&tape](double a, double b) {
    tape.Reset();
    const Var x = tape.Variable(a);
    const Var y = tape.Variable(b);
    const Var f = x * x * y + sin(y);
    tape.Backward(f);
    return Eigen::Vector2d(tape.Adjoint(x), tape.Adjoint(y));
  };
  const Eigen::Vector2d first = gradient_at(1.5, 0.5);
  EXPECT_DOUBLE_EQ(first.x(), 2.0 * 1.5 * 0.5);
  EXPECT_DOUBLE_EQ(first.y(), 1.5 * 1.5 + std::cos(0.5));
  const std::size_t nodes = tape.size();
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector2d again = gradient_at(-2.0, 3.0);
    EXPECT_DOUBLE_EQ(again.x(), 2.0 * -2.0 * 3.0);
    EXPECT_DOUBLE_EQ(again.y(), 4.0 + std::cos(3.0));
    EXPECT_EQ(tape.size(), nodes);
    EXPECT_EQ(tape.capacity(), 64u);
  }
  tape.Reset();
  EXPECT_EQ(tape.size(), 1u);  // Only the constant sink.
  EXPECT_EQ(tape.capacity(), 64u);
}

TEST(TapeTest, ArenaGrowsPastItsInitialCapacity) {
  Tape tape(Tape::Options{.initial_capacity = 4});
  const Var x = tape.Variable(1.0001);
  Var product = x;
  for (int i = 1; i < 1000; ++i) {
    product *= x;
  }
  EXPECT_GE(tape.capacity(), tape.size());
  EXPECT_EQ(tape.size(), 1u + 1u + 999u);
  tape.Backward(product);
  const double expected = 1000.0 * std::pow(1.0001, 999.0);
  EXPECT_NEAR(tape.Adjoint(x), expected, 1e-12 * expected);
}

TEST(TapeTest, InvalidOptionsAreRefusedNamingTheField) {
  std::string why;
  EXPECT_TRUE(TapeOptions{}.IsValid(&why));
  EXPECT_FALSE((TapeOptions{.initial_capacity = 0}).IsValid(&why));
  EXPECT_NE(why.find("initial_capacity"), std::string::npos) << why;
  EXPECT_FALSE((TapeOptions{.initial_capacity = 64, .max_nodes = 32}).IsValid(&why));
  EXPECT_NE(why.find("initial_capacity"), std::string::npos) << why;
  EXPECT_FALSE((TapeOptions{.max_nodes = kMaxTapeNodes + 1}).IsValid(&why));
  EXPECT_NE(why.find("max_nodes"), std::string::npos) << why;

  // A tape made with them records nothing, says why, and ReverseJacobian refuses it.
  Tape tape(TapeOptions{.initial_capacity = 0});
  EXPECT_FALSE(tape.ok());
  EXPECT_NE(tape.error().find("initial_capacity"), std::string::npos) << tape.error();
  EXPECT_TRUE(tape.Variable(2.0).is_constant());
  const double x[2] = {1.2, 0.4};
  Eigen::VectorXd value;
  Eigen::MatrixXd jacobian;
  EXPECT_FALSE(ReverseJacobian(AllOperations(), x, &tape, &value, &jacobian));
}

TEST(TapeTest, RecordingPastMaxNodesFailsAndResetRecordsAgain) {
  Tape tape(TapeOptions{.initial_capacity = 4, .max_nodes = 16});
  const Var x = tape.Variable(1.0001);
  Var product = x;
  for (int i = 1; i < 100; ++i) {
    product *= x;
  }
  EXPECT_FALSE(tape.ok());
  EXPECT_NE(tape.error().find("max_nodes = 16"), std::string::npos) << tape.error();
  EXPECT_EQ(tape.size(), 16u);
  EXPECT_EQ(tape.capacity(), 16u);
  const double at[2] = {1.2, 0.4};
  Eigen::VectorXd value;
  Eigen::MatrixXd jacobian;
  EXPECT_FALSE(ReverseJacobian(AllOperations(), at, &tape, &value, &jacobian));  // needs more than 16

  tape.Reset();
  EXPECT_TRUE(tape.ok());
  EXPECT_TRUE(tape.error().empty());
  const Var y = tape.Variable(3.0);
  tape.Backward(y * y);
  EXPECT_EQ(tape.Adjoint(y), 6.0);
}

TEST(TapeTest, OperationsOnConstantsAreNotRecorded) {
  Tape tape;
  const Var x = tape.Variable(2.0);
  const std::size_t before = tape.size();
  const Var c = sqrt(Var(4.0)) * Var(3.0) + 1.0;
  EXPECT_TRUE(c.is_constant());
  EXPECT_EQ(c.value(), 7.0);
  EXPECT_EQ(tape.size(), before);
  const Var f = c * x;
  EXPECT_FALSE(f.is_constant());
  tape.Backward(f);
  EXPECT_EQ(tape.Adjoint(x), 7.0);
  EXPECT_EQ(tape.Adjoint(c), 0.0);

  tape.Backward(c);  // A constant output: no dependence on anything.
  EXPECT_EQ(tape.Adjoint(x), 0.0);
}

TEST(TapeTest, InfinitePartialOnlyReachesInputsItDependsOn) {
  Tape tape;
  const Var x = tape.Variable(0.0);
  const Var y = tape.Variable(2.0);
  tape.Backward(sqrt(x) + y);
  EXPECT_EQ(tape.Adjoint(x), std::numeric_limits<double>::infinity());
  EXPECT_EQ(tape.Adjoint(y), 1.0);
  // sqrt(x) recorded but unused by the output: its infinite partial never runs.
  [[maybe_unused]] const Var unused = sqrt(x);
  tape.Backward(y * y);
  EXPECT_EQ(tape.Adjoint(x), 0.0);
  EXPECT_EQ(tape.Adjoint(y), 4.0);
}

TEST(TapeTest, EdgeCasesMatchForwardMode) {
  Tape tape;
  const Var zero = tape.Variable(0.0);
  const Var exponent = tape.Variable(2.5);
  const Var power = pow(zero, exponent);
  tape.Backward(power);
  EXPECT_EQ(tape.Adjoint(zero), 0.0);
  EXPECT_EQ(tape.Adjoint(exponent), 0.0);

  tape.Backward(max(Var(0.0), zero));  // Tie: the constant, derivative 0.
  EXPECT_EQ(tape.Adjoint(zero), 0.0);
  tape.Backward(max(zero, Var(0.0)));  // Tie: the first argument passes through.
  EXPECT_EQ(tape.Adjoint(zero), 1.0);
}

TEST(TapeTest, EigenVectorsOfVars) {
  Tape tape;
  const Eigen::Vector3d v(0.3, -1.2, 0.7);
  Eigen::Matrix<Var, 3, 1> vv;
  for (int i = 0; i < 3; ++i) {
    vv[i] = tape.Variable(v[i]);
  }
  const Var norm = vv.norm();
  tape.Backward(norm);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(tape.Adjoint(vv[i]), v[i] / v.norm(), 1e-16);
  }
  const Var mixed = Eigen::Vector3d(1.0, 2.0, 3.0).dot(vv);
  tape.Backward(mixed);
  EXPECT_EQ(tape.Adjoint(vv[2]), 3.0);
}

}  // namespace
}  // namespace photorig::solvers::autodiff
