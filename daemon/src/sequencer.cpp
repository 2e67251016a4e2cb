#include "photorig/daemon/sequencer.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>

namespace photorig::daemon {
namespace {

// Owns the "devices are safe" guarantee: whatever happens inside the scope,
// the dome goes dark and the camera stops and closes.
class DeviceGuard {
 public:
  DeviceGuard(drivers::LightController& lights, drivers::Camera& camera) : lights_(lights), camera_(camera) {}
  ~DeviceGuard() {
    const Status off = lights_.Close();
    if (!off.ok()) spdlog::error("could not switch the lights off: {}", off.ToString());
    const Status closed = camera_.Close();
    if (!closed.ok()) spdlog::warn("camera close: {}", closed.ToString());
  }

 private:
  drivers::LightController& lights_;
  drivers::Camera& camera_;
};

struct StepFailure {
  std::string reason;
};

void Check(const Status& status) {
  if (!status.ok()) throw StepFailure{status.ToString()};
}

}  // namespace

CaptureReport RunCapture(const std::vector<CaptureStep>& steps, const CameraConfig& camera_config,
                         drivers::LightController& lights, drivers::Camera& camera, RunWriter& writer,
                         const CaptureOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  CaptureReport report;
  report.steps_total = static_cast<int>(steps.size());
  try {
    DeviceGuard guard(lights, camera);
    Check(lights.Open());
    Check(camera.Open());
    drivers::CameraSettings settings;
    settings.width = camera_config.width;
    settings.height = camera_config.height;
    settings.bit_depth = camera_config.bit_depth;
    settings.exposure_us = steps.empty() ? camera_config.exposure_us : steps.front().exposure_us;
    settings.gain_db = steps.empty() ? camera_config.gain_db : steps.front().gain_db;
    auto adjustments = camera.Configure(settings);
    Check(adjustments.status());
    report.adjustments = adjustments.value();
    for (const auto& a : report.adjustments)
      spdlog::warn("camera {}: {} {} -> {} ({})", camera.id(), a.field, a.requested, a.applied, a.reason);
    Check(camera.Start());
    for (const CaptureStep& step : steps) {
      if (options.stop_requested && options.stop_requested->load()) {
        report.status = "aborted";
        report.reason = "stop requested before step " + step.label;
        break;
      }
      if (step.exposure_us != camera.settings().exposure_us || step.gain_db != camera.settings().gain_db) {
        Check(camera.Stop());
        settings.exposure_us = step.exposure_us;
        settings.gain_db = step.gain_db;
        Check(camera.Configure(settings).status());
        Check(camera.Start());
      }
      Check(lights.SetPattern(step.pattern));
      Check(camera.Trigger());
      const int timeout_ms =
          static_cast<int>(std::ceil(step.exposure_us / 1000.0)) + options.frame_timeout_margin_ms;
      auto frame = camera.WaitFrame(timeout_ms);
      // Lights off before anything else can fail, so no LED stays on longer than one exposure.
      Check(lights.AllOff());
      Check(frame.status());
      const FrameRecord& record = writer.WriteFrame(step, frame.value());
      ++report.frames_written;
      if (options.on_frame) options.on_frame(step, record, report.steps_total);
    }
    if (report.status.empty()) report.status = "complete";
  } catch (const StepFailure& failure) {
    report.status = "failed";
    report.reason = failure.reason;
  } catch (const std::exception& e) {
    report.status = "failed";
    report.reason = e.what();
  }
  report.elapsed_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return report;
}

}  // namespace photorig::daemon
