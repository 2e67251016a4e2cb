#include "photorig/drivers/trigger_output.h"

#include "photorig/drivers/internal/safety_net.h"

namespace photorig::drivers {

const char* TriggerOutputStateName(TriggerOutput::State state) {
  switch (state) {
    case TriggerOutput::State::kClosed: return "closed";
    case TriggerOutput::State::kOpen: return "open";
  }
  return "unknown";
}

TriggerOutput::~TriggerOutput() { SafetyNet::Remove(this); }

Status TriggerOutput::IllegalTransition(const char* action) const {
  return Device::IllegalTransition(action, TriggerOutputStateName(state_));
}

Status TriggerOutput::Open() {
  if (state_ != State::kClosed) return IllegalTransition("open");
  Status status = DoOpen();
  if (!status.ok()) return status;
  state_ = State::kOpen;
  SafetyNet::Add(this, [this] { (void)Close(); });
  return Status::Ok();
}

Status TriggerOutput::Fire(std::chrono::microseconds width) {
  if (state_ != State::kOpen) return IllegalTransition("fire");
  if (width.count() <= 0) return DeviceError(StatusCode::kInvalidArgument, "pulse width must be > 0");
  return DoFire(width);
}

Status TriggerOutput::Close() {
  if (state_ == State::kClosed) return Status::Ok();
  Status status = DoClose();
  state_ = State::kClosed;  // a failed release still leaves nothing we can fire
  SafetyNet::Remove(this);
  return status;
}

}  // namespace photorig::drivers
