#include "photorig/drivers/light_controller.h"

namespace photorig::drivers {

Status LightController::Open() {
  if (state_ != State::kClosed)
    return DeviceError(StatusCode::kFailedPrecondition, "already open");
  Status status = DoOpen();
  if (!status.ok()) return status;
  state_ = State::kOpen;
  // Whatever the controller was left doing by a previous process, start dark.
  return AllOff();
}

Status LightController::SetPattern(const LightPattern& pattern) {
  if (state_ != State::kOpen)
    return DeviceError(StatusCode::kFailedPrecondition, "set pattern while closed");
  if (static_cast<int>(pattern.levels.size()) != channel_count())
    return DeviceError(StatusCode::kInvalidArgument, "pattern has " + std::to_string(pattern.levels.size()) +
                                                         " channels, device has " + std::to_string(channel_count()));
  for (std::size_t i = 0; i < pattern.levels.size(); ++i) {
    if (!(pattern.levels[i] >= 0.0 && pattern.levels[i] <= 1.0))
      return DeviceError(StatusCode::kInvalidArgument, "channel " + std::to_string(i) + " level " +
                                                           std::to_string(pattern.levels[i]) + " outside [0, 1]");
  }
  return DoSetPattern(pattern);
}

Status LightController::AllOff() { return SetPattern(LightPattern::AllOff(channel_count())); }

Result<LightPattern> LightController::ReadBack() {
  if (state_ != State::kOpen)
    return DeviceError(StatusCode::kFailedPrecondition, "read back while closed");
  return DoReadBack();
}

Status LightController::KeepAlive() {
  if (state_ != State::kOpen)
    return DeviceError(StatusCode::kFailedPrecondition, "keep-alive while closed");
  return DoKeepAlive();
}

Status LightController::Close() {
  if (state_ == State::kClosed) return Status::Ok();
  Status off = AllOff();
  Status closed = DoClose();
  state_ = State::kClosed;
  return off.ok() ? closed : off;
}

}  // namespace photorig::drivers
