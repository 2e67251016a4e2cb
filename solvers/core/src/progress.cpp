#include "photorig/solvers/core/progress.h"

#include <algorithm>

namespace photorig::solvers::core {

ProgressThrottle::ProgressThrottle(const ProgressCallback& callback, std::string_view stage, std::int64_t total)
    : callback_(callback), stage_(stage), total_(total), step_(std::max<std::int64_t>(1, total / 100)) {}

void ProgressThrottle::Update(std::int64_t done) {
  if (!callback_ || (last_reported_ >= 0 && done - last_reported_ < step_)) return;
  last_reported_ = done;
  callback_(Progress{stage_, done, total_});
}

void ProgressThrottle::Finish() {
  if (!callback_ || last_reported_ == total_) return;
  last_reported_ = total_;
  callback_(Progress{stage_, total_, total_});
}

void ProgressThrottle::StoppedAt(std::int64_t done, std::string_view why) {
  if (!callback_) return;
  last_reported_ = total_;
  callback_(Progress{stage_, done, total_, why});
}

}  // namespace photorig::solvers::core
