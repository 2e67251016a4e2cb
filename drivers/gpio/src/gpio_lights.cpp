#include "photorig/drivers/gpio/gpio_lights.h"

#include <thread>

namespace photorig::drivers {
namespace {

std::vector<int> Physical(const std::vector<GpioLine>& lines, const std::vector<int>& logical) {
  std::vector<int> physical(lines.size());
  for (std::size_t i = 0; i < lines.size(); ++i) physical[i] = (logical[i] != 0) != lines[i].active_low ? 1 : 0;
  return physical;
}

std::string Describe(const GpioLine& line) { return line.chip + ":" + std::to_string(line.offset); }

}  // namespace

GpioLightController::GpioLightController(std::string id, std::vector<GpioLine> lines,
                                         std::unique_ptr<GpioBackend> backend, std::optional<GpioLine> heartbeat)
    : LightController(std::move(id)),
      leds_(lines.size()),
      lines_(std::move(lines)),
      has_heartbeat_(heartbeat.has_value()),
      backend_(std::move(backend)) {
  if (heartbeat) lines_.push_back(*heartbeat);
}

GpioLightController::~GpioLightController() { (void)Close(); }

Status GpioLightController::DoOpen() {
  if (leds_ == 0) return {StatusCode::kInvalidArgument, "light controller " + id() + ": no GPIO lines"};
  logical_.assign(lines_.size(), 0);
  Status status = backend_->Request("photorig:" + id(), lines_, Physical(lines_, logical_));
  if (!status.ok()) return {status.code(), "light controller " + id() + ": " + status.message()};
  return Status::Ok();
}

Status GpioLightController::Drive() {
  Status status = backend_->Set(Physical(lines_, logical_));
  if (!status.ok()) return {status.code(), "light controller " + id() + ": " + status.message()};
  return Status::Ok();
}

Status GpioLightController::DoSetPattern(const LightPattern& pattern) {
  for (std::size_t i = 0; i < leds_; ++i) logical_[i] = pattern.levels[i] > 0.0 ? 1 : 0;
  return Drive();
}

Result<LightPattern> GpioLightController::DoReadBack() {
  auto physical = backend_->Get();
  if (!physical.ok()) return physical.status();
  LightPattern pattern = LightPattern::AllOff(channel_count());
  for (std::size_t i = 0; i < leds_; ++i)
    pattern.levels[i] = (physical.value()[i] != 0) != lines_[i].active_low ? 1.0 : 0.0;
  return pattern;
}

Status GpioLightController::DoKeepAlive() {
  if (!has_heartbeat_) return Status::Ok();
  // An edge every call: the external watchdog is retriggered by edges, not levels.
  logical_.back() ^= 1;
  return Drive();
}

Status GpioLightController::DoClose() {
  backend_->Release();
  return Status::Ok();
}

GpioTriggerLine::GpioTriggerLine(std::string id, GpioLine line, std::unique_ptr<GpioBackend> backend)
    : TriggerOutput(std::move(id)), line_(std::move(line)), backend_(std::move(backend)) {}

GpioTriggerLine::~GpioTriggerLine() { (void)Close(); }

Status GpioTriggerLine::DoOpen() {
  Status status = backend_->Request("photorig:" + id(), {line_}, Physical({line_}, {0}));
  if (!status.ok()) return {status.code(), "trigger " + id() + " (" + Describe(line_) + "): " + status.message()};
  return Status::Ok();
}

Status GpioTriggerLine::DoFire(std::chrono::microseconds width) {
  Status status = backend_->Set(Physical({line_}, {1}));
  if (!status.ok()) return status;
  std::this_thread::sleep_for(width);
  return backend_->Set(Physical({line_}, {0}));
}

Status GpioTriggerLine::DoClose() {
  // Deassert before releasing: the kernel keeps a released line's last value.
  Status status = backend_->Set(Physical({line_}, {0}));
  backend_->Release();
  return status;
}

}  // namespace photorig::drivers
