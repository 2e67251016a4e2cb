#pragma once
// How a long solve says how far it has got. A solver whose work can take
// more than a second takes a ProgressCallback in its Options and calls it
// from the solving thread as units of work (pixels, tiles, iterations,
// samples) complete: about every percent, never in an inner loop, and once
// with done == total at the end of each stage. The callback must be cheap and
// must not throw; the CLI turns it into a bar with an ETA, the daemon into
// run events. An empty callback costs nothing.

#include <cstdint>
#include <functional>
#include <string_view>

namespace photorig::solvers::core {

struct Progress {
  std::string_view stage;  // what is being done now, e.g. "lambertian", "blinn-phong", "sirt"
  std::int64_t done = 0;   // units finished in this stage
  std::int64_t total = 0;  // units in this stage (0 when unknown, e.g. iterate until a rule stops)
  // Set on a stage's last report when a rule ended it before `total` (an
  // iteration that converged): why, e.g. "converged"; `done` is where it stopped.
  std::string_view stopped;
};

using ProgressCallback = std::function<void(const Progress&)>;

// Calls `callback` (if set) at most once per `step` units, and always at the
// end: the throttle a solver keeps beside its loop so that reporting stays
// out of the inner work.
class ProgressThrottle {
 public:
  ProgressThrottle(const ProgressCallback& callback, std::string_view stage, std::int64_t total);
  // Reports `done` if it has advanced by at least a percent of total since the last report.
  void Update(std::int64_t done);
  // Reports done == total.
  void Finish();
  // Reports that a rule ended the stage at `done` of total, and why (Progress::stopped).
  void StoppedAt(std::int64_t done, std::string_view why);

 private:
  const ProgressCallback& callback_;
  std::string_view stage_;
  std::int64_t total_;
  std::int64_t step_;
  std::int64_t last_reported_ = -1;
};

}  // namespace photorig::solvers::core
