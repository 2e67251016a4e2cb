#include "photorig/daemon/capture/sequencer.h"

#include "photorig/daemon/capture/plan.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <thread>

namespace photorig::daemon {
using solvers::core::Refuse;

namespace {

// A light command can fail transiently (that is one of the faults we retry),
// so switching off gets a few tries before Close, which switches off once more.
void SwitchOffAndClose(drivers::LightController& lights) {
  if (lights.state() == drivers::LightController::State::kClosed) return;
  for (int attempt = 0; attempt < 3; ++attempt)
    if (lights.AllOff().ok()) break;
  const Status off = lights.Close();
  if (!off.ok()) spdlog::error("could not switch the lights off: {}", off.ToString());
}

// Owns the "devices are safe" guarantee: whatever happens inside the scope,
// the dome goes dark and the camera stops and closes.
class DeviceGuard {
 public:
  DeviceGuard(drivers::LightController& lights, drivers::Camera& camera, MotionRig* motion,
              drivers::TriggerOutput* trigger)
      : lights_(lights), camera_(camera), motion_(motion), trigger_(trigger) {}
  ~DeviceGuard() { Release(); }
  void Release() {
    if (trigger_) {
      if (Status closed = trigger_->Close(); !closed.ok())
        spdlog::error("could not release the trigger output {}: {}", trigger_->id(), closed.ToString());
    }
    if (motion_ && motion_->goniometer) {
      // Close stops each drive first; StopAll before it halts every arm before any closes.
      (void)motion_->goniometer->StopAll();
      if (Status closed = motion_->goniometer->CloseAll(); !closed.ok())
        spdlog::error("could not stop and close the motion axes: {}", closed.ToString());
    }
    SwitchOffAndClose(lights_);
    if (camera_.state() != drivers::Camera::State::kClosed) {
      const Status closed = camera_.Close();
      if (!closed.ok()) spdlog::warn("camera close: {}", closed.ToString());
    }
  }

 private:
  drivers::LightController& lights_;
  drivers::Camera& camera_;
  MotionRig* motion_;
  drivers::TriggerOutput* trigger_;
};

// Faults worth a reopen and a retry; anything else (bad settings, a light
// that does not do what it is told) will not get better by trying again.
bool IsTransient(const Status& status) {
  return status.code() == StatusCode::kTimeout || status.code() == StatusCode::kUnavailable ||
         status.code() == StatusCode::kDataLoss;
}

class Capture {
 public:
  Capture(const std::vector<config::CaptureStep>& steps, const config::CameraConfig& camera_config,
          drivers::LightController& lights, drivers::Camera& camera, RunWriter& writer, const CaptureOptions& options,
          CaptureReport& report)
      : camera_config_(camera_config), lights_(lights), camera_(camera), writer_(writer), options_(options),
        report_(report), health_(options.health, steps, options.leds) {}

  bool StopRequested() const {
    return (options_.stop_requested && options_.stop_requested->load()) ||
           (options_.control && options_.control->abort_requested());
  }

  void Notify(RunState state, const std::string& detail) const {
    if (options_.on_state) options_.on_state(state, detail);
  }

  // Sleeps in short slices so that SIGTERM and abort both cut it short.
  bool Sleep(int ms) const {
    const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(ms);
    while (!StopRequested()) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(until - std::chrono::steady_clock::now());
      if (left.count() <= 0) return true;
      const int slice = static_cast<int>(std::min<std::int64_t>(left.count(), 20));
      if (options_.control) {
        options_.control->SleepUnlessAborted(slice);
      } else {
        std::this_thread::sleep_for(std::chrono::milliseconds(slice));
      }
    }
    return false;
  }

  // Returns false when a stop arrived while paused.
  bool HoldWhilePaused() const {
    if (!options_.control || !options_.control->paused()) return true;
    Notify(RunState::kPaused, "");
    while (options_.control->paused())
      if (!Sleep(20)) return false;
    Notify(RunState::kRunning, "resumed");
    return true;
  }

