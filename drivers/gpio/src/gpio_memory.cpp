#include "photorig/drivers/gpio/internal/gpio_memory.h"

namespace photorig::drivers {

class InMemoryGpioBackend : public GpioBackend {
 public:
  explicit InMemoryGpioBackend(std::shared_ptr<InMemoryGpioChips> chips) : chips_(std::move(chips)) {}
  ~InMemoryGpioBackend() override { Release(); }

  Status Request(const std::string&, const std::vector<GpioLine>& lines, const std::vector<int>& initial) override {
    Release();
    std::lock_guard lock(chips_->mutex_);
    for (const GpioLine& line : lines) {
      auto chip = chips_->chips_.find(line.chip);
      if (chip == chips_->chips_.end() || line.offset >= chip->second.size())
        return {StatusCode::kUnavailable, "gpio: no line " + line.chip + ":" + std::to_string(line.offset)};
      if (chip->second[line.offset].requested)
        return {StatusCode::kUnavailable, "gpio: line " + line.chip + ":" + std::to_string(line.offset) + " busy"};
    }
    lines_ = lines;
    for (const GpioLine& line : lines) chips_->chips_[line.chip][line.offset].requested = true;
    SetLocked(initial);
    return Status::Ok();
  }

  Status Set(const std::vector<int>& physical) override {
    std::lock_guard lock(chips_->mutex_);
    if (physical.size() != lines_.size()) return {StatusCode::kInvalidArgument, "gpio: value count mismatch"};
    SetLocked(physical);
    return Status::Ok();
  }

  Result<std::vector<int>> Get() override {
    std::lock_guard lock(chips_->mutex_);
    std::vector<int> values;
    for (const GpioLine& line : lines_) values.push_back(chips_->chips_[line.chip][line.offset].physical);
    return values;
  }

  void Release() override {
    std::lock_guard lock(chips_->mutex_);
    for (const GpioLine& line : lines_) chips_->chips_[line.chip][line.offset].requested = false;
    lines_.clear();
  }

 private:
  void SetLocked(const std::vector<int>& physical) {
    ++chips_->bulk_calls_;
    const auto now = std::chrono::steady_clock::now();
    for (std::size_t i = 0; i < lines_.size(); ++i) {
      auto& line = chips_->chips_[lines_[i].chip][lines_[i].offset];
      if (line.physical != physical[i]) chips_->changes_.push_back({lines_[i].chip, lines_[i].offset, physical[i], now});
      line.physical = physical[i];
    }
  }

  std::shared_ptr<InMemoryGpioChips> chips_;
  std::vector<GpioLine> lines_;
};

void InMemoryGpioChips::AddChip(const std::string& name, unsigned lines) {
  std::lock_guard lock(mutex_);
  chips_[name].resize(lines);
}

int InMemoryGpioChips::physical(const std::string& chip, unsigned offset) const {
  std::lock_guard lock(mutex_);
  auto it = chips_.find(chip);
  return it == chips_.end() || offset >= it->second.size() ? -1 : it->second[offset].physical;
}

bool InMemoryGpioChips::requested(const std::string& chip, unsigned offset) const {
  std::lock_guard lock(mutex_);
  auto it = chips_.find(chip);
  return it != chips_.end() && offset < it->second.size() && it->second[offset].requested;
}

std::vector<InMemoryGpioChips::Change> InMemoryGpioChips::changes() const {
  std::lock_guard lock(mutex_);
  return changes_;
}

int InMemoryGpioChips::bulk_calls() const {
  std::lock_guard lock(mutex_);
  return bulk_calls_;
}

std::unique_ptr<GpioBackend> InMemoryGpioChips::MakeBackend() {
  return std::make_unique<InMemoryGpioBackend>(shared_from_this());
}

}  // namespace photorig::drivers
