#include "photorig/sim/devices.h"

#include <algorithm>
#include <chrono>
#include <cmath>

namespace photorig::sim {
namespace {

std::int64_t NowNs(bool realtime) {
  const auto now = realtime ? std::chrono::system_clock::now().time_since_epoch()
                            : std::chrono::steady_clock::now().time_since_epoch();
  return std::chrono::duration_cast<std::chrono::nanoseconds>(now).count();
}

// The simulated sensor's limits, as a real camera would advertise them.
constexpr double kMinExposureUs = 10.0;
constexpr double kMaxExposureUs = 1e6;
constexpr double kExposureStepUs = 1.0;
constexpr double kMaxGainDb = 24.0;

}  // namespace

SimLightDome::SimLightDome(std::string id, std::shared_ptr<World> world)
    : LightController(std::move(id)), world_(std::move(world)) {}

int SimLightDome::channel_count() const { return static_cast<int>(world_->config().lights.size()); }
Status SimLightDome::DoOpen() { return Status::Ok(); }
Status SimLightDome::DoSetPattern(const drivers::LightPattern& pattern) {
  const LightFaults& faults = world_->config().light_faults;
  if (faults.fail_commands.count(commands_++))
    return {StatusCode::kUnavailable, "light controller " + id() + ": no reply to pattern command (injected fault)"};
  std::vector<double> levels = pattern.levels;
  for (int channel : faults.stuck_off_channels)
    if (channel >= 0 && channel < static_cast<int>(levels.size())) levels[channel] = 0.0;
  world_->SetLevels(std::move(levels));
  return Status::Ok();
}
Result<drivers::LightPattern> SimLightDome::DoReadBack() { return drivers::LightPattern{world_->levels()}; }
Status SimLightDome::DoClose() { return Status::Ok(); }

SimCamera::SimCamera(std::string id, std::shared_ptr<World> world)
    : Camera(std::move(id)), world_(std::move(world)) {}

SimCamera::~SimCamera() {
  world_->DisconnectTriggerInput();
  (void)Close();
}

Status SimCamera::DoOpen() {
  next_frame_id_ = 0;
  link_lost_ = false;
  return Status::Ok();
}

Result<std::vector<drivers::SettingAdjustment>> SimCamera::DoConfigure(drivers::CameraSettings* settings) {
  std::vector<drivers::SettingAdjustment> adjustments;
  const auto& camera = world_->config().camera;
  const int bit_depth = world_->config().sensor.bit_depth;
  auto adjust = [&adjustments](const char* field, double requested, double applied, const char* reason) {
    if (requested != applied) adjustments.push_back({field, requested, applied, reason});
  };
  if (settings->width == 0) settings->width = camera.width;
  if (settings->height == 0) settings->height = camera.height;
  if (settings->width != camera.width || settings->height != camera.height)
    return Status{StatusCode::kInvalidArgument, "camera " + id() + ": the simulated sensor is " +
                                                    std::to_string(camera.width) + "x" + std::to_string(camera.height) +
                                                    " and has no region of interest"};
  adjust("bit_depth", settings->bit_depth, bit_depth, "fixed by the sensor");
  settings->bit_depth = bit_depth;
  // The sensor's own format: Mono<n>, or Bayer<pattern><n> behind a colour filter.
  const std::string format = SensorPixelFormat();
  if (!settings->pixel_format.empty() && settings->pixel_format != format)
    return Status{StatusCode::kInvalidArgument,
                  "camera " + id() + ": pixel format " + settings->pixel_format + " is not offered (the sensor delivers " +
                      format + ")"};
  settings->pixel_format = format;
  const double exposure =
      std::clamp(std::round(settings->exposure_us / kExposureStepUs) * kExposureStepUs, kMinExposureUs, kMaxExposureUs);
  adjust("exposure_us", settings->exposure_us, exposure, "rounded to the 1 us step within [10 us, 1 s]");
  settings->exposure_us = exposure;
  const double gain = std::clamp(settings->gain_db, 0.0, kMaxGainDb);
  adjust("gain_db", settings->gain_db, gain, "clamped to [0, 24] dB");
  settings->gain_db = gain;
  if (settings->trigger == drivers::TriggerMode::kHardware && settings->trigger_line != "Line1")
    return Status{StatusCode::kInvalidArgument,
                  "camera " + id() + ": the simulated camera's trigger input is Line1, not '" + settings->trigger_line + "'"};
  return adjustments;
}

std::string SimCamera::SensorPixelFormat() const {
  const ColorCamera& color = world_->config().color;
  const std::string bits = std::to_string(world_->config().sensor.bit_depth);
  if (!color.IsOn()) return "Mono" + bits;
  // GenICam names a Bayer format by its first two filters: BayerRG = RGGB.
  return "Bayer" + color.mosaic.substr(0, 2) + bits;
}

Status SimCamera::DoStart() {
  {
    std::lock_guard lock(frames_mutex_);
    ready_.clear();
  }
  if (settings().trigger == drivers::TriggerMode::kHardware)
    world_->ConnectTriggerInput([this] { (void)Capture(); });
  return Status::Ok();
}

Status SimCamera::DoTrigger() { return Capture(); }

Status SimCamera::Capture() {
  std::lock_guard lock(frames_mutex_);
  if (link_lost_) return {StatusCode::kUnavailable, "camera " + id() + ": control link lost"};
  const CameraFaults& faults = world_->config().camera_faults;
  const std::uint64_t trigger = triggers_++;
  if (faults.disconnect_at.count(trigger)) {
    link_lost_ = true;
    return {StatusCode::kUnavailable, "camera " + id() + ": control link lost (injected fault)"};
  }
  if (faults.drop_frames.count(trigger)) {
    ++next_frame_id_;  // the device counted the frame; it never reached the host
    return Status::Ok();
  }
  const drivers::CameraSettings& s = settings();
  drivers::Frame frame = drivers::FrameTakenWith(s, s.width, s.height);
  frame.frame_id = next_frame_id_++;
  frame.device_timestamp_ns = NowNs(false);
  if (faults.repeat_frames.count(trigger) && !last_pixels_.empty()) {
    frame.pixels = last_pixels_;
  } else {
    const cv::Mat radiance = faults.lens_cap ? cv::Mat::zeros(s.height, s.width, CV_32F) : world_->RenderRadiance();
    // Noise seeded by the trigger count, which a reopen does not reset (frame
    // ids restart at 0): no two exposures of a camera share their noise.
    frame.pixels = ExposeFrame(world_->config().sensor, radiance, s.exposure_us, s.gain_db, world_->config().seed,
                               trigger);
  }
  last_pixels_ = frame.pixels;
  frame.host_timestamp_ns = NowNs(true);
  if (faults.short_frames.count(trigger)) frame.pixels.resize(frame.pixels.size() / 2);
  if (faults.corrupt_frames.count(trigger)) {
    // As a GigE camera with lost packets: the payload is damaged and the
    // buffer status says so.
    for (std::size_t i = 0; i < frame.pixels.size(); i += 7) frame.pixels[i] ^= 0x0a5a;
    corrupt_ids_.insert(frame.frame_id);
  }
  ready_.push_back(std::move(frame));
  return Status::Ok();
}

Result<drivers::Frame> SimCamera::DoWaitFrame(int timeout_ms) {
  std::lock_guard lock(frames_mutex_);
  if (link_lost_) return Status{StatusCode::kUnavailable, "camera " + id() + ": control link lost"};
  if (ready_.empty())
    return Status{StatusCode::kTimeout,
                  "camera " + id() + ": no frame within " + std::to_string(timeout_ms) + " ms (was it triggered?)"};
  drivers::Frame frame = std::move(ready_.front());
  ready_.pop_front();
  if (corrupt_ids_.erase(frame.frame_id))
    return Status{StatusCode::kDataLoss,
                  "camera " + id() + ": frame " + std::to_string(frame.frame_id) + " incomplete (missing packets)"};
  return frame;
}

Status SimCamera::DoStop() {
  world_->DisconnectTriggerInput();
  std::lock_guard lock(frames_mutex_);
  ready_.clear();
  return Status::Ok();
}

Status SimCamera::DoClose() { return Status::Ok(); }

SimTriggerLine::SimTriggerLine(std::string id, std::shared_ptr<World> world)
    : TriggerOutput(std::move(id)), world_(std::move(world)) {}

SimTriggerLine::~SimTriggerLine() { (void)Close(); }

// The wire carries no level between pulses, so there is nothing to deassert:
// the pulse is delivered whole, whatever its width.
Status SimTriggerLine::DoFire(std::chrono::microseconds) {
  if (!world_->PulseTriggerInput())
    return {StatusCode::kFailedPrecondition, "trigger " + id() + ": no camera armed for a hardware trigger on the wire"};
  return Status::Ok();
}

}  // namespace photorig::sim
