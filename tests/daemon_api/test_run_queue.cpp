// The persistent run queue: what the worker can see, and when, and who
// takes a run out of it.

#include "photorig/daemon/service/run_queue.h"
#include "test_support.h"

#include <gtest/gtest.h>
#include <sqlite3.h>

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

// The health check's count of waiting runs, without reading the runs.
TEST(RunQueue, CountsTheQueuedRunsAlone) {
  TempDir dir;
  RunQueue queue((dir.path() / "queue.db").string());
  EXPECT_EQ(queue.CountQueued(), 0);
  for (int i = 0; i < 3; ++i) queue.Add("ps-sphere", 49, [](const QueuedRun&) {});
  QueuedRun first = *queue.NextQueued();
  ASSERT_TRUE(queue.LeaveQueued(first, RunState::kRunning, ""));
  EXPECT_EQ(queue.CountQueued(), 2);
  bool older = true;
  EXPECT_EQ(queue.Page(5, "", &older).size(), 3u);
  EXPECT_FALSE(older);
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

// A run's solve stages are kept with it; a run that was solving when the
// daemon stopped is one to recover.
TEST(RunQueue, KeepsTheSolveAndCountsASolvingRunAsUnfinished) {
  TempDir dir;
  const std::string path = (dir.path() / "queue.db").string();
  std::string id;
  {
    RunQueue queue(path);
    QueuedRun run = queue.Add("ps-sphere", 49, nullptr);
    id = run.id;
    ASSERT_TRUE(queue.LeaveQueued(run, RunState::kRunning, ""));
    run.state = RunState::kSolving;
    run.solve = {{"ok", false}, {"stages", {{{"stage", "photometric_stereo"}, {"ok", false}}}}};
    queue.Update(run);
    ASSERT_EQ(queue.Unfinished().size(), 1u);
  }
  RunQueue reopened(path);
  const std::optional<QueuedRun> run = reopened.Get(id);
  ASSERT_TRUE(run);
  EXPECT_EQ(run->state, RunState::kSolving);
  EXPECT_EQ(run->solve["stages"][0]["stage"], "photometric_stereo");
  EXPECT_EQ(run->ToJson()["solve"]["ok"], false);
  EXPECT_FALSE(reopened.Add("no-solve-yet", 1, nullptr).ToJson().contains("solve"));
}

// A queue written before runs carried their solve gains the column on open.
TEST(RunQueue, OpensAQueueWithoutTheSolveColumn) {
  TempDir dir;
  const std::string path = (dir.path() / "queue.db").string();
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db,
                         "CREATE TABLE runs (seq INTEGER PRIMARY KEY AUTOINCREMENT, id TEXT UNIQUE NOT NULL, "
                         "recipe_name TEXT NOT NULL, state TEXT NOT NULL, reason TEXT NOT NULL DEFAULT '', "
                         "frames INTEGER NOT NULL DEFAULT 0, steps_total INTEGER NOT NULL DEFAULT 0, "
                         "retries INTEGER NOT NULL DEFAULT 0, dropped_frames INTEGER NOT NULL DEFAULT 0, "
                         "created_ns INTEGER NOT NULL, updated_ns INTEGER NOT NULL);"
                         "INSERT INTO runs (id, recipe_name, state, created_ns, updated_ns) "
                         "VALUES ('000001-old', 'old', 'done', 1, 1);",
                         nullptr, nullptr, nullptr),
            SQLITE_OK);
  sqlite3_close(db);
  RunQueue queue(path);
  std::optional<QueuedRun> old = queue.Get("000001-old");
  ASSERT_TRUE(old);
  EXPECT_EQ(old->state, RunState::kDone);
  EXPECT_TRUE(old->solve.is_null());
  old->solve = {{"ok", true}, {"stages", nlohmann::json::array()}};
  queue.Update(*old);
  EXPECT_EQ(queue.Get("000001-old")->solve["ok"], true);
}

}  // namespace
}  // namespace photorig::daemon
