#include "photorig/solvers/core/summary.h"

#include <cstdio>
#include <utility>

namespace photorig::solvers::core {
namespace {
double MillisecondsBetween(std::chrono::steady_clock::time_point from, std::chrono::steady_clock::time_point to) {
  return std::chrono::duration<double, std::milli>(to - from).count();
}
}  // namespace

const char* TerminationName(Termination termination) {
  switch (termination) {
    case Termination::kSuccess: return "success";
    case Termination::kNoConvergence: return "no-convergence";
    case Termination::kInvalidOptions: return "invalid-options";
    case Termination::kInvalidInput: return "invalid-input";
    case Termination::kFailure: return "failure";
  }
  return "failure";
}

bool Summary::IsSolutionUsable() const {
  return termination == Termination::kSuccess || termination == Termination::kNoConvergence;
}

void Summary::End(Termination how, std::string why) {
  termination = how;
  message = std::move(why);
}

std::string Summary::BriefReport() const {
  char text[96];
  std::snprintf(text, sizeof(text), "%s, %.1f ms (setup %.1f ms)", TerminationName(termination), total_ms, setup_ms);
  return message.empty() ? std::string(text) : std::string(text) + ": " + message;
}

bool Refuse(std::string* why, std::string reason) {
  if (why) *why = std::move(reason);
  return false;
}

Summary Ended(Termination how, std::string why) {
  Summary summary;
  summary.End(how, std::move(why));
  return summary;
}

bool EndIfBadInput(std::string problem, Summary* summary) {
  if (problem.empty()) return false;
  summary->End(Termination::kInvalidInput, std::move(problem));
  return true;
}

SolveTimer::SolveTimer() : start_(Clock::now()), solve_start_(start_) {}

void SolveTimer::SetupDone(Summary* summary) {
  solve_start_ = Clock::now();
  summary->setup_ms = MillisecondsBetween(start_, solve_start_);
  setup_done_ = true;
}

void SolveTimer::Finish(Summary* summary) const {
  const Clock::time_point end = Clock::now();
  summary->total_ms = MillisecondsBetween(start_, end);
  summary->solve_ms = MillisecondsBetween(setup_done_ ? solve_start_ : start_, end);
}

double SolveTimer::ElapsedMs() const { return MillisecondsBetween(start_, Clock::now()); }

Summary SolveTimer::Succeeded(std::string note) const {
  Summary summary = Ended(Termination::kSuccess, std::move(note));
  Finish(&summary);
  return summary;
}

}  // namespace photorig::solvers::core
