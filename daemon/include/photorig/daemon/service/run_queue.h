#pragma once
// The daemon's persistent run queue: one SQLite row per submitted run, so
// queued and interrupted runs survive a restart (or a kill -9). Writes are
// synchronous (WAL, synchronous=FULL); the run directory stays the authority
// on frames, the queue on what the daemon is asked to do next.

#include "photorig/daemon/capture/run_control.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

struct sqlite3;

namespace photorig::daemon {

struct QueuedRun {
  std::string id;            // "000042-ps-sphere": sequence number and recipe name, safe as a file name
  std::string recipe_name;
  RunState state = RunState::kQueued;
  std::string reason;
  int frames = 0;
  int steps_total = 0;
  int retries = 0;
  int dropped_frames = 0;
  std::int64_t created_ns = 0;  // CLOCK_REALTIME
  std::int64_t updated_ns = 0;
  // The solve stages' outcome once they ran: {"ok", "stages": [SolveStageReport...]}; null before.
  nlohmann::json solve;

  nlohmann::json ToJson() const;  // "solve" only when set
};

class RunQueue {
 public:
  // Opens or creates the database. On a full disk, where SQLite cannot make
  // its write-ahead log, an existing queue opens read-only as it was last
  // checkpointed; every write then tries to open it writable again, and
  // throws naming the file while it cannot. Throws std::runtime_error naming
  // the file when it cannot be opened at all.
  explicit RunQueue(const std::string& path);
  ~RunQueue();
  RunQueue(const RunQueue&) = delete;
  RunQueue& operator=(const RunQueue&) = delete;

  // Adds a queued run. `prepare` runs with the new run (its id assigned)
  // before the row is committed, so before NextQueued can return it: the
  // daemon writes the run's recipe there. If it throws, nothing is added.
  QueuedRun Add(const std::string& recipe_name, int steps_total,
                const std::function<void(const QueuedRun&)>& prepare);
  std::optional<QueuedRun> Get(const std::string& id) const;
  std::vector<QueuedRun> List() const;  // oldest first
  // The `limit` newest runs added before run `before_id` (before none: the
  // newest of all), oldest first; *older: whether older runs remain. A
  // client pages back through years of runs without the daemon reading them all.
  std::vector<QueuedRun> Page(int limit, const std::string& before_id, bool* older) const;
  int CountQueued() const;
  std::optional<QueuedRun> NextQueued() const;
  std::vector<QueuedRun> Unfinished() const;  // neither queued nor final: a run the daemon was executing
  void Update(const QueuedRun& run);          // state, reason, counters and solve
  // Moves the run from kQueued to `to` if it is still queued, in one
  // statement, and updates `run`; false (and `run` untouched) otherwise. The
  // worker claims a run and Abort cancels one this way, so a run is either
  // started or aborted, never both.
  bool LeaveQueued(QueuedRun& run, RunState to, const std::string& reason);
  // Why the queue is read-only (a full disk); empty while it is writable.
  // Tries to make it writable first.
  std::string ReadOnlyReason();

 private:
  // Opens db_ writable and readies the table; false (db_ closed, `why` set) when it cannot.
  bool OpenWritable(std::string* why);
  void OpenReadOnly(const std::string& why_not_writable);
  void MakeWritable();  // mutex_ held; throws while the queue stays read-only
  void Exec(const std::string& sql) const;
  std::vector<QueuedRun> Select(const std::string& where, const std::string& text_argument,
                                const std::string& order = "ORDER BY seq") const;

  std::string path_;
  sqlite3* db_ = nullptr;
  std::string read_only_reason_;  // empty while writable
  mutable std::mutex mutex_;
};

}  // namespace photorig::daemon
