#pragma once
// What a compiled recipe will do before any device is touched: estimated
// duration (exposures, per-step overhead, arm moves) and data size, LED duty
// (flats and patterns light several LEDs at once), soft limits and arm
// separation at every pose, and the checks `photorig dry-run` and the
// daemon's admission make (limits, free disk space).

#include "photorig/config/recipe.h"
#include "photorig/config/solve_requests.h"
#include "photorig/config/rig.h"
#include "photorig/config/sim.h"
#include "photorig/config/yaml_node.h"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
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
  nlohmann::json ToJson(const std::vector<config::CaptureStep>& steps, std::size_t max_listed_steps = SIZE_MAX) const;
};

RunPlan PlanRun(const config::Recipe& recipe, const config::RigConfig& rig, const std::vector<config::CaptureStep>& steps,
                const PlanOptions& options = {});

// A pose as goniometer targets by axis id (light_arm, camera_arm, sample_rotation,
// and sample_changer when the pose sets it).
std::map<std::string, double> PoseTargets(const config::GonioPose& pose);

// The most memory compiling a plan of `frames` steps for a rig of `channels`
// LEDs and answering it with `listed` steps holds at once: the steps, their
// shared patterns and the answer's JSON (docs/daemon.md, "Plan memory").
std::uint64_t PlanMemoryBytes(std::size_t frames, std::size_t channels, std::size_t listed);

// Memory that plans being compiled may hold at once, shared by concurrent
// dry-runs and submits. Each reserves the worst case of its rig before
// compiling (a recipe's size is known only once it is expanded), shrinks the
// reservation to its plan's size once compiled and keeps it while its answer
// lives. A reservation of a large plan gives the freed memory back to the
// system when it ends, so the daemon's size falls back after a burst.
class PlanMemoryBudget {
 public:
  class Reservation {
   public:
    ~Reservation();
    Reservation(const Reservation&) = delete;
    Reservation& operator=(const Reservation&) = delete;
    // Keeps `bytes` (at most what is held) and gives the rest back.
    void Shrink(std::uint64_t bytes);
    std::uint64_t bytes() const { return bytes_; }

   private:
    friend class PlanMemoryBudget;
    struct Pool;
    Reservation(std::shared_ptr<Pool> pool, std::uint64_t bytes) : pool_(std::move(pool)), bytes_(bytes) {}
    std::shared_ptr<Pool> pool_;
    std::uint64_t bytes_;
  };

  explicit PlanMemoryBudget(std::uint64_t bytes);
  // `bytes` of the budget, waiting up to `wait` for them to be free; null
  // when they were not (the budget is spent: try again later). A request
  // larger than the whole budget waits until it is all free.
  std::shared_ptr<Reservation> Reserve(std::uint64_t bytes, std::chrono::milliseconds wait);

 private:
  std::shared_ptr<Reservation::Pool> pool_;
};

// Free bytes for an unprivileged writer on the filesystem holding `path`
// (or its nearest existing ancestor).
std::uint64_t FreeBytes(const std::string& path);

}  // namespace photorig::daemon
