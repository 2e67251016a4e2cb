#include "photorig/drivers/camera.h"

namespace photorig::drivers {

const char* CameraStateName(Camera::State state) {
  switch (state) {
    case Camera::State::kClosed: return "closed";
    case Camera::State::kOpen: return "open";
    case Camera::State::kConfigured: return "configured";
    case Camera::State::kStreaming: return "streaming";
  }
  return "unknown";
}

Status Camera::IllegalTransition(const char* action) const {
  return Device::IllegalTransition(action, CameraStateName(state_));
}

Status Camera::Open() {
  if (state_ != State::kClosed) return IllegalTransition("open");
  Status status = DoOpen();
  if (status.ok()) state_ = State::kOpen;
  return status;
}

Result<std::vector<SettingAdjustment>> Camera::Configure(const CameraSettings& settings) {
  if (state_ != State::kOpen && state_ != State::kConfigured) return IllegalTransition("configure");
  CameraSettings applied = settings;
  auto adjustments = DoConfigure(&applied);
  if (adjustments.ok()) {
    settings_ = applied;
    state_ = State::kConfigured;
  }
  return adjustments;
}

Status Camera::Start() {
  if (state_ != State::kConfigured) return IllegalTransition("start streaming");
  Status status = DoStart();
  if (status.ok()) state_ = State::kStreaming;
  return status;
}

Status Camera::Trigger() {
  if (state_ != State::kStreaming) return IllegalTransition("trigger");
  if (settings_.trigger != TriggerMode::kSoftware)
    return DeviceError(StatusCode::kFailedPrecondition, "software trigger while not in software trigger mode");
  return DoTrigger();
}

Result<Frame> Camera::WaitFrame(int timeout_ms) {
  if (state_ != State::kStreaming) return IllegalTransition("wait for a frame");
  if (timeout_ms <= 0) return DeviceError(StatusCode::kInvalidArgument, "timeout_ms must be > 0");
  auto frame = DoWaitFrame(timeout_ms);
  // Every driver gets the same check: a frame shorter than its geometry is data loss, not a frame.
  if (frame.ok() && frame->pixels.size() != static_cast<std::size_t>(frame->width) * frame->height)
    return DeviceError(StatusCode::kDataLoss, "frame " + std::to_string(frame->frame_id) + " is short (" +
                                                  std::to_string(frame->pixels.size()) + " of " +
                                                  std::to_string(frame->width * frame->height) + " pixels)");
  return frame;
}

Status Camera::Stop() {
  if (state_ != State::kStreaming) return IllegalTransition("stop streaming");
  Status status = DoStop();
  state_ = State::kConfigured;  // a failed stop still leaves no stream we can use
  return status;
}

Status Camera::Close() {
  if (state_ == State::kClosed) return Status::Ok();
  Status stop_status;
  if (state_ == State::kStreaming) stop_status = Stop();
  Status status = DoClose();
  state_ = State::kClosed;
  return status.ok() ? stop_status : status;
}

namespace {

// Prefix -> mosaic; the rest of the name is the bit count.
constexpr struct {
  const char* prefix;
  const char* mosaic;
} kPixelFormatFamilies[] = {
    {"Mono", "mono"}, {"BayerRG", "RGGB"}, {"BayerGR", "GRBG"}, {"BayerGB", "GBRG"}, {"BayerBG", "BGGR"}, {"RGB", "RGB"},
};

}  // namespace

std::string MosaicOfPixelFormat(const std::string& pixel_format) {
  if (BitsOfPixelFormat(pixel_format) == 0) return "";
  for (const auto& family : kPixelFormatFamilies)
    if (pixel_format.rfind(family.prefix, 0) == 0) return family.mosaic;
  return "";
}

int BitsOfPixelFormat(const std::string& pixel_format) {
  for (const auto& family : kPixelFormatFamilies) {
    if (pixel_format.rfind(family.prefix, 0) != 0) continue;
    const std::string bits = pixel_format.substr(std::string(family.prefix).size());
    const bool rgb = std::string(family.mosaic) == "RGB";
    for (const char* allowed : {"8", "10", "12", "14", "16"})
      if (bits == allowed && (!rgb || bits == "8" || bits == "16")) return std::stoi(bits);
  }
  return 0;
}

Frame FrameTakenWith(const CameraSettings& settings, int width, int height) {
  Frame frame;
  frame.width = width;
  frame.height = height;
  frame.bit_depth = settings.bit_depth;
  frame.pixel_format = settings.pixel_format;
  frame.exposure_us = settings.exposure_us;
  frame.gain_db = settings.gain_db;
  return frame;
}

}  // namespace photorig::drivers
