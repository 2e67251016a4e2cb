#pragma once
// Runs compiled capture steps on open devices:
//   for each step: set the light pattern -> check it took -> trigger -> wait
//   for the frame -> lights off -> store the frame durably (the checkpoint).
// Steps already stored in the run (a resumed run) are skipped, so a run picks
// up at its last checkpoint. A transient device fault (timeout, disconnect,
// dropped or damaged frame, unanswered light command) suspends the run: the
// devices are closed, reopened after a backoff and the step is retried, up to
// the bounds of the RetryPolicy. An adaptive pose plan adds the steps of its
// next pass after the last step of a pass (CaptureOptions::next_pass); they
// run through the same code as every other step. On a gonioreflectometer a pose step first
// moves the arms (lights off) through the Goniometer, which refuses targets
// outside soft limits or separation before anything moves. Lights are
// switched off, the camera stopped and every axis stopped and closed on every
// exit path: normal end, device error, storage error, exception, pause and
// stop request.
// Every frame passes the capture health checks (frame_health.h) before it is
// stored: a frame that fails is retried like a transient fault (devices
// reopened, counting against the RetryPolicy); once a step's attempts are
// spent the run is bound to fail, but the remaining steps are still taken,
// once each, so the reason names every LED or frame that failed, and the
// healthy frames are stored. A failed frame is never stored, so a resumed
// run takes it again.

#include "photorig/daemon/capture/device_factory.h"
#include "photorig/daemon/capture/frame_health.h"
#include "photorig/config/recipe.h"
#include "photorig/config/solve_requests.h"
#include "photorig/daemon/capture/run_control.h"
#include "photorig/daemon/capture/run_store.h"
#include "photorig/drivers/camera.h"
#include "photorig/drivers/light_controller.h"
#include "photorig/drivers/trigger_output.h"

#include <atomic>
#include <functional>
#include <string>
#include <vector>

namespace photorig::daemon {

struct RetryPolicy {
  int max_attempts_per_step = 4;  // the first try included
  int max_retries_per_run = 20;   // over all steps
  int initial_backoff_ms = 50;    // before the first reopen; then multiplied by backoff_factor
  double backoff_factor = 2.0;
  int max_backoff_ms = 2000;

  bool IsValid(std::string* why) const;
};

struct CaptureOptions {
  int frame_timeout_margin_ms = 1000;  // added to the exposure when waiting for a frame
  // While a frame is awaited the lights hear KeepAlive this often, so that an
  // exposure longer than the safety layer's watchdog (5 s by default) is not
  // cut as a stalled sequencer would be.
  int lights_keepalive_ms = 1000;
  RetryPolicy retry;
  const std::atomic<bool>* stop_requested = nullptr;  // checked between steps (SIGTERM/SIGINT)
  RunControl* control = nullptr;                      // pause/resume/abort from another thread
  // Gonioreflectometers: the axes (opened and homed before the first step)
  // and the profile of every move. Null for a dome; required by pose steps.
  MotionRig* motion = nullptr;
  drivers::MotionProfile motion_profile;
  // Required when the camera config asks for a hardware trigger: fired once
  // per frame, after the lights are checked; closed (deasserted) on every exit.
  drivers::TriggerOutput* trigger_output = nullptr;
  // Thresholds of the health checks (the rig's `health:`), and the rig's
  // LEDs, which name them in messages and find each LED's neighbours.
  config::HealthConfig health;
  std::vector<config::LedConfig> leds;
  // Adaptive pose plans: after each step that ends a pass (CaptureStep::ends_pass),
  // once it is stored, with every step so far and the index of that one; the
  // steps returned are taken next (none: the plan is done). Also called for a
  // stored step of a resumed run, so it must give the same pass again from the
  // same frames. An exception it throws fails the run like a storage error.
  struct AddedSteps {
    std::vector<config::CaptureStep> steps;
    std::string detail;  // what the pass adds, for on_state
  };
  std::function<AddedSteps(const std::vector<config::CaptureStep>& steps, std::size_t ended, const RunWriter& writer)> next_pass;
  std::function<void(const config::CaptureStep&, const FrameRecord&, int total)> on_frame;
  // Every state change of the run: kRunning, kPaused, kSuspended (detail: the fault), kAborting.
  std::function<void(RunState, const std::string& detail)> on_state;
};

struct CaptureReport {
  CaptureStatus status = CaptureStatus::kFailed;  // kComplete, kFailed or kAborted
  std::string reason;
  // What ended a failed capture, e.g. kUnavailable for a device that cannot
  // be reached or opened; kOk otherwise.
  StatusCode fault = StatusCode::kOk;
  int frames_written = 0;   // by this call
  int frames_resumed = 0;   // already in the run when this call started
  int steps_total = 0;  // with the steps adaptive passes added
  int retries = 0;
  int dropped_frames = 0;   // frames that timed out or arrived damaged
  int frames_rejected = 0;  // frames that failed a health check (retries included), never stored
  std::vector<HealthFinding> health;  // the checks that failed the run; `reason` describes them
  double elapsed_ms = 0.0;
  std::vector<drivers::SettingAdjustment> adjustments;

  StopRecord ToStopRecord() const;
};

// Opens, configures and closes the devices itself. Never throws for device
// faults: they end the run with status kFailed and a reason naming the device.
CaptureReport RunCapture(const std::vector<config::CaptureStep>& steps, const config::CameraConfig& camera_config,
                         drivers::LightController& lights, drivers::Camera& camera, RunWriter& writer,
                         const CaptureOptions& options);

}  // namespace photorig::daemon
