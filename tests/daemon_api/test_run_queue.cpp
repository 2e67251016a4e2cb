// The persistent run queue: what the worker can see, and when, and who
// takes a run out of it.

#include "photorig/daemon/run_queue.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <stdexcept>

namespace photorig::daemon {
namespace {

using photorig::testing::TempDir;

// The daemon writes a run's recipe while adding it; a worker asking for the
// next run in the meantime must wait, not start a run whose recipe is not on
// disk yet.
TEST(RunQueue, ARunStaysHiddenUntilItsPreparationIsDone) {
  TempDir dir;
  RunQueue queue((dir.path() / "queue.db").string());
  std::future<std::optional<QueuedRun>> seen;
  std::string prepared_id;
  const QueuedRun run = queue.Add("ps-sphere", 49, [&](const QueuedRun& added) {
    prepared_id = added.id;
    seen = std::async(std::launch::async, [&queue] { return queue.NextQueued(); });
    EXPECT_EQ(seen.wait_for(std::chrono::milliseconds(200)), std::future_status::timeout);
  });
  EXPECT_EQ(run.id, prepared_id);
  const std::optional<QueuedRun> next = seen.get();
  ASSERT_TRUE(next);
  EXPECT_EQ(next->id, run.id);
  EXPECT_EQ(next->state, RunState::kQueued);
  EXPECT_EQ(next->steps_total, 49);
}

TEST(RunQueue, AFailedPreparationAddsNothing) {
  TempDir dir;
  RunQueue queue((dir.path() / "queue.db").string());
  EXPECT_THROW(queue.Add("ps-sphere", 49, [](const QueuedRun&) { throw std::runtime_error("disk full"); }),
               std::runtime_error);
  EXPECT_TRUE(queue.List().empty());
  EXPECT_FALSE(queue.NextQueued());
  const QueuedRun run = queue.Add("ps-sphere", 49, [](const QueuedRun&) {});
  EXPECT_EQ(queue.List().size(), 1u);
  EXPECT_EQ(queue.NextQueued()->id, run.id);
}

// The worker claims a queued run and Abort cancels one with the same
// conditional transition: whichever comes second finds the run gone from the
// queue and changes nothing.
TEST(RunQueue, ARunLeavesTheQueueOnlyOnce) {
  TempDir dir;
  RunQueue queue((dir.path() / "queue.db").string());
  const QueuedRun first = queue.Add("claimed-first", 1, nullptr), second = queue.Add("aborted-first", 1, nullptr);

  QueuedRun worker = first, aborter = first;
  ASSERT_TRUE(queue.LeaveQueued(worker, RunState::kRunning, ""));
  EXPECT_EQ(worker.state, RunState::kRunning);
  EXPECT_FALSE(queue.LeaveQueued(aborter, RunState::kAborted, "aborted before it started"));
  EXPECT_EQ(aborter.state, RunState::kQueued);  // untouched
  EXPECT_EQ(queue.Get(first.id)->state, RunState::kRunning);

  aborter = worker = second;
  ASSERT_TRUE(queue.LeaveQueued(aborter, RunState::kAborted, "aborted before it started"));
  EXPECT_FALSE(queue.LeaveQueued(worker, RunState::kRunning, ""));
  EXPECT_EQ(queue.Get(second.id)->state, RunState::kAborted);
  EXPECT_EQ(queue.Get(second.id)->reason, "aborted before it started");
  EXPECT_FALSE(queue.NextQueued());
}

}  // namespace
}  // namespace photorig::daemon
