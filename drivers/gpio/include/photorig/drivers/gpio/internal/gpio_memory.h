#pragma once
// An in-memory stand-in for the kernel's GPIO chips behind the GpioBackend
// seam: it applies active-low the way the kernel does (so tests see physical
// levels), refuses lines that do not exist or are already requested, and
// records every physical change with its time, so a trigger pulse's width
// can be measured.

#include "photorig/drivers/gpio/gpio_lights.h"

#include <chrono>
#include <map>
#include <memory>
#include <mutex>
#include <utility>

namespace photorig::drivers {

class InMemoryGpioChips : public std::enable_shared_from_this<InMemoryGpioChips> {
 public:
  struct Change {
    std::string chip;
    unsigned offset;
    int physical;
    std::chrono::steady_clock::time_point when;
  };

  void AddChip(const std::string& name, unsigned lines);
  int physical(const std::string& chip, unsigned offset) const;  // -1 if unknown or never driven
  bool requested(const std::string& chip, unsigned offset) const;
  std::vector<Change> changes() const;
  int bulk_calls() const;  // Set calls that reached the chips
  std::unique_ptr<GpioBackend> MakeBackend();

 private:
  friend class InMemoryGpioBackend;
  struct Line {
    int physical = -1;
    bool requested = false;
  };
  mutable std::mutex mutex_;
  std::map<std::string, std::vector<Line>> chips_;
  std::vector<Change> changes_;
  int bulk_calls_ = 0;
};

}  // namespace photorig::drivers
