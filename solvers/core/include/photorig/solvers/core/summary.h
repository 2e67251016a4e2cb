#pragma once
// What every solver returns: how it ended, why, and how long it took. Solvers
// never throw on bad options or bad data; they end with one of the
// terminations below, a message naming what was wrong, and (where they work
// per pixel or per sample) flags on what they could not resolve.
//
// Each solver's own summary derives from Summary and adds its figures:
//
//   struct IntegrationSummary : solvers::core::Summary { std::size_t pixels; ... };
//
// and each solver's Options has documented defaults and IsValid(std::string*),
// which the solver calls first (ending kInvalidOptions with the reason).

#include <chrono>
#include <string>
#include <utility>

namespace photorig::solvers::core {

enum class Termination {
  kSuccess,         // the solver finished by its own rule; the result is its answer
  kNoConvergence,   // an iteration limit came first: the result is usable, not converged
  kInvalidOptions,  // Options::IsValid failed: nothing was computed
  kInvalidInput,    // input sizes, types or values are unusable: nothing was computed
  kFailure          // the data support no result (degenerate geometry, too few samples)
};

// "success", "no-convergence", "invalid-options", "invalid-input", "failure":
// the words reports and the CLI print.
const char* TerminationName(Termination termination);

struct Summary {
  Termination termination = Termination::kFailure;
  std::string message;  // empty on plain success; otherwise what happened and what to do

  double setup_ms = 0.0;  // validation and preparation
  double solve_ms = 0.0;  // the computation proper
  double total_ms = 0.0;  // everything, from the call to the return

  // True when the result may be used: kSuccess or kNoConvergence.
  bool IsSolutionUsable() const;

  // Ends the summary with `termination` and `why` (for the early returns of
  // invalid options, invalid input and failures).
  void End(Termination how, std::string why);

  // One line: "success, 12.3 ms (setup 0.4 ms)" and ": message" when there is
  // one. A family's summary that adds figures has a BriefReport of its own
  // that says them (ps::SolverSummary's); summary_json.h gives the same as JSON.
  std::string BriefReport() const;
};

// The refusal of an Options::IsValid: sets *why (when given) to `reason` and
// returns false, so each check is one line:
//   if (!(step > 0.0)) return Refuse(why, "step must be positive");
bool Refuse(std::string* why, std::string reason);

// A summary ended with `how` and `why`: the one-line early return of a solver
// whose output is a plain value (an image, a matrix) rather than a Summary subclass.
Summary Ended(Termination how, std::string why);

// The checks every solver opens with, as one-line early returns:
//   if (EndIfInvalid(options, &summary)) return summary;
//   if (EndIfBadInput(CheckInputs(...), &summary)) return summary;
// EndIfInvalid ends `summary` kInvalidOptions with "invalid options: " and the
// reason when options.IsValid fails; EndIfBadInput ends it kInvalidInput with
// `problem` when that is not empty. Both return true when they ended it.
template <typename Options>
bool EndIfInvalid(const Options& options, Summary* summary) {
  std::string why;
  if (options.IsValid(&why)) return false;
  summary->End(Termination::kInvalidOptions, "invalid options: " + why);
  return true;
}
bool EndIfBadInput(std::string problem, Summary* summary);

// Measures the phases of a solve into a Summary's timings:
//   SolveTimer timer;  ... timer.SetupDone(&summary); ... timer.Finish(&summary);
// Early returns that computed nothing may leave the timings at zero.
class SolveTimer {
 public:
  SolveTimer();
  // Ends the setup phase: setup_ms is the time so far, solve_ms runs from here.
  void SetupDone(Summary* summary);
  // Sets solve_ms (the whole call if SetupDone was never called) and total_ms.
  void Finish(Summary* summary) const;
  // Ends *summary with `how` and `why`, finishes its timings and returns a
  // copy: the early return of a solve whose every path is timed.
  //   if (!sigma) return timer.End(&summary, Termination::kInvalidInput, "no output volume given");
  template <typename SolverSummary>
  SolverSummary End(SolverSummary* summary, Termination how, std::string why) const {
    summary->End(how, std::move(why));
    Finish(summary);
    return *summary;
  }
  // A kSuccess summary (with `note` as its message) timed by this timer.
  Summary Succeeded(std::string note = {}) const;
  // Milliseconds since construction (for a solve that keeps the setup and
  // solve phases of an inner solver and times only the whole).
  double ElapsedMs() const;

 private:
  using Clock = std::chrono::steady_clock;
  Clock::time_point start_;
  Clock::time_point solve_start_;
  bool setup_done_ = false;
};

}  // namespace photorig::solvers::core
