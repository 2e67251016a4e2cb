// The progress throttle: about a hundred reports per stage however many units
// it has, always one at the end, and nothing when no callback is set.

#include "photorig/solvers/core/progress.h"

#include <gtest/gtest.h>

#include <vector>

namespace photorig::solvers::core {
namespace {

std::vector<Progress> ReportsFor(std::int64_t total) {
  std::vector<Progress> seen;
  const ProgressCallback callback = [&seen](const Progress& p) { seen.push_back(p); };
  ProgressThrottle throttle(callback, "stage", total);
  for (std::int64_t done = 0; done < total; ++done) throttle.Update(done);
  throttle.Finish();
  return seen;
}

TEST(ProgressThrottle, ReportsAboutEveryPercentAndOnceAtTheEnd) {
  const std::vector<Progress> seen = ReportsFor(100000);
  ASSERT_GE(seen.size(), 100u);
  EXPECT_LE(seen.size(), 102u);
  EXPECT_EQ(seen.back().done, 100000);
  EXPECT_EQ(seen.back().total, 100000);
  EXPECT_EQ(seen.back().stage, "stage");
  for (std::size_t i = 1; i < seen.size(); ++i) EXPECT_GT(seen[i].done, seen[i - 1].done);
}

TEST(ProgressThrottle, FewUnitsReportEachAndTheEndOnce) {
  const std::vector<Progress> seen = ReportsFor(3);
  ASSERT_EQ(seen.size(), 4u);  // 0, 1, 2, then 3 of 3
  EXPECT_EQ(seen.back().done, 3);
}

TEST(ProgressThrottle, WithoutACallbackNothingIsCalled) {
  const ProgressCallback none;
  ProgressThrottle throttle(none, "stage", 10);
  throttle.Update(5);
  throttle.Finish();  // must not call an empty std::function
  SUCCEED();
}

}  // namespace
}  // namespace photorig::solvers::core