  Status OpenDevices(const config::CaptureStep& first) {
    if (lights_.state() == drivers::LightController::State::kClosed)
      if (Status s = lights_.Open(); !s.ok()) return s;
    if (camera_.state() != drivers::Camera::State::kClosed) (void)camera_.Close();
    if (Status s = camera_.Open(); !s.ok()) return s;
    settings_.width = camera_config_.width;
    settings_.height = camera_config_.height;
    settings_.bit_depth = camera_config_.bit_depth;
    settings_.pixel_format = camera_config_.pixel_format;
    settings_.exposure_us = first.exposure_us;
    settings_.gain_db = first.gain_db;
    settings_.trigger = camera_config_.trigger.mode;
    settings_.trigger_line = camera_config_.trigger.line;
    if (settings_.trigger == drivers::TriggerMode::kHardware) {
      if (!options_.trigger_output)
        return {StatusCode::kFailedPrecondition,
                "camera " + camera_.id() + " is set for a hardware trigger but the rig has no trigger output"};
      if (options_.trigger_output->state() == drivers::TriggerOutput::State::kClosed)
        if (Status s = options_.trigger_output->Open(); !s.ok()) return s;
    }
    auto adjustments = camera_.Configure(settings_);
    if (!adjustments.ok()) return adjustments.status();
    if (report_.adjustments.empty()) {
      report_.adjustments = adjustments.value();
      for (const auto& a : report_.adjustments)
        spdlog::warn("camera {}: {} {} -> {} ({})", camera_.id(), a.field, a.requested, a.applied, a.reason);
    }
    if (Status s = camera_.Start(); !s.ok()) return s;
    return OpenMotion();
  }

  // Opens and homes the axes; after a fault the axes that are still good
  // stay open and homed, and a faulted one is cleared, which loses its
  // position, so all are homed again before the retried step moves them.
  Status OpenMotion() {
    if (!options_.motion || !options_.motion->goniometer) return Status::Ok();
    bool home = false;
    for (auto& axis : options_.motion->axes) {
      if (axis->state() == drivers::Motion::State::kClosed)
        if (Status s = axis->Open(); !s.ok()) return s;
      if (axis->state() == drivers::Motion::State::kFault)
        if (Status s = axis->ClearFault(); !s.ok()) return s;
      home = home || axis->state() == drivers::Motion::State::kOpen;
    }
    return home ? options_.motion->goniometer->HomeAll() : Status::Ok();
  }

  Status FireTrigger() {
    if (settings_.trigger != drivers::TriggerMode::kHardware) return camera_.Trigger();
    return options_.trigger_output->Fire(std::chrono::microseconds(camera_config_.trigger.pulse_us));
  }

  // Leaves the devices closed and dark after a fault; they are reopened before the retry.
  void CloseAfterFault() {
    if (options_.trigger_output) (void)options_.trigger_output->Close();
    if (options_.motion && options_.motion->goniometer) (void)options_.motion->goniometer->StopAll();
    SwitchOffAndClose(lights_);
    if (camera_.state() != drivers::Camera::State::kClosed) (void)camera_.Close();
  }

  Status CheckPattern(const drivers::LightPattern& pattern) {
    auto actual = lights_.ReadBack();
    if (!actual.ok()) return actual.status();
    for (std::size_t channel = 0; channel < pattern.levels.size(); ++channel) {
      const double got = channel < actual->levels.size() ? actual->levels[channel] : 0.0;
      if (std::abs(got - pattern.levels[channel]) > 1e-6)
        return {StatusCode::kInternal, "light controller " + lights_.id() + ": channel " + std::to_string(channel) +
                                           " reads back " + std::to_string(got) + " after being set to " +
                                           std::to_string(pattern.levels[channel])};
    }
    return Status::Ok();
  }

  // One step: a frame on disk and in the journal, or the device status that
  // prevented it, or (status ok) the health check the frame failed, unstored.
  // Waits for the frame in slices of lights_keepalive_ms, telling the lights
  // between them that the sequencer is alive.
  Result<drivers::Frame> WaitFrameKeepingLightsAlive(int timeout_ms) {
    const int slice_ms = std::max(1, options_.lights_keepalive_ms);
    for (int remaining_ms = timeout_ms;;) {
      const int wait_ms = std::min(remaining_ms, slice_ms);
      auto frame = camera_.WaitFrame(wait_ms);
      remaining_ms -= wait_ms;
      if (frame.ok() || frame.status().code() != StatusCode::kTimeout || remaining_ms <= 0) return frame;
      if (Status alive = lights_.KeepAlive(); !alive.ok()) return alive;
    }
  }

