#pragma once
// The output of a solver operation that a test needs to succeed:
//   const cv::Mat image = OutputOf<cv::Mat>([&](cv::Mat* out) { return RenderShLighting(n, a, sh, out); });
// A termination other than kSuccess fails the test with the solver's message.

#include "photorig/solvers/core/summary.h"

#include <gtest/gtest.h>

namespace photorig::solvers::lighting::testing {

template <typename Output, typename Operation>
Output OutputOf(Operation operation) {
  Output output{};
  const solvers::core::Summary summary = operation(&output);
  EXPECT_EQ(summary.termination, solvers::core::Termination::kSuccess) << summary.message;
  return output;
}

}  // namespace photorig::solvers::lighting::testing
