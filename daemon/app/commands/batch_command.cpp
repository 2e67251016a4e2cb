// photorig batch solve --runs GLOB|LIST... (--slurm [--partition P --time T --mem M] | --local N) [--batch DIR]
// photorig batch solve --retry-failed --batch DIR [--slurm | --local N]
// photorig batch status --batch DIR [--wait]
// One `photorig solve ps` per run directory, as a Slurm job array or N
// processes on this machine (photorig/daemon/service/internal/batch.h, docs/scaling.md).

#include "../command.h"
#include "../command_output.h"
#include "../progress_display.h"
#include "../signals.h"
#include "photorig/config/solve_requests.h"
#include "photorig/daemon/io/utc_time.h"
#include "photorig/daemon/service/internal/batch.h"
#include "photorig/solvers/ps/photometric_stereo.h"

#include <chrono>
#include <cstdio>
#include <functional>
#include <filesystem>
#include <map>
#include <memory>
#include <thread>

namespace photorig::app {
namespace {
namespace fs = std::filesystem;
using daemon::BatchManifest;
using daemon::TaskStatus;

std::string DefaultBatchDirectory() { return "batches/" + daemon::UtcNowInName(); }

nlohmann::json Counts(const std::vector<TaskStatus>& statuses) {
  std::map<std::string, int> counts;
  for (const TaskStatus& status : statuses) ++counts[status.state];
  return counts;
}

bool AnyLive(const std::vector<TaskStatus>& statuses) {
  for (const TaskStatus& status : statuses)
    if (status.live()) return true;
  return false;
}

std::vector<int> EndedUnsuccessfully(const std::vector<TaskStatus>& statuses) {
  std::vector<int> indices;
  for (const TaskStatus& status : statuses)
    if (!status.live() && !status.succeeded()) indices.push_back(status.index);
  return indices;
}

std::string CountsText(const nlohmann::json& counts) {
  std::string text;
  for (const auto& [state, count] : counts.items()) text += (text.empty() ? "" : ", ") + std::to_string(count.get<int>()) + " " + state;
  return text;
}

// The document's fields and the exit code shared by solve (local) and status.
int ReportStatuses(const BatchManifest& batch, const std::vector<TaskStatus>& statuses) {
  nlohmann::json tasks = nlohmann::json::array();
  for (const TaskStatus& status : statuses) tasks.push_back(status.ToJson());
  ResultFields()["batch"] = batch.directory;
  ResultFields()["executor"] = solvers::core::NameOf(config::kExecutorNames, batch.executor);
  ResultFields()["job_ids"] = batch.job_ids;
  ResultFields()["tasks"] = tasks;
  ResultFields()["counts"] = Counts(statuses);
  ResultFields()["finished"] = !AnyLive(statuses);
  std::printf("batch %s: %zu tasks: %s\n", batch.directory.c_str(), statuses.size(),
              CountsText(ResultFields()["counts"]).c_str());
  const std::vector<int> failed = EndedUnsuccessfully(statuses);
  for (int index : failed) {
    const TaskStatus& status = statuses[static_cast<std::size_t>(index)];
    std::printf("  task %d %s%s%s: %s\n", status.index, status.state.c_str(), status.job_id.empty() ? "" : " job ",
                status.job_id.c_str(), status.run.c_str());
    if (!status.error.empty()) std::printf("    %s\n", status.error.c_str());
    std::printf("    log: %s/logs/%d.log\n", batch.directory.c_str(), status.index);
  }
  if (failed.empty()) return kExitOk;
  std::printf("  resubmit with photorig batch solve --retry-failed --batch %s\n", batch.directory.c_str());
  return Fail(kExitFailed, std::to_string(failed.size()) + " of " + std::to_string(statuses.size()) +
                               " tasks ended without a result");
}

struct SolveOptions {
  std::vector<std::string> runs;
  std::string batch_dir;
  std::string method, derivative, integrator, shadow_sigma, commit_gate;
  std::string photorig;
  bool slurm = false;
  daemon::SlurmOptions slurm_options;
  int local = 0;
  bool retry_failed = false;
};

int RunLocally(const BatchManifest& batch, const std::vector<int>& indices, int processes) {
  ProgressDisplay progress;
  const auto start = std::chrono::steady_clock::now();
  std::fprintf(stderr, "batch %s: %zu tasks, %d at a time on this machine\n", batch.directory.c_str(), indices.size(),
               processes);
  const bool finished = daemon::RunBatchLocally(
      batch, indices, processes, &g_stop_requested, [&progress](const TaskStatus& ended, int done, int total) {
        progress.Update("tasks", done, total, ended.state + " " + fs::path(ended.run).filename().string());
      });
  progress.EndLine();
  const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ResultFields()["elapsed_s"] = elapsed_s;
  ResultFields()["processes"] = processes;
  const int code = ReportStatuses(batch, daemon::CollectBatchStatus(batch));
  std::printf("  %zu tasks in %.2f s with %d processes (%.2f runs/s)\n", indices.size(), elapsed_s, processes,
              elapsed_s > 0 ? indices.size() / elapsed_s : 0.0);
  if (!finished) return Fail(kExitInterrupted, "interrupted; the tasks that had not ended left no results");
  return code;
}

int Submit(BatchManifest* batch, const std::vector<int>& indices) {
  std::string job_id;
  const std::string kept = " (the batch is kept: photorig batch solve --retry-failed --batch " + batch->directory +
                           " submits it again)";
  try {
    job_id = daemon::SubmitSlurmArray(batch, indices);
  } catch (const daemon::SlurmUnavailable& e) {
    return Fail(kExitUnavailable, e.what() + kept);
  } catch (const std::runtime_error& e) {
    return Fail(kExitUsage, e.what() + kept);  // sbatch refused the request (a partition or limit it does not have)
  }
  daemon::SaveBatch(*batch);
  std::printf("batch %s: job array %s, %zu tasks\n", batch->directory.c_str(), job_id.c_str(), indices.size());
  std::printf("  follow it with: photorig batch status --batch %s --wait\n", batch->directory.c_str());
  ResultFields()["batch"] = batch->directory;
  ResultFields()["executor"] = solvers::core::NameOf(config::kExecutorNames, batch->executor);
  ResultFields()["job_id"] = job_id;
  ResultFields()["job_ids"] = batch->job_ids;
  ResultFields()["tasks_submitted"] = indices;
  return kExitOk;
}

int ExecuteSolve(const SolveOptions& options) {
  if (options.slurm && options.local > 0) return Fail(kExitUsage, "give --slurm or --local N, not both");
  BatchManifest batch;
  std::vector<int> indices;
  if (options.retry_failed) {
    if (options.batch_dir.empty()) return Fail(kExitUsage, "--retry-failed needs --batch DIR");
    batch = daemon::LoadBatch(options.batch_dir);
    const std::vector<TaskStatus> statuses = daemon::CollectBatchStatus(batch);
    indices = EndedUnsuccessfully(statuses);
    if (indices.empty()) {
      std::printf("batch %s: no task to retry (%s)\n", batch.directory.c_str(), CountsText(Counts(statuses)).c_str());
      return ReportStatuses(batch, statuses);
    }
    daemon::ClearTaskRecords(batch, indices);
    if (options.slurm) batch.executor = config::Executor::kSlurm;
    if (options.local > 0) batch.executor = config::Executor::kLocal;
    daemon::SaveBatch(batch);
  } else {
    if (options.runs.empty()) return Fail(kExitUsage, "give --runs GLOB|LIST (or --retry-failed --batch DIR)");
    if (!options.slurm && options.local <= 0) return Fail(kExitUsage, "give --slurm or --local N");
    std::vector<std::string> arguments = {"ps"};
    auto forward = [&arguments](const char* flag, const std::string& value) {
      if (value.empty()) return;
      arguments.push_back(flag);
      arguments.push_back(value);
    };
    forward("--method", options.method);
    forward("--derivative", options.derivative);
    forward("--integrator", options.integrator);
    forward("--shadow-sigma", options.shadow_sigma);
    forward("--commit-gate", options.commit_gate.empty() ? "" : fs::absolute(options.commit_gate).string());
    const std::string photorig =
        options.photorig.empty() ? fs::read_symlink("/proc/self/exe").string() : fs::absolute(options.photorig).string();
    const std::vector<std::string> runs = daemon::ExpandRunArguments(options.runs);
    batch = daemon::CreateBatch(options.batch_dir.empty() ? DefaultBatchDirectory() : options.batch_dir, runs, photorig,
                                arguments, options.slurm ? config::Executor::kSlurm : config::Executor::kLocal,
                                options.slurm_options);
    for (const daemon::BatchTask& task : batch.tasks) indices.push_back(task.index);
  }
  if (batch.executor == config::Executor::kSlurm) return Submit(&batch, indices);
  const int processes = options.local > 0 ? options.local : static_cast<int>(std::thread::hardware_concurrency());
  return RunLocally(batch, indices, std::max(1, processes));
}

// Slurm not answering is a service unavailable (exit 3), wherever it is asked.
int ExitUnavailableOnSlurm(const std::function<int()>& command) {
  try {
    return command();
  } catch (const daemon::SlurmUnavailable& e) {
    return Fail(kExitUnavailable, e.what());
  }
}

CommandRunner SetupSolve(CLI::App& app) {
  auto options = std::make_shared<SolveOptions>();
  CLI::App* batch = SubcommandGroup(app, "batch", "solve many runs: a Slurm job array or N processes here");
  CLI::App* solve = batch->add_subcommand("solve", "photometric stereo on every run, one task per run");
  solve->add_option("--runs", options->runs, "run directories: GLOB patterns, comma-separated lists or paths");
  solve->add_option("--batch", options->batch_dir,
                    "batch folder, on a filesystem every node shares (default: batches/<UTC time>)");
  // Forwarded as text to each task's `photorig solve ps`, checked here against the same names.
  solve->add_option("--method", options->method, "as photorig solve ps (default auto)")
      ->check(CLI::IsMember(solvers::core::NameMap(solvers::ps::kMethodNames)));
  solve->add_option("--derivative", options->derivative, "as photorig solve ps")
      ->check(CLI::IsMember(solvers::core::NameMap(solvers::ps::kBlinnPhongDerivativeNames)));
  solve->add_option("--integrator", options->integrator, "as photorig solve ps")->check(CLI::IsMember(config::IntegratorChoices()));
  solve->add_option("--shadow-sigma", options->shadow_sigma, "as photorig solve ps");
  solve->add_option("--commit-gate", options->commit_gate, "as photorig solve ps")->group("");
  solve->add_option("--photorig", options->photorig,
                    "the photorig executable the tasks run, at the same path on every node (default: this one)");
  auto* slurm = solve->add_flag("--slurm", options->slurm, "submit one Slurm job array (sbatch --array)");
  solve->add_option("--partition", options->slurm_options.partition, "Slurm partition")->needs(slurm);
  solve->add_option("--time", options->slurm_options.time, "Slurm time limit per task, e.g. 00:10:00")->needs(slurm);
  solve->add_option("--mem", options->slurm_options.mem, "Slurm memory per task, e.g. 2G")->needs(slurm);
  solve->add_option("--local", options->local, "run the tasks here, N processes at a time")->check(CLI::PositiveNumber);
  solve->add_flag("--retry-failed", options->retry_failed,
                  "run again the tasks of --batch DIR that ended without a result (as first run, or --slurm/--local N)");
  return {solve, [options] { return ExitUnavailableOnSlurm([&options] { return ExecuteSolve(*options); }); }};
}

struct StatusOptions {
  std::string batch_dir;
  bool wait = false;
};

int ExecuteStatus(const StatusOptions& options) {
  const BatchManifest batch = daemon::LoadBatch(options.batch_dir);
  std::vector<TaskStatus> statuses = daemon::CollectBatchStatus(batch);
  ProgressDisplay progress;
  while (options.wait && AnyLive(statuses)) {
    int ended = 0;
    for (const TaskStatus& status : statuses) ended += status.live() ? 0 : 1;
    progress.Update("tasks", ended, static_cast<std::int64_t>(statuses.size()));
    for (int i = 0; i < 20 && !g_stop_requested.load(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    if (g_stop_requested.load()) {
      progress.EndLine();
      ReportStatuses(batch, statuses);
      return Fail(kExitInterrupted, "interrupted while waiting; the tasks go on");
    }
    try {
      statuses = daemon::CollectBatchStatus(batch);
    } catch (const daemon::SlurmUnavailable& e) {
      // A busy or restarting controller while waiting: the tasks go on, ask again.
      progress.EndLine();
      std::fprintf(stderr, "batch %s: %s; asking again\n", batch.directory.c_str(), e.what());
    }
  }
  progress.EndLine();
  return ReportStatuses(batch, statuses);
}

CommandRunner SetupStatus(CLI::App& app) {
  auto options = std::make_shared<StatusOptions>();
  CLI::App* batch = SubcommandGroup(app, "batch", "solve many runs: a Slurm job array or N processes here");
  CLI::App* status = batch->add_subcommand("status", "each task's state (Slurm's, then its record) and its run's report");
  status->add_option("--batch", options->batch_dir, "batch folder")->required()->check(CLI::ExistingDirectory);
  status->add_flag("--wait", options->wait, "wait until no task is pending or running");
  return {status, [options] { return ExitUnavailableOnSlurm([&options] { return ExecuteStatus(*options); }); }};
}

const bool registered_solve = RegisterCommand(SetupSolve);
const bool registered_status = RegisterCommand(SetupStatus);

}  // namespace
}  // namespace photorig::app