  Status Step(const config::CaptureStep& step, std::optional<HealthFinding>* unhealthy) {
    if (step.exposure_us != camera_.settings().exposure_us || step.gain_db != camera_.settings().gain_db) {
      if (Status s = camera_.Stop(); !s.ok()) return s;
      settings_.exposure_us = step.exposure_us;
      settings_.gain_db = step.gain_db;
      if (Status s = camera_.Configure(settings_).status(); !s.ok()) return s;
      if (Status s = camera_.Start(); !s.ok()) return s;
    }
    if (step.pose) {
      if (!options_.motion || !options_.motion->goniometer)
        return {StatusCode::kFailedPrecondition, "step " + step.label + " is a pose but the rig has no motion"};
      if (Status s = options_.motion->goniometer->MoveTo(PoseTargets(*step.pose), options_.motion_profile); !s.ok())
        return s;
    }
    if (Status s = lights_.SetPattern(*step.pattern); !s.ok()) return s;
    if (Status s = CheckPattern(*step.pattern); !s.ok()) {
      (void)lights_.AllOff();
      return s;
    }
    if (Status s = FireTrigger(); !s.ok()) {
      (void)lights_.AllOff();
      return s;
    }
    const int timeout_ms = static_cast<int>(std::ceil(step.exposure_us / 1000.0)) + options_.frame_timeout_margin_ms;
    auto frame = WaitFrameKeepingLightsAlive(timeout_ms);
    // Lights off before anything else can fail, so no LED stays on longer than one exposure.
    const Status off = lights_.AllOff();
    if (!frame.ok()) return frame.status();
    if (!off.ok()) return off;
    const drivers::Frame& pixels = frame.value();
    const bool measurable = health_.enabled() && pixels.pixels.size() == static_cast<std::size_t>(pixels.width) * pixels.height;
    const cv::Mat view = measurable ? cv::Mat(pixels.height, pixels.width, CV_16U,
                                              const_cast<std::uint16_t*>(pixels.pixels.data()))
                                    : cv::Mat();
    const FrameStats stats = measurable ? health_.Measure(view, pixels.bit_depth) : FrameStats{};
    if (measurable) {
      *unhealthy = health_.Judge(step, stats);
      if (*unhealthy) {
        ++report_.frames_rejected;
        return Status::Ok();
      }
    }
    const FrameRecord& record = writer_.WriteFrame(step, pixels);  // throws on storage failure
    if (measurable) health_.Accept(step, view, stats);
    ++report_.frames_written;
    if (options_.on_frame) options_.on_frame(step, record, report_.steps_total);
    return Status::Ok();
  }

  // A frame stored before this call (a resumed run) is a reference like any other.
  void AcceptStored(const config::CaptureStep& step) {
    if (!health_.enabled()) return;
    for (const FrameRecord& record : writer_.manifest().frames)
      if (record.index == step.index) {
        const cv::Mat frame = LoadFrame(writer_.directory(), record);
        health_.Accept(step, frame, health_.Measure(frame, record.bit_depth));
        return;
      }
  }

  // A device fault that ends the run; health findings so far go with it.
  void Fail(std::string reason) {
    if (!report_.health.empty()) reason += "; also " + FrameHealth::Describe(report_.health);
    report_.status = CaptureStatus::kFailed;
    report_.reason = std::move(reason);
  }

  // After step `ended` (stored now or before a resume): an adaptive plan's
  // next pass goes in right after it.
  void AddNextPass(std::vector<config::CaptureStep>& steps, std::size_t ended) {
    if (!steps[ended].ends_pass || !options_.next_pass) return;
    CaptureOptions::AddedSteps added = options_.next_pass(steps, ended, writer_);
    if (!added.detail.empty()) Notify(RunState::kRunning, added.detail);
    if (added.steps.empty()) return;
    health_.AddSteps(added.steps);
    report_.steps_total += static_cast<int>(added.steps.size());
    steps.insert(steps.begin() + static_cast<std::ptrdiff_t>(ended + 1), added.steps.begin(), added.steps.end());
  }

