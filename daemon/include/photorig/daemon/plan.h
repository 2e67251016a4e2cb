#pragma once
// What a compiled recipe will do before any device is touched: estimated
// duration (exposures, per-step overhead, arm moves) and data size, LED duty
// (flats and patterns light several LEDs at once), soft limits and arm
// separation at every pose, and the checks `photorig dry-run` and the
// daemon's admission make (limits, free disk space).

#include "photorig/daemon/recipe.h"
#include "photorig/daemon/rig_config.h"

#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace photorig::daemon {

struct PlanOptions {
  // Per-step time besides the exposure: light switching, trigger latency,
  // readout and the durable write. A conservative figure for the sim and
  // GigE cameras at 1 MP; measured per rig it tightens the estimate.
  double step_overhead_ms = 40.0;
  double max_led_duty = 1.0;  // highest fraction of the run any LED may be lit, in (0, 1]

  bool IsValid(std::string* why) const;
};

struct RunEstimate {
  int frames = 0;
  double duration_s = 0.0;
  std::uint64_t bytes_per_frame = 0;  // upper bound: uncompressed 16-bit pixels plus file overhead
  std::uint64_t bytes = 0;            // frames, ground truth, journal and manifest
};

// An adaptive pose plan's passes, at their largest: every pass adds all its
// poses, each taken with the plan step's bracket and count, and each move at
// most as long as the coarse plan's whole range of each arm (the added
// configurations split intervals between coarse ones, so the arms stay in
// that range).
struct AdaptiveBound {
  int coarse_poses = 0;
  int passes = 0;
  int added_poses = 0;  // per pass
  int max_frames = 0;
  double max_duration_s = 0.0;
  std::uint64_t max_bytes = 0;
};

struct RunPlan {
  RunEstimate estimate;  // the steps compiled; bytes also holds the adaptive passes at their largest
  std::optional<AdaptiveBound> adaptive;
  double move_s = 0.0;        // of estimate.duration_s: arm moves and settling
  double max_led_duty = 0.0;  // over all LEDs
  int max_duty_led = -1;      // its LED id
  std::vector<std::string> errors;    // the run must not start
  std::vector<std::string> warnings;

  bool ok() const { return errors.empty(); }
  // The step list holds the first `max_listed_steps` steps ("steps_listed"
  // says how many); the figures always cover all of them.
  nlohmann::json ToJson(const std::vector<CaptureStep>& steps, std::size_t max_listed_steps = SIZE_MAX) const;
};

RunPlan PlanRun(const Recipe& recipe, const RigConfig& rig, const std::vector<CaptureStep>& steps,
                const PlanOptions& options = {});

// A pose as goniometer targets by axis id (light_arm, camera_arm, sample_rotation,
// and sample_changer when the pose sets it).
std::map<std::string, double> PoseTargets(const GonioPose& pose);

// Free bytes for an unprivileged writer on the filesystem holding `path`
// (or its nearest existing ancestor).
std::uint64_t FreeBytes(const std::string& path);

}  // namespace photorig::daemon
