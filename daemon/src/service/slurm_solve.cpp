#include "photorig/daemon/service/internal/slurm_solve.h"

#include "photorig/daemon/service/internal/batch.h"
#include "photorig/solvers/core/number_text.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <filesystem>
#include <thread>

namespace photorig::daemon {
namespace fs = std::filesystem;

namespace {

std::string Number(double value) { return solvers::core::NumberText(value, 17); }

// The stage's report from the task's record, or, for a task that left none,
// from how Slurm says it ended.
SolveStageReport ReportFromTask(const TaskStatus& status, const std::string& job_id) {
  SolveStageReport report;
  if (status.report.contains("termination")) {
    report = ReportPhotometricStereoStage(status.report, status.exit_code == 0);
  } else {
    report.stage = "photometric_stereo";
    report.results = "results/ps";
    report.termination = status.state;
    report.message = status.error.empty() ? "Slurm job " + job_id + " ended " + status.state +
                                                " without a result (its log: batch/logs/0.log)"
                                          : status.error;
    report.figures = nlohmann::json::object();
    report.timings_ms = nlohmann::json::object();
  }
  report.figures["slurm_job_id"] = job_id;
  return report;
}

}  // namespace

std::string PhotorigForTasks(const std::string& configured) {
  if (!configured.empty()) return fs::absolute(configured).string();
  std::error_code error;
  const fs::path self = fs::read_symlink("/proc/self/exe", error);
  return error ? std::string("photorig") : (self.parent_path() / "photorig").string();
}

std::vector<std::string> SolveArguments(const config::PhotometricStereoRequest& request) {
  // The task's command line: the request's values written back as the names the CLI parses.
  std::vector<std::string> arguments = {"ps",
          "--method",
          solvers::ps::MethodName(request.method),
          "--derivative",
          solvers::core::NameOf(solvers::ps::kBlinnPhongDerivativeNames, request.derivative),
          "--integrator",
          config::IntegratorChoiceName(request.integrator),
          "--shadow-sigma",
          Number(request.shadow_threshold_sigma),
          "--max-condition",
          Number(request.max_condition_number),
          "--max-distant-bias",
          Number(request.max_distant_bias_deg)};
  if (request.assume_distant) arguments.push_back("--assume-distant");
  if (!request.fill_unresolved) arguments.push_back("--no-fill");
  return arguments;
}

SlurmSolveOutcome SolvePhotometricStereoOnSlurm(const std::string& run_directory, const config::PhotometricStereoRequest& solve,
                                                const config::SolveExecutorConfig& executor, const RunRequest& request) {
  const fs::path batch_directory = fs::absolute(run_directory) / "batch";
  const std::vector<std::string> arguments = SolveArguments(solve);
  BatchManifest batch;
  // A daemon restarted while its job ran follows that job instead of solving again.
  bool follow = false;
  if (fs::exists(batch_directory / "batch.json")) {
    try {
      batch = LoadBatch(batch_directory.string());
      if (batch.solve_arguments == arguments && !batch.job_ids.empty()) {
        try {
          const TaskStatus status = CollectBatchStatus(batch).front();
          follow = status.live() || status.succeeded();
        } catch (const SlurmUnavailable& e) {
          // Slurm cannot say now; a second job would solve the run twice. The
          // loop below asks again until it can.
          spdlog::warn("solve photometric_stereo: Slurm job {}_0: {}", batch.job_ids.back(), e.what());
          follow = true;
        }
      }
    } catch (const std::invalid_argument& e) {
      spdlog::warn("{}: {}; submitting anew", batch_directory.string(), e.what());
    }
    if (!follow) fs::remove_all(batch_directory);
  }
  if (!follow) {
    batch = CreateBatch(batch_directory.string(), {fs::absolute(run_directory).lexically_normal().string()},
                        PhotorigForTasks(executor.photorig), arguments, config::Executor::kSlurm,
                        {executor.partition, executor.time, executor.mem});
    SubmitSlurmArray(&batch, {0});
    SaveBatch(batch);
  }
  SlurmSolveOutcome outcome;
  outcome.job_id = batch.job_ids.back() + "_0";
  spdlog::info("solve photometric_stereo: {} Slurm job {} ({})", follow ? "following" : "submitted", outcome.job_id,
               batch_directory.string());
  if (request.on_solve_submitted) request.on_solve_submitted("photometric_stereo", outcome.job_id, batch_directory.string());
  if (request.on_state) request.on_state(RunState::kSolving, "photometric_stereo: Slurm job " + outcome.job_id);

  auto stop_requested = [&request] { return request.stop_requested && request.stop_requested->load(); };
  auto abort_requested = [&request] { return request.control && request.control->abort_requested(); };
  bool cancelled = false;
  for (;;) {
    TaskStatus status;
    try {
      status = CollectBatchStatus(batch).front();
    } catch (const SlurmUnavailable& e) {
      // A controller restarting is no reason to fail the run: ask again later.
      spdlog::warn("solve photometric_stereo: Slurm job {}: {}", outcome.job_id, e.what());
      status.state = "running";
    }
    if (!status.live()) {
      outcome.report = ReportFromTask(status, outcome.job_id);
      return outcome;
    }
    if (abort_requested() && !cancelled) {
      // Its task is stopped before its rename: the run keeps no half result.
      CancelSlurmJobs(batch);
      cancelled = true;
    }
    if (stop_requested() && !cancelled) return outcome;
    for (int waited_ms = 0; waited_ms < executor.poll_ms && !(stop_requested() || (abort_requested() && !cancelled));
         waited_ms += 100)
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
}

}  // namespace photorig::daemon
