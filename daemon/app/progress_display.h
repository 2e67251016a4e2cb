#pragma once
// Progress of long work on stderr: on a terminal a bar with percent and ETA,
// redrawn in place at most ten times a second; otherwise (a log, a pipe) a
// plain line every few seconds and at the end of each stage. Silent under
// --json, whose stdout carries the result alone. Fed by captures (frame by
// frame) and by solvers through solvers::core::ProgressCallback.

#include "photorig/solvers/core/progress.h"

#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>
#include <string_view>

namespace photorig::app {

class ProgressDisplay {
 public:
  ProgressDisplay();
  ~ProgressDisplay();
  ProgressDisplay(const ProgressDisplay&) = delete;
  ProgressDisplay& operator=(const ProgressDisplay&) = delete;

  // `done` of `total` units of `stage` (total 0: unknown); `detail` follows,
  // e.g. the frame's label. A new stage starts its own ETA. `stopped` (a rule
  // ended the stage at `done`: why) ends the stage as "stage stopped at
  // done/total (why)".
  void Update(std::string_view stage, std::int64_t done, std::int64_t total, std::string_view detail = {},
              std::string_view stopped = {});
  // For a solver's Options; the display must outlive the solve.
  solvers::core::ProgressCallback Callback();
  // Ends a bar left on the terminal's line.
  void EndLine();

 private:
  using Clock = std::chrono::steady_clock;
  std::mutex mutex_;
  const bool silent_;
  const bool terminal_;
  std::string stage_;
  Clock::time_point stage_start_{};
  std::int64_t stage_first_done_ = 0;
  Clock::time_point last_print_{};
  bool line_open_ = false;  // a bar is on the terminal's current line
};

// "12 s", "3 min 05 s", "1 h 02 min": the ETA as people read it.
std::string FormatDuration(double seconds);

}  // namespace photorig::app