  void Run(std::vector<config::CaptureStep> steps) {
    const RetryPolicy& retry = options_.retry;
    bool devices_open = false;
    // Once a step has failed its health checks on every attempt, the run
    // will fail; the rest is taken once per step, so the reason can name
    // every LED that did not light, not only the first.
    bool surveying = false;
    int attempts = 0;  // failed attempts at the current step
    int backoff_ms = retry.initial_backoff_ms;
    for (std::size_t i = 0; i < steps.size();) {
      const config::CaptureStep& step = steps[i];
      if (writer_.HasFrame(step.index)) {
        AcceptStored(step);
        AddNextPass(steps, i);
        ++i;
        continue;
      }
      if (StopRequested() || !HoldWhilePaused()) {
        Notify(RunState::kAborting, "");
        report_.status = CaptureStatus::kAborted;
        report_.reason = "stop requested before step " + step.label;
        return;
      }
      Status status = devices_open ? Status::Ok() : OpenDevices(step);
      devices_open = status.ok();
      std::optional<HealthFinding> unhealthy;
      if (status.ok()) status = Step(step, &unhealthy);
      if (status.ok() && !unhealthy) {
        if (!surveying) AddNextPass(steps, i);  // a run bound to fail adds no pass
        ++i;
        attempts = 0;
        backoff_ms = retry.initial_backoff_ms;
        continue;
      }
      ++attempts;
      std::string fault;
      if (unhealthy) {
        // A frame can fail for a passing cause (a controller that dropped its
        // state, a stale buffer), so it is retried like a transient fault.
        fault = FrameHealth::Describe({*unhealthy});
        if (surveying || attempts >= retry.max_attempts_per_step || report_.retries >= retry.max_retries_per_run) {
          spdlog::error("step {}: {}", step.label, fault);
          report_.health.push_back(*unhealthy);
          surveying = true;
          ++i;
          attempts = 0;
          backoff_ms = retry.initial_backoff_ms;
          continue;
        }
      } else {
        if (status.code() == StatusCode::kTimeout || status.code() == StatusCode::kDataLoss) ++report_.dropped_frames;
        if (!IsTransient(status) || attempts >= retry.max_attempts_per_step ||
            report_.retries >= retry.max_retries_per_run) {
          report_.fault = status.code();
          Fail((IsTransient(status) ? "step " + step.label + " failed " + std::to_string(attempts) + " times; last: "
                                    : "step " + step.label + ": ") +
               status.ToString());
          return;
        }
        fault = status.ToString();
      }
      ++report_.retries;
      spdlog::warn("step {}: {}; retry {} in {} ms", step.label, fault, attempts, backoff_ms);
      Notify(RunState::kSuspended, fault);
      CloseAfterFault();
      devices_open = false;
      if (!Sleep(backoff_ms)) continue;  // the stop check at the top of the loop ends the run
      backoff_ms = std::min(retry.max_backoff_ms, static_cast<int>(backoff_ms * retry.backoff_factor));
      Notify(RunState::kRunning, "retrying step " + step.label);
    }
    for (HealthFinding& dim : health_.CompareNeighbours()) report_.health.push_back(std::move(dim));
    if (!report_.health.empty()) {
      report_.status = CaptureStatus::kFailed;
      report_.reason = FrameHealth::Describe(report_.health);
      return;
    }
    report_.status = CaptureStatus::kComplete;
  }

 private:
  const config::CameraConfig& camera_config_;
  drivers::LightController& lights_;
  drivers::Camera& camera_;
  RunWriter& writer_;
  const CaptureOptions& options_;
  CaptureReport& report_;
  FrameHealth health_;
  drivers::CameraSettings settings_;
};

}  // namespace

bool RetryPolicy::IsValid(std::string* why) const {
  if (max_attempts_per_step < 1) return Refuse(why, "max_attempts_per_step must be >= 1");
  if (max_retries_per_run < 0) return Refuse(why, "max_retries_per_run must be >= 0");
  if (initial_backoff_ms < 0 || max_backoff_ms < initial_backoff_ms)
    return Refuse(why, "backoff must satisfy 0 <= initial_backoff_ms <= max_backoff_ms");
  if (!(backoff_factor >= 1.0)) return Refuse(why, "backoff_factor must be >= 1");
  return true;
}

StopRecord CaptureReport::ToStopRecord() const {
  return {status, reason, frames_resumed + frames_written, steps_total, retries, dropped_frames};
}

CaptureReport RunCapture(const std::vector<config::CaptureStep>& steps, const config::CameraConfig& camera_config,
                         drivers::LightController& lights, drivers::Camera& camera, RunWriter& writer,
                         const CaptureOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  CaptureReport report;
  report.steps_total = static_cast<int>(steps.size());
  report.frames_resumed = static_cast<int>(writer.manifest().frames.size());
  try {
    DeviceGuard guard(lights, camera, options.motion, options.trigger_output);
    std::string why;
    if (!options.retry.IsValid(&why)) throw std::invalid_argument("retry policy: " + why);
    Capture(steps, camera_config, lights, camera, writer, options, report).Run(steps);
  } catch (const std::exception& e) {
    report.status = CaptureStatus::kFailed;
    report.reason = e.what();
  }
  report.elapsed_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return report;
}

}  // namespace photorig::daemon
