#pragma once
// Capture health checks: does each frame show what its step asked for? Pure
// computation on the frame, the run's dark frames and what the plan says the
// step is (which LEDs, which exposure). The sequencer judges every frame
// before storing it and compares the LEDs with each other once the capture
// is in (docs/daemon.md, "Capture health checks").
//
//   kNoLight      a lit step whose brightest pixel does not rise lit_sigma
//                 noise sigmas above the dark (LEDs off, board unpowered, lens cap)
//   kLightInDark  a dark frame whose mean rises lit_sigma sigmas above the
//                 darks before it (an LED stuck on, room light)
//   kClipped      more than max_clipped_fraction of the pixels clipped
//   kRepeated     pixel for pixel the previous frame stored, which showed
//                 another pattern, exposure or pose (a stale buffer)
//   kBrightness   off by more than max_brightness_ratio from what an earlier
//                 frame of the same pattern predicts for this exposure
//   kDimLed       an LED whose response is below min_neighbour_ratio of the
//                 median of its nearest neighbours (by direction)

#include "photorig/config/recipe.h"
#include "photorig/config/solve_requests.h"

#include <opencv2/core.hpp>

#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace photorig::daemon {

// 1.4826 x the median absolute deviation of a CV_32F image's values (every
// channel): the standard deviation of Gaussian noise, unmoved by a few bright pixels; 0 for no values.
double RobustSigma(const cv::Mat& values);


enum class HealthCheck { kNoLight, kLightInDark, kClipped, kRepeated, kBrightness, kDimLed };

// What one frame measured, in DN.
struct FrameStats {
  static constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();
  double mean_response_dn = kUnknown;  // mean over the frame above the dark; unknown before a dark
  double peak_response_dn = kUnknown;  // brightest pixel above the dark
  double clipped_fraction = 0.0;       // pixels at or above HealthConfig::saturation_dn
  std::uint64_t pixel_hash = 0;
  bool uniform = false;                // every pixel the same code (nothing to call repeated)
};

struct HealthFinding {
  HealthCheck check = HealthCheck::kNoLight;
  int step_index = -1;
  std::string label;      // the frame's label, e.g. "0003_led02"
  int led_id = -1;        // the rig id of the LED a single-LED step lights; -1 otherwise
  double value = 0.0;     // the statistic the check tests (see Describe for its unit)
  double threshold = 0.0; // what it had to reach (or stay within)
  double noise_sigma_dn = 0.0;  // kNoLight, kLightInDark: the sigma the threshold counts in
  double mean_response_dn = 0.0;
  std::string reference;  // kBrightness: the earlier frame; kDimLed: the neighbours compared
};

class FrameHealth {
 public:
  // `steps`: the whole plan (for brackets); `leds`: the rig's LEDs (CaptureStep::led
  // indexes them), for LED ids in messages and the neighbour comparison.
  FrameHealth(config::HealthConfig health, const std::vector<config::CaptureStep>& steps,
              std::vector<config::LedConfig> leds);

  // Steps added to the plan while it runs (an adaptive pose plan's passes): brackets among them.
  void AddSteps(const std::vector<config::CaptureStep>& steps);

  bool enabled() const { return config_.enabled; }

  // One pass over a CV_16U frame against the current dark reference.
  FrameStats Measure(const cv::Mat& frame, int bit_depth) const;
  // The first check `stats` of `step` fails, against the frames accepted
  // before it; nullopt when healthy.
  std::optional<HealthFinding> Judge(const config::CaptureStep& step, const FrameStats& stats) const;
  // A stored frame: darks refine the dark level and its noise, lit frames
  // become the reference for later frames of their pattern and for the LED
  // comparison.
  void Accept(const config::CaptureStep& step, const cv::Mat& frame, const FrameStats& stats);
  // Each LED against its nearest neighbours, over the single-LED frames accepted.
  std::vector<HealthFinding> CompareNeighbours() const;

  // Per-pixel noise of (frame - dark reference) in DN; 0 before the first dark.
  double response_sigma_dn() const;

  // One sentence per check that failed, naming the LEDs or frames, the
  // statistic against its threshold, and what to look at.
  static std::string Describe(const std::vector<HealthFinding>& findings);

 private:
  struct LitRecord {  // an accepted lit frame
    drivers::LightPattern pattern;
    double gain_db = 0.0;
    double exposure_us = 0.0;
    double mean_response_dn = 0.0;
    double clipped_fraction = 0.0;
    std::string label;
  };
  HealthFinding Finding(HealthCheck check, const config::CaptureStep& step, double value, double threshold) const;
  // The LED's drive scale: exposure x gain x level x calibrated intensity.
  double LedScale(const config::CaptureStep& step) const;

  config::HealthConfig config_;
  std::vector<config::LedConfig> leds_;
  std::vector<bool> bracket_long_;   // by step index: a longer exposure of a bracket, expected to clip
  std::vector<bool> bracket_short_;  // by step index: a shorter exposure of a bracket, may be too dark
  cv::Mat dark_sum_;                // CV_64F sum of the accepted darks
  cv::Mat dark_mean_;               // CV_32F, their mean: the reference
  cv::Mat first_dark_;              // CV_32F, for the temporal noise of a second dark
  int darks_ = 0;
  double dark_sigma_dn_ = 0.0;      // per-pixel noise of one dark frame
  std::optional<std::uint64_t> previous_hash_;  // of the last frame accepted
  config::CaptureStep previous_step_;                   // ... and what it was of
  std::vector<LitRecord> lit_;
  std::map<int, std::vector<std::pair<double, double>>> led_responses_;  // LED index -> (response DN, scale)
};

}  // namespace photorig::daemon
