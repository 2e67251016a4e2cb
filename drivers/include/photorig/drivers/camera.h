#pragma once
// Camera interface: an explicit state machine
//
//   Closed --Open--> Open --Configure--> Configured --Start--> Streaming
//     ^                |  ^                  |   ^                 |
//     +------Close-----+  +----Configure-----+   +------Stop-------+
//
// The public methods check the transition and then call the implementation's
// Do* hook, so every driver (real or simulated) shares the same rules: an
// illegal transition returns kFailedPrecondition and changes nothing.

#include "photorig/drivers/device.h"
#include "photorig/drivers/status.h"

#include <cstdint>
#include <string>
#include <vector>

namespace photorig::drivers {

enum class TriggerMode { kSoftware, kHardware, kFreeRun };

struct CameraSettings {
  int width = 0;   // 0 = the sensor's full width
  int height = 0;  // 0 = the sensor's full height
  int bit_depth = 12;
  double exposure_us = 10000.0;
  double gain_db = 0.0;
  TriggerMode trigger = TriggerMode::kSoftware;
  std::string trigger_line;  // kHardware: the input the pulse arrives on, e.g. "Line1"
  std::string pixel_format;  // GenICam name ("Mono12", "BayerRG8"); empty = "Mono<bit_depth>"
};

// One field the camera could not take as asked, and what it used instead.
struct SettingAdjustment {
  std::string field;
  double requested = 0.0;
  double applied = 0.0;
  std::string reason;
};

struct Frame {
  int width = 0;
  int height = 0;
  int bit_depth = 0;               // significant bits in each 16-bit sample
  std::vector<std::uint16_t> pixels;  // row-major, width * height
  std::uint64_t frame_id = 0;      // device counter; gaps mean dropped frames
  std::int64_t device_timestamp_ns = 0;
  std::int64_t host_timestamp_ns = 0;  // CLOCK_REALTIME when the frame arrived
  double exposure_us = 0.0;
  double gain_db = 0.0;
  std::string pixel_format;        // GenICam name, e.g. "Mono12"
  std::uint64_t dropped_before = 0;  // frames the device counted since the previous delivered one but never delivered
};

// A `width` x `height` frame taken with `settings`: its size, bit depth, pixel
// format, exposure and gain. The driver adds the pixels, counters and stamps.
Frame FrameTakenWith(const CameraSettings& settings, int width, int height);

// What discovery reports about a camera it can see (`photorig devices`).
// Fields a driver could not read stay empty or 0; `error` says why.
struct CameraInfo {
  std::string driver;   // factory name: "aravis", "v4l2"
  std::string id;       // what the driver's `device` option accepts
  std::string vendor, model, serial, address;
  int sensor_width = 0, sensor_height = 0;
  std::vector<std::string> pixel_formats;
  double exposure_min_us = 0.0, exposure_max_us = 0.0;
  std::string error;
};

class Camera : public Device {
 public:
  enum class State { kClosed, kOpen, kConfigured, kStreaming };

  explicit Camera(std::string id) : Device("camera", std::move(id)) {}
  virtual ~Camera() = default;

  State state() const { return state_; }

  Status Open();
  // Validates the settings against the device, applies them and reports every
  // value it had to change (rounded exposure, clamped gain, ...).
  Result<std::vector<SettingAdjustment>> Configure(const CameraSettings& settings);
  Status Start();
  Status Trigger();  // software trigger; only in kStreaming with TriggerMode::kSoftware
  Result<Frame> WaitFrame(int timeout_ms);
  Status Stop();
  Status Close();  // from any state; stops streaming first

  const CameraSettings& settings() const { return settings_; }

 protected:
  virtual Status DoOpen() = 0;
  virtual Result<std::vector<SettingAdjustment>> DoConfigure(CameraSettings* settings) = 0;
  virtual Status DoStart() = 0;
  virtual Status DoTrigger() = 0;
  virtual Result<Frame> DoWaitFrame(int timeout_ms) = 0;
  virtual Status DoStop() = 0;
  virtual Status DoClose() = 0;

  Status IllegalTransition(const char* action) const;

 private:
  State state_ = State::kClosed;
  CameraSettings settings_;
};

const char* CameraStateName(Camera::State state);

// The colour filter a GenICam pixel format implies: "mono" (Mono*), the Bayer
// pattern of the top-left 2 x 2 block ("RGGB" for BayerRG*, "GRBG", "GBRG",
// "BGGR"), "RGB" (RGB8, RGB16); "" for a format not listed.
std::string MosaicOfPixelFormat(const std::string& pixel_format);
// Significant bits per sample of those formats (BayerRG12 -> 12); 0 otherwise.
int BitsOfPixelFormat(const std::string& pixel_format);

}  // namespace photorig::drivers
