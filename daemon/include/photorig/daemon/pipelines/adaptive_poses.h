#pragma once
// The passes of an adaptive pose plan during a capture: after the coarse
// poses (and after each added pass), the frames taken so far become BRDF
// samples (MeasureBrdf on the partial run), ProposeDenserPoses picks the
// reachable configurations that split the intervals where log f_r changes
// most, planned in a safe order from where the arms stand, and they become
// the next pass's steps: the plan step's bracket and count, labelled and
// stored like any pose frame, with the pass in each frame's record.

#include "photorig/config/recipe.h"
#include "photorig/config/solve_requests.h"
#include "photorig/daemon/capture/sequencer.h"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace photorig::daemon {

struct AdaptivePassReport {
  int pass = 0;         // 1 = the first pass after the coarse one
  int samples = 0;      // the measured samples the proposal read
  int poses_added = 0;  // at most the plan's added_poses
  int frames_added = 0;
  int unreachable = 0;  // midpoints of high-scoring intervals the arms cannot reach
  // Why this pass added fewer poses than asked, or none (then the plan ends
  // here): nothing left to split, or the partial run could not be measured.
  // Empty when it added all it asked for.
  std::string stopped;

  nlohmann::json ToJson() const;
};

class AdaptivePoses {
 public:
  // `group` is the recipe's adaptive poses group (AdaptivePlanGroup); the
  // recipe, rig and group must outlive this.
  AdaptivePoses(const config::Recipe& recipe, const config::Recipe::Group& group, const config::RigConfig& rig);

  // CaptureOptions::next_pass. Deterministic in the stored frames of steps up
  // to `ended`, so a resumed run gets the same passes again.
  CaptureOptions::AddedSteps NextPass(const std::vector<config::CaptureStep>& steps, std::size_t ended, const RunWriter& writer);

  // Each pass tried, in order (a resumed run reports the passes again).
  const std::vector<AdaptivePassReport>& passes() const { return passes_; }

 private:
  const config::Recipe& recipe_;
  const config::Recipe::Group& group_;
  const config::RigConfig& rig_;
  std::vector<AdaptivePassReport> passes_;
};

}  // namespace photorig::daemon
