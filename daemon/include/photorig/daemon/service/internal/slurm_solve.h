#pragma once
// A run's photometric-stereo stage as a one-task Slurm batch (rig
// `solve: {executor: slurm}`, docs/scaling.md): the batch folder is
// <run>/batch/ (batch.h), the task a plain `photorig solve ps --run <run>`
// with the recipe's request, and the stage's report is read back from the
// task's record once Slurm says it has ended.

#include "photorig/daemon/service/run_request.h"

#include <optional>
#include <string>

namespace photorig::daemon {

struct SlurmSolveOutcome {
  std::string job_id;
  // The stage's report once the task ended; empty when the daemon was asked
  // to stop first: the job goes on, and the next start resumes tracking it.
  std::optional<SolveStageReport> report;
};

// The photorig executable the tasks run: `configured`, else the one beside
// this process's executable (photorigd and photorig install side by side).
std::string PhotorigForTasks(const std::string& configured);

// `photorig solve ps` arguments for a request (after `solve`), every field given.
std::vector<std::string> SolveArguments(const config::PhotometricStereoRequest& request);

// Submits the stage (or, for a run whose <run>/batch/ already tracks a job for
// the same arguments, follows that job), announces the job through
// request.on_solve_submitted, and waits for it, asking Slurm every
// executor.poll_ms. An abort through request.control cancels the job (its
// task leaves no result; the stage is reported aborted). Throws
// std::runtime_error when sbatch cannot submit.
SlurmSolveOutcome SolvePhotometricStereoOnSlurm(const std::string& run_directory, const config::PhotometricStereoRequest& solve,
                                                const config::SolveExecutorConfig& executor, const RunRequest& request);

}  // namespace photorig::daemon
