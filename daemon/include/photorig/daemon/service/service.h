#pragma once
// The daemon's core, independent of the transport: a persistent queue of
// submitted recipes, one worker that executes them on the rig one at a time,
// pause/resume/abort, progress events, and recovery of the run a crash
// interrupted. The HTTP API (api_server.h) is a thin layer over this.
//
// Data root layout:
//   queue.sqlite         the persistent queue (run_queue.h)
//   recipes/<id>.yaml    the recipe text as submitted
//   runs/<id>/           the run directory (run_store.h)

#include "photorig/daemon/capture/plan.h"
#include "photorig/daemon/service/rig_cache.h"
#include "photorig/daemon/service/run_queue.h"
#include "photorig/daemon/capture/sequencer.h"

#include <nlohmann/json.hpp>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace photorig::daemon {

struct ServiceOptions {
  std::string data_root;                 // required; created if missing
  std::string rig_path;                  // required: the rig this daemon drives
  bool resume_interrupted = true;        // false: mark runs a crash interrupted as "interrupted"
  bool solve = true;                     // run the recipe's solve: stages after a complete capture
  std::size_t max_recipe_bytes = 256 * 1024;
  // What one recipe may expand to (frames, bytes, duration); beyond it
  // dry-run and submit answer 413. Its step_overhead_ms is plan.step_overhead_ms.
  config::CaptureLimits limits;
  std::size_t max_listed_steps = 10000;  // steps listed in a dry-run or submit answer
  // Memory the plans of concurrent dry-runs and submits may hold at once
  // (PlanMemoryBudget); a request that finds it spent for plan_wait_ms
  // answers 503 with Retry-After.
  std::uint64_t plan_memory_bytes = std::uint64_t{512} << 20;
  int plan_wait_ms = 2000;
  RetryPolicy retry;
  PlanOptions plan;
  // Folders whose *.yaml recipes GET /recipes lists besides <data_root>/recipes
  // (photorigd: the recipes folder beside the rig's folder, e.g. config/recipes).
  std::vector<std::string> recipe_folders;

  bool IsValid(std::string* why) const;
};

struct RunEvent {
  std::uint64_t seq = 0;  // per service, increasing
  std::string run_id;
  std::string type;       // state | frame | solve_started | solve_finished | stop
  nlohmann::json data;
};

// The outcome of a request, with the HTTP status that describes it.
struct ServiceReply {
  int http_status = 200;
  nlohmann::json body;
  int retry_after_s = 0;  // > 0: try again after this many seconds (the Retry-After header)
  // Plan memory reserved for as long as the body lives (PlanMemoryBudget).
  std::shared_ptr<const void> holds = nullptr;
};

// The "stop" event's data for a run record (RunService::GetRun's body): how
// it ended, its counters, its solve stages and where its results are.
nlohmann::json StopEventData(const nlohmann::json& run);

class RunService {
 public:
  // Throws std::runtime_error for invalid options or an unusable data root.
  explicit RunService(ServiceOptions options);
  ~RunService();
  RunService(const RunService&) = delete;
  RunService& operator=(const RunService&) = delete;

  // Recovers runs a crash interrupted, then starts the worker.
  void Start();
  // Graceful stop: the current run finishes its frame, switches the lights off
  // and stays queued for the next start. Idempotent.
  void Stop();
  bool Healthy() const;

