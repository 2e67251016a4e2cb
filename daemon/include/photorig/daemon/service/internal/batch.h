#pragma once
// Batches of solves, one task per run directory, for `photorig batch` and the
// daemon's Slurm executor (docs/scaling.md). A batch lives in a folder on a
// filesystem every node shares:
//   batch.json      the manifest (kBatchFormat): executor, the solve's
//                   arguments, Slurm's job ids, and the tasks (index, run)
//   task.sh         one task: `photorig solve <arguments> --run RUN --json`
//                   for the run numbered $SLURM_ARRAY_TASK_ID (or $1), its
//                   JSON document written to tasks/N.json by rename as it ends
//   tasks/N.json    task N's document: exit_code and the solve's report
//   logs/N.log      task N's stderr (logs/N.slurm.log: what Slurm itself says)
// The same task.sh runs as a Slurm job array (sbatch --array) or N at a time
// on this machine; the solve writes its results folder whole or not at all
// (results_folder.h), so a task that is cancelled or re-queued leaves no half result.

#include "photorig/config/rig.h"

#include <nlohmann/json.hpp>

#include <atomic>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace photorig::daemon {

inline constexpr const char* kBatchFormat = "photorig-batch/1";

// sbatch's resource requests; empty: the cluster's defaults.
struct SlurmOptions {
  std::string partition;  // --partition
  std::string time;       // --time, e.g. "00:10:00"
  std::string mem;        // --mem, e.g. "2G"
};

struct BatchTask {
  int index = 0;
  std::string run;  // absolute run directory
};

struct BatchManifest {
  std::string directory;                      // absolute batch folder
  config::Executor executor = config::Executor::kLocal;  // stored by name (config::kExecutorNames)
  std::string photorig;                       // the executable every task runs (same path on every node)
  std::vector<std::string> solve_arguments;   // after `photorig solve`, e.g. {"ps", "--method", "auto"}
  SlurmOptions slurm;
  std::vector<std::string> job_ids;           // one per sbatch, oldest first
  std::string created_utc;
  std::vector<BatchTask> tasks;

  nlohmann::json ToJson() const;
};

// Run directories from GLOB patterns, comma-separated lists and plain paths,
// in order, each once; only folders holding a run (manifest.json). Throws
// std::invalid_argument naming what matched no run.
std::vector<std::string> ExpandRunArguments(const std::vector<std::string>& patterns);

// Writes a new batch folder (batch.json, task.sh, tasks/, logs/). Throws
// std::invalid_argument when `directory` already holds a batch.
BatchManifest CreateBatch(const std::string& directory, const std::vector<std::string>& runs,
                          const std::string& photorig, const std::vector<std::string>& solve_arguments,
                          config::Executor executor, const SlurmOptions& slurm);
// Throws std::invalid_argument for a folder without a readable batch.json.
BatchManifest LoadBatch(const std::string& directory);
void SaveBatch(const BatchManifest& batch);

// What one task is doing or did.
struct TaskStatus {
  int index = 0;
  std::string run;
  // "pending" | "running" (the scheduler's word for a live task), "completed"
  // (exit 0), "failed" (its solve failed), "cancelled", "timeout",
  // "preempted", "node_fail", "out_of_memory" (Slurm ended it), "no_result"
  // (not running, and no record of how it ended: never ran, or killed).
  std::string state;
  std::optional<int> exit_code;  // from tasks/N.json
  std::string job_id;            // Slurm's "JOB_TASK" of its latest attempt
  std::string error;             // the solve's error, when it failed
  nlohmann::json report;         // the solve's document (report.json fields), when it ended

  bool live() const { return state == "pending" || state == "running"; }
  bool succeeded() const { return state == "completed"; }
  nlohmann::json ToJson() const;
};

// sbatch or squeue cannot be run, or Slurm's controller does not answer.
struct SlurmUnavailable : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Each task's state: Slurm's (squeue, then sacct where accounting is on) for
// live tasks of the batch's newest jobs, else the task's own record. Throws
// SlurmUnavailable for a batch with jobs when Slurm cannot be asked.
std::vector<TaskStatus> CollectBatchStatus(const BatchManifest& batch);

// Removes the records of these tasks, so a new attempt's state is its own.
void ClearTaskRecords(const BatchManifest& batch, const std::vector<int>& indices);

// Submits these tasks as one job array; returns its job id and appends it to
// batch->job_ids (the caller saves). Throws std::runtime_error with sbatch's
// words when it refuses, SlurmUnavailable when sbatch cannot be run or
// reach the controller.
std::string SubmitSlurmArray(BatchManifest* batch, const std::vector<int>& indices);
// scancel of the batch's jobs (the daemon aborting a run); true when scancel ran.
bool CancelSlurmJobs(const BatchManifest& batch);

// Runs these tasks on this machine, `processes` at a time; `on_task_end`
// after each (tasks ended, total). A stop request terminates the running
// tasks (they leave no results) and returns false.
bool RunBatchLocally(const BatchManifest& batch, const std::vector<int>& indices, int processes,
                     const std::atomic<bool>* stop_requested,
                     const std::function<void(const TaskStatus& ended, int done, int total)>& on_task_end);

}  // namespace photorig::daemon
