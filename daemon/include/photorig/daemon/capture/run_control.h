#pragma once
// The life cycle of a run and the requests that steer it from other threads.
//
//   queued -> running <-> paused
//               |  ^
//               v  |
//            suspended            (device fault: backoff, reopen, retry)
//               |
//   running/paused/suspended -> aborting -> aborted
//   running -> solving            (capture complete; the recipe's solve stages run)
//   running/solving -> done | failed
//   solving -> aborted            (an abort waits for the stage in progress)
//   any non-final state -> interrupted   (daemon restarted and told not to resume)

#include <condition_variable>
#include <mutex>
#include <optional>
#include <string>

namespace photorig::daemon {

enum class RunState { kQueued, kRunning, kPaused, kSuspended, kAborting, kSolving, kDone, kFailed, kAborted, kInterrupted };

const char* RunStateName(RunState state);
std::optional<RunState> RunStateFromName(const std::string& name);
bool IsFinal(RunState state);

// Thread-safe pause/resume/abort flags. The sequencer polls them between steps
// and sleeps on them during backoff, so an abort never waits for a backoff.
class RunControl {
 public:
  void Pause();
  void Resume();
  void Abort();
  bool paused() const;
  bool abort_requested() const;
  // Blocks while paused. Returns false when an abort arrives.
  bool WaitWhilePaused();
  // Sleeps for `ms` unless an abort arrives first (then returns false).
  bool SleepUnlessAborted(int ms);

 private:
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  bool paused_ = false;
  bool aborted_ = false;
};

}  // namespace photorig::daemon
