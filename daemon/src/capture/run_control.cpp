#include "photorig/daemon/capture/run_control.h"

#include "photorig/solvers/core/names.h"

#include <chrono>

namespace photorig::daemon {
namespace {

constexpr solvers::core::NameTable<RunState, 10> kStateNames = {{
    {RunState::kQueued, "queued"},   {RunState::kRunning, "running"},     {RunState::kPaused, "paused"},
    {RunState::kSuspended, "suspended"}, {RunState::kAborting, "aborting"}, {RunState::kSolving, "solving"},
    {RunState::kDone, "done"},
    {RunState::kFailed, "failed"},   {RunState::kAborted, "aborted"},     {RunState::kInterrupted, "interrupted"},
}};

}  // namespace

const char* RunStateName(RunState state) { return solvers::core::NameOf(kStateNames, state); }

std::optional<RunState> RunStateFromName(const std::string& name) { return solvers::core::ParseName(kStateNames, name); }

bool IsFinal(RunState state) {
  return state == RunState::kDone || state == RunState::kFailed || state == RunState::kAborted ||
         state == RunState::kInterrupted;
}

void RunControl::Pause() {
  std::lock_guard lock(mutex_);
  paused_ = true;
  changed_.notify_all();
}

void RunControl::Resume() {
  std::lock_guard lock(mutex_);
  paused_ = false;
  changed_.notify_all();
}

void RunControl::Abort() {
  std::lock_guard lock(mutex_);
  aborted_ = true;
  changed_.notify_all();
}

bool RunControl::paused() const {
  std::lock_guard lock(mutex_);
  return paused_;
}

bool RunControl::abort_requested() const {
  std::lock_guard lock(mutex_);
  return aborted_;
}

bool RunControl::WaitWhilePaused() {
  std::unique_lock lock(mutex_);
  changed_.wait(lock, [this] { return !paused_ || aborted_; });
  return !aborted_;
}

bool RunControl::SleepUnlessAborted(int ms) {
  std::unique_lock lock(mutex_);
  return !changed_.wait_for(lock, std::chrono::milliseconds(ms), [this] { return aborted_; });
}

}  // namespace photorig::daemon
