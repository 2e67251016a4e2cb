// The solvers' opening checks: a refused Options or a named input problem
// ends the summary with the matching termination and message; anything else
// leaves it untouched.

#include "photorig/solvers/core/summary.h"

#include <gtest/gtest.h>

#include <string>

namespace photorig::solvers::core {
namespace {

struct FakeOptions {
  bool valid = true;
  bool IsValid(std::string* why) const {
    if (!valid) *why = "step must be positive";
    return valid;
  }
};

TEST(Refuse, SetsTheReasonWhenAskedAndReturnsFalse) {
  std::string why;
  EXPECT_FALSE(Refuse(&why, "step must be positive"));
  EXPECT_EQ(why, "step must be positive");
  EXPECT_FALSE(Refuse(nullptr, "nobody asked"));
}

TEST(EndIfInvalid, EndsWithTheOptionsReason) {
  Summary summary;
  EXPECT_TRUE(EndIfInvalid(FakeOptions{false}, &summary));
  EXPECT_EQ(summary.termination, Termination::kInvalidOptions);
  EXPECT_EQ(summary.message, "invalid options: step must be positive");
}

TEST(EndIfInvalid, LeavesValidOptionsAlone) {
  Summary summary;
  EXPECT_FALSE(EndIfInvalid(FakeOptions{}, &summary));
  EXPECT_EQ(summary.termination, Termination::kFailure);
  EXPECT_TRUE(summary.message.empty());
}

TEST(EndIfBadInput, EndsWithTheProblem) {
  Summary summary;
  EXPECT_TRUE(EndIfBadInput("mask size differs", &summary));
  EXPECT_EQ(summary.termination, Termination::kInvalidInput);
  EXPECT_EQ(summary.message, "mask size differs");
}

TEST(EndIfBadInput, LeavesNoProblemAlone) {
  Summary summary;
  EXPECT_FALSE(EndIfBadInput("", &summary));
  EXPECT_EQ(summary.termination, Termination::kFailure);
}

}  // namespace
}  // namespace photorig::solvers::core
