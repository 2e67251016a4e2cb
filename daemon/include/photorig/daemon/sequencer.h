#pragma once
// Runs compiled capture steps on open devices:
//   for each step: set the light pattern -> trigger -> wait for the frame ->
//   lights off -> store the frame durably.
// Lights are switched off and the camera stopped on every exit path: normal
// end, device error, storage error, exception and stop request.

#include "photorig/daemon/recipe.h"
#include "photorig/daemon/run_store.h"
#include "photorig/drivers/camera.h"
#include "photorig/drivers/light_controller.h"

#include <atomic>
#include <functional>
#include <string>
#include <vector>

namespace photorig::daemon {

struct CaptureOptions {
  int frame_timeout_margin_ms = 1000;  // added to the exposure when waiting for a frame
  const std::atomic<bool>* stop_requested = nullptr;  // checked between steps
  std::function<void(const CaptureStep&, const FrameRecord&, int total)> on_frame;
};

struct CaptureReport {
  std::string status;  // complete | failed | aborted
  std::string reason;
  int frames_written = 0;
  int steps_total = 0;
  double elapsed_ms = 0.0;
  std::vector<drivers::SettingAdjustment> adjustments;
};

// Opens, configures and closes the devices itself. Never throws for device
// faults: they end the run with status "failed" and a reason naming the device.
CaptureReport RunCapture(const std::vector<CaptureStep>& steps, const CameraConfig& camera_config,
                         drivers::LightController& lights, drivers::Camera& camera, RunWriter& writer,
                         const CaptureOptions& options);

}  // namespace photorig::daemon