  // `name` names the recipe in messages; `recipe_path`, when the client
  // gives one, is where it read the recipe, so a relative `recipe.rig`
  // resolves from its folder (see RigMismatch in service.cpp).
  ServiceReply Submit(const std::string& name, const std::string& recipe_yaml, const std::string& recipe_path = "");
  ServiceReply DryRun(const std::string& name, const std::string& recipe_yaml,
                      const std::string& recipe_path = "") const;
  // A page of the run history: the `limit` newest runs before run `before`
  // ("": the newest), oldest first: {"runs", "older"} and, while older runs
  // remain, "before", the cursor of the next page back.
  static constexpr int kRunsPerPage = 200, kMaxRunsPerPage = 1000;
  ServiceReply ListRuns(int limit = kRunsPerPage, const std::string& before = "") const;
  ServiceReply GetRun(const std::string& id) const;
  ServiceReply Pause(const std::string& id);
  ServiceReply Resume(const std::string& id);
  ServiceReply Abort(const std::string& id);
  // The run's regular files under `under` (a folder of the run, "" for all):
  // {"id", "under", "files": [{"path", "size", "crc32"}], "bytes"}, by path.
  ServiceReply ListFiles(const std::string& id, const std::string& under) const;
  // A path inside the run's directory: 200 and `*absolute` set, or the error
  // reply (404 unknown run, 400 a path that leaves the run directory, by
  // "..", an absolute path or a symlink).
  ServiceReply ResolveRunPath(const std::string& id, const std::string& relative, std::string* absolute) const;
  ServiceReply Devices() const;
  // The recipes of `recipe_folders` and of <data_root>/recipes (not the
  // copies of submitted runs), each with its text, for choosing one to submit.
  ServiceReply ListRecipes() const;
  ServiceReply Health() const;

  // Events of `run_id` after `after_seq`, waiting up to `wait_ms` for one.
  std::vector<RunEvent> EventsAfter(const std::string& run_id, std::uint64_t after_seq, int wait_ms) const;
  bool IsRunFinal(const std::string& run_id) const;
  // The run's directory; empty for unknown ids. Ids are checked, never used raw.
  std::string RunDirectory(const std::string& id) const;
  const ServiceOptions& options() const { return options_; }

 private:
  // 404 for an unknown run, else 409 naming the state of a run that is not the current one (mutex_ held).
  ServiceReply NotTheCurrentRun(const std::string& id, const std::string& request) const;
  // 202 with `run`'s record and "requested": what (pause, resume or abort).
  ServiceReply Requested(const QueuedRun& run, const char* what) const;
  void WorkerLoop();
  void Execute(QueuedRun run);
  void Publish(const std::string& run_id, const std::string& type, nlohmann::json data);
  void PublishLocked(const std::string& run_id, const std::string& type, nlohmann::json data);  // mutex_ held
  void SetState(QueuedRun& run, RunState state, const std::string& reason);
  void AnnounceState(const QueuedRun& run);  // the log line and the "state" event
  // Storage (the queue, a run directory) failed, e.g. on a full disk: logged
  // and reported by Health until the next queue write succeeds.
  void NoteStorageError(const std::string& what);
  // A failed run's stop record and manifest, written when its directory has a
  // journal and no manifest yet; a failure to write them is logged only.
  void FinishRunDirectory(const std::string& run_id, const StopRecord& stop);
  ServiceReply Validate(const std::string& name, const std::string& recipe_yaml, const std::string& recipe_path,
                        bool for_submit) const;
  nlohmann::json RunJson(const QueuedRun& run) const;  // the record as GET /runs/{id} shows it

  ServiceOptions options_;
  mutable RigFileCache rig_;  // options_.rig_path, loaded again when the file changes
  std::unique_ptr<RunQueue> queue_;
  std::unique_ptr<PlanMemoryBudget> plan_budget_;
  std::atomic<bool> stopping_{false};
  std::thread worker_;
  std::atomic<bool> worker_alive_{false};
  std::chrono::steady_clock::time_point started_;

  mutable std::mutex mutex_;  // guards everything below
  mutable std::condition_variable changed_;
  std::string current_id_;
  std::shared_ptr<RunControl> current_control_;
  QueuedRun current_;            // live counters of the current run
  std::deque<RunEvent> events_;  // the most recent events of all runs
  std::uint64_t next_seq_ = 1;
  std::string last_device_fault_;
  nlohmann::json last_frame_;  // the most recent frame's record and run: what the lights and arms last did
  std::string storage_error_;  // empty while storage works
};

}  // namespace photorig::daemon
