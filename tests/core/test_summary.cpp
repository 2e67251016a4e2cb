// The solvers' opening checks: a refused Options or a named input problem
// ends the summary with the matching termination and message; anything else
// leaves it untouched.

#include "photorig/solvers/core/summary.h"
#include "photorig/solvers/core/summary_json.h"

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

TEST(Summary, BriefReportSaysHowItEndedAndHowLongItTook) {
  Summary summary;
  summary.termination = Termination::kNoConvergence;
  summary.setup_ms = 0.27, summary.solve_ms = 12.04, summary.total_ms = 12.31;
  EXPECT_EQ(summary.BriefReport(), "no-convergence, 12.3 ms (setup 0.3 ms)");
  summary.message = "iteration limit (50) reached";
  EXPECT_EQ(summary.BriefReport(), "no-convergence, 12.3 ms (setup 0.3 ms): iteration limit (50) reached");
}

TEST(Summary, ToJsonCarriesTheTerminationMessageAndTimings) {
  Summary summary;
  summary.End(Termination::kInvalidInput, "images of two sizes");
  summary.setup_ms = 1.5, summary.solve_ms = 0.0, summary.total_ms = 1.5;
  const nlohmann::json json = ToJson(summary);
  EXPECT_EQ(json.at("termination"), "invalid-input");
  EXPECT_EQ(json.at("message"), "images of two sizes");
  EXPECT_EQ(json.at("timings_ms").at("setup"), 1.5);
  EXPECT_EQ(json.at("timings_ms").at("solve"), 0.0);
  EXPECT_EQ(json.at("timings_ms").at("total"), 1.5);
}

}  // namespace
}  // namespace photorig::solvers::core
