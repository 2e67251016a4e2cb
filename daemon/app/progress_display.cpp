#include "progress_display.h"

#include "command_output.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace photorig::app {
namespace {

constexpr std::chrono::milliseconds kTerminalInterval{100};  // ten redraws a second at most
constexpr std::chrono::seconds kLogInterval{5};

}  // namespace

std::string FormatDuration(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return "?";
  const long s = std::lround(seconds);
  char text[32];
  if (s < 60)
    std::snprintf(text, sizeof(text), "%ld s", s);
  else if (s < 3600)
    std::snprintf(text, sizeof(text), "%ld min %02ld s", s / 60, s % 60);
  else
    std::snprintf(text, sizeof(text), "%ld h %02ld min", s / 3600, s / 60 % 60);
  return text;
}

ProgressDisplay::ProgressDisplay() : silent_(JsonOutput()), terminal_(::isatty(STDERR_FILENO) != 0) {}

ProgressDisplay::~ProgressDisplay() { EndLine(); }

void ProgressDisplay::EndLine() {
  std::lock_guard lock(mutex_);
  if (!line_open_) return;
  std::fputc('\n', stderr);
  line_open_ = false;
}

solvers::core::ProgressCallback ProgressDisplay::Callback() {
  return [this](const solvers::core::Progress& progress) {
    Update(progress.stage, progress.done, progress.total, {}, progress.stopped);
  };
}

void ProgressDisplay::Update(std::string_view stage, std::int64_t done, std::int64_t total, std::string_view detail,
                             std::string_view stopped) {
  if (silent_) return;
  std::lock_guard lock(mutex_);
  const Clock::time_point now = Clock::now();
  const bool new_stage = stage != stage_;
  if (new_stage) {
    if (line_open_) std::fputc('\n', stderr);
    line_open_ = false;
    stage_ = stage;
    stage_start_ = now;
    stage_first_done_ = done;
  }
  const bool finished = (total > 0 && done >= total) || !stopped.empty();
  if (!new_stage && !finished && now - last_print_ < (terminal_ ? kTerminalInterval : kLogInterval)) return;
  last_print_ = now;

  // The rate since the stage began, from the first report on (work before it,
  // such as frames a resumed run already had, does not count).
  const double elapsed_s = std::chrono::duration<double>(now - stage_start_).count();
  std::string eta;
  if (finished)
    eta = "in " + FormatDuration(elapsed_s);
  else if (total > 0 && done > stage_first_done_ && elapsed_s > 0.0)
    eta = "ETA " + FormatDuration(elapsed_s * double(total - done) / double(done - stage_first_done_));
  const double percent = total > 0 ? 100.0 * double(done) / double(total) : 0.0;
  const std::string name(stage), extra(detail);
  if (!stopped.empty()) {
    // Where the rule stopped it, not a bar filled to a total it never reached.
    std::fprintf(stderr, "%s%s stopped at %lld/%lld (%.*s), %s%s\n", terminal_ ? "\r" : "", name.c_str(),
                 static_cast<long long>(done), static_cast<long long>(total), static_cast<int>(stopped.size()),
                 stopped.data(), eta.c_str(), terminal_ ? "\033[K" : "");
    line_open_ = false;
  } else if (terminal_) {
    constexpr int kWidth = 30;
    const int filled = total > 0 ? static_cast<int>(std::min<std::int64_t>(kWidth, done * kWidth / total)) : 0;
    std::fprintf(stderr, "\r%s [%.*s%*s] %3.0f%% %lld/%lld %s %s\033[K", name.c_str(), filled,
                 "##############################", kWidth - filled, "", percent, static_cast<long long>(done),
                 static_cast<long long>(total), eta.c_str(), extra.c_str());
    line_open_ = true;
    if (finished) {
      std::fputc('\n', stderr);
      line_open_ = false;
    }
  } else if (total > 0) {
    std::fprintf(stderr, "%s %lld/%lld (%.0f%%)%s%s%s%s\n", name.c_str(), static_cast<long long>(done),
                 static_cast<long long>(total), percent, eta.empty() ? "" : ", ", eta.c_str(),
                 extra.empty() ? "" : ", ", extra.c_str());
  } else {
    std::fprintf(stderr, "%s %lld%s%s\n", name.c_str(), static_cast<long long>(done), extra.empty() ? "" : ", ",
                 extra.c_str());
  }
  std::fflush(stderr);
}

}  // namespace photorig::app
