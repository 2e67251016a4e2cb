#include "photorig/daemon/capture/frame_health.h"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <string_view>

namespace photorig::daemon {

double RobustSigma(const cv::Mat& values) {
  const cv::Mat samples = values.isContinuous() ? values.reshape(1) : values.clone().reshape(1);
  std::vector<float> v(samples.begin<float>(), samples.end<float>());
  if (v.empty()) return 0.0;
  auto middle = v.begin() + v.size() / 2;
  std::nth_element(v.begin(), middle, v.end());
  const float median = *middle;
  for (float& x : v) x = std::abs(x - median);
  std::nth_element(v.begin(), middle, v.end());
  return 1.4826 * *middle;
}
namespace {

// Quantisation alone leaves 1/sqrt(12) DN of noise: a floor for a dark so
// clean (or so coarsely quantised) that its spread reads as zero.
constexpr double kQuantisationSigmaDn = 0.28867513459481287;

double Gain(double gain_db) { return std::pow(10.0, gain_db / 20.0); }

bool IsLit(const config::CaptureStep& step) { return step.kind != config::CaptureStep::Kind::kDark && !step.pattern->IsDark(); }

// "0-2, 5, 7-9" for sorted ids.
std::string IdRanges(std::vector<int> ids) {
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  std::string text;
  for (std::size_t i = 0; i < ids.size();) {
    std::size_t j = i;
    while (j + 1 < ids.size() && ids[j + 1] == ids[j] + 1) ++j;
    if (!text.empty()) text += ", ";
    text += j == i ? std::to_string(ids[i]) : std::to_string(ids[i]) + "-" + std::to_string(ids[j]);
    i = j + 1;
  }
  return text;
}

// "LEDs 0-47" / "LED 3" / "frames 0003_flat, 0007_pat_x" / "frame 0003_flat".
std::string Subject(const std::vector<const HealthFinding*>& group) {
  std::vector<int> leds;
  std::vector<std::string> frames;
  for (const HealthFinding* f : group) {
    if (f->led_id >= 0) leds.push_back(f->led_id);
    else frames.push_back(f->label);
  }
  std::string subject;
  if (!leds.empty()) {
    const std::string ranges = IdRanges(leds);
    const bool several = ranges.find_first_of(",-") != std::string::npos;
    subject = (several ? "LEDs " : "LED ") + ranges;
  }
  if (!frames.empty()) {
    if (!subject.empty()) subject += " and ";
    subject += frames.size() == 1 ? "frame " : "frames ";
    const std::size_t shown = std::min<std::size_t>(frames.size(), 6);
    for (std::size_t i = 0; i < shown; ++i) subject += (i ? ", " : "") + frames[i];
    if (shown < frames.size()) subject += fmt::format(" and {} more", frames.size() - shown);
  }
  return subject;
}

// `value` to `digits` decimals, never "-0.0": a dead LED's mean response is
// noise around zero, and a minus sign on nothing reads as a fault of its own.
double Rounded(double value, int digits) {
  const double scale = std::pow(10.0, digits);
  return std::round(value * scale) / scale + 0.0;
}

std::string DescribeGroup(HealthCheck check, const std::vector<const HealthFinding*>& group) {
  // The worst of the group speaks for it: the highest value where the check
  // wants more, the one farthest from 1 for ratios.
  const HealthFinding& worst = **std::max_element(group.begin(), group.end(), [check](auto* a, auto* b) {
    if (check == HealthCheck::kBrightness)
      return std::abs(std::log(std::max(a->value, 1e-9))) < std::abs(std::log(std::max(b->value, 1e-9)));
    return a->value < b->value;
  });
  const std::string subject = Subject(group);
  const bool several = group.size() > 1;
  const std::string at_most = several ? "at most " : "";
  switch (check) {
    case HealthCheck::kNoLight:
      return fmt::format(
          "{} did not light: brightest pixel {}{:.1f} DN above dark, mean response {:.1f} DN (needs a pixel >= {:g} "
          "sigma = {:.1f} DN above dark); {}",
          subject, at_most, Rounded(worst.value, 1), Rounded(worst.mean_response_dn, 1), worst.threshold / worst.noise_sigma_dn,
          worst.threshold,
          several ? "check the LED controller's power and wiring, and that nothing covers the lens"
                  : "check that LED and its channel's wiring");
    case HealthCheck::kLightInDark:
      return fmt::format(
          "dark {} saw light: mean {}{:.1f} DN above the darks before it (allowed < {:g} sigma = {:.1f} DN); an LED "
          "stuck on, or room light reaching the sample",
          subject, several ? "up to " : "", worst.value, worst.threshold / worst.noise_sigma_dn, worst.threshold);
    case HealthCheck::kClipped:
      return fmt::format(
          "{} overexposed: {}{:.1f}% of the pixels clipped (allowed {:.1f}%); shorten the exposure or lower "
          "the gain or the LED level",
          subject, several ? "up to " : "", 100.0 * worst.value, 100.0 * worst.threshold);
    case HealthCheck::kRepeated:
      return fmt::format(
          "{} repeated the previous frame pixel for pixel: the camera delivered a stale buffer; check the camera's "
          "driver, link and trigger",
          subject);
    case HealthCheck::kBrightness:
      return fmt::format(
          "{} far from the expected brightness: mean response {:.2f} times what {} predicts for its exposure "
          "(allowed within a factor {:g}); check for light that flickers or changed between frames",
          subject, worst.value, worst.reference, worst.threshold);
    case HealthCheck::kDimLed:
      return fmt::format(
          "{} dead or dim: mean response {}{:.2f} of the median of its neighbours ({}) (needs >= {:g}); check the LED "
          "and its driver channel",
          subject, at_most, Rounded(worst.value, 2), worst.reference, worst.threshold);
  }
  return subject;
}

}  // namespace

FrameHealth::FrameHealth(config::HealthConfig health, const std::vector<config::CaptureStep>& steps,
                         std::vector<config::LedConfig> leds)
    : config_(std::move(health)), leds_(std::move(leds)) {
  AddSteps(steps);
}

void FrameHealth::AddSteps(const std::vector<config::CaptureStep>& steps) {
  // A bracket takes one pattern at several exposures: the longer ones may
  // clip and the shorter ones may show a dim pose below the noise, so
  // clipping is judged on its shortest exposure only and light on its longest.
  int last_index = static_cast<int>(bracket_long_.size()) - 1;
  for (const config::CaptureStep& step : steps) last_index = std::max(last_index, step.index);
  bracket_long_.resize(static_cast<std::size_t>(last_index + 1), false);
  bracket_short_.resize(static_cast<std::size_t>(last_index + 1), false);
  // A gonioreflectometer's bracket is one pose's exposures.
  const auto same_pose = [](const config::CaptureStep& a, const config::CaptureStep& b) {
    if (!a.pose || !b.pose) return !a.pose && !b.pose;
    return a.pose->light_arm_deg == b.pose->light_arm_deg && a.pose->camera_arm_deg == b.pose->camera_arm_deg &&
           a.pose->sample_rotation_deg == b.pose->sample_rotation_deg &&
           a.pose->sample_changer_deg == b.pose->sample_changer_deg;
  };
  for (const config::CaptureStep& step : steps)
    for (const config::CaptureStep& other : steps)
      if (other.exposure_us != step.exposure_us && other.group == step.group && other.repeat == step.repeat &&
          other.pattern->levels == step.pattern->levels && other.gain_db == step.gain_db && same_pose(other, step)) {
        (other.exposure_us < step.exposure_us ? bracket_long_ : bracket_short_)[step.index] = true;
        if (bracket_long_[step.index] && bracket_short_[step.index]) break;
      }
}

double FrameHealth::response_sigma_dn() const {
  if (darks_ == 0) return 0.0;
  // The frame's own noise plus that of the mean dark subtracted from it.
  return dark_sigma_dn_ * std::sqrt(1.0 + 1.0 / darks_);
}

FrameStats FrameHealth::Measure(const cv::Mat& frame, int bit_depth) const {
  CV_Assert(frame.type() == CV_16U && frame.isContinuous());
  FrameStats stats;
  const std::uint16_t* pixels = frame.ptr<std::uint16_t>();
  const std::size_t count = frame.total();
  const double full_scale = config_.saturation_dn > 0.0
                                ? config_.saturation_dn
                                : static_cast<double>((1u << std::clamp(bit_depth, 1, 16)) - 1u);
  std::size_t clipped = 0;
  bool uniform = true;
  for (std::size_t i = 0; i < count; ++i) {
    clipped += pixels[i] >= full_scale;
    uniform = uniform && pixels[i] == pixels[0];
  }
  stats.clipped_fraction = count ? static_cast<double>(clipped) / count : 0.0;
  stats.uniform = uniform;
  stats.pixel_hash = std::hash<std::string_view>{}(
      std::string_view(reinterpret_cast<const char*>(pixels), count * sizeof(std::uint16_t)));
  if (darks_ > 0 && dark_mean_.size() == frame.size()) {
    const float* dark = dark_mean_.ptr<float>();
    double sum = 0.0, peak = -std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < count; ++i) {
      const double response = pixels[i] - dark[i];
      sum += response;
      peak = std::max(peak, response);
    }
    stats.mean_response_dn = count ? sum / count : 0.0;
    stats.peak_response_dn = peak;
  }
  return stats;
}

HealthFinding FrameHealth::Finding(HealthCheck check, const config::CaptureStep& step, double value, double threshold) const {
  HealthFinding finding;
  finding.check = check;
  finding.step_index = step.index;
  finding.label = step.label;
  if (step.kind == config::CaptureStep::Kind::kLight && step.led >= 0)
    finding.led_id = step.led < static_cast<int>(leds_.size()) ? leds_[step.led].id : step.led;
  finding.value = value;
  finding.threshold = threshold;
  finding.noise_sigma_dn = response_sigma_dn();
  return finding;
}

std::optional<HealthFinding> FrameHealth::Judge(const config::CaptureStep& step, const FrameStats& stats) const {
  if (!config_.enabled) return std::nullopt;
  // A real sensor's noise never repeats, so identical pixels mean the same
  // buffer twice. Against the last frame stored, so a retry that gets the
  // stale buffer again fails again. Only between frames that should differ
  // anyway: a noise-free simulated sensor repeats a repeated step exactly
  // (and restarts its noise when reopened), and a uniform frame (a
  // noise-free black) proves nothing.
  const bool should_differ = step.pattern->levels != previous_step_.pattern->levels ||
                             step.exposure_us != previous_step_.exposure_us ||
                             step.gain_db != previous_step_.gain_db || step.pose || previous_step_.pose;
  const bool repeated = previous_hash_ && *previous_hash_ == stats.pixel_hash && !stats.uniform && should_differ;
  if (repeated) return Finding(HealthCheck::kRepeated, step, 1.0, 0.0);

  const bool known = darks_ > 0 && !std::isnan(stats.mean_response_dn);
  const double lit_dn = config_.lit_sigma * response_sigma_dn();
  const auto in_bracket = [&step](const std::vector<bool>& flags) {
    return step.index >= 0 && step.index < static_cast<int>(flags.size()) && flags[step.index];
  };
  if (known && IsLit(step) && !in_bracket(bracket_short_) && stats.peak_response_dn < lit_dn) {
    HealthFinding finding = Finding(HealthCheck::kNoLight, step, stats.peak_response_dn, lit_dn);
    finding.mean_response_dn = stats.mean_response_dn;
    return finding;
  }
  // The mean, not the brightest pixel, for darks: a hot pixel or a cosmic ray
  // in one dark must not fail a run; a lamp left on raises the whole frame.
  if (known && !IsLit(step) && stats.mean_response_dn >= lit_dn)
    return Finding(HealthCheck::kLightInDark, step, stats.mean_response_dn, lit_dn);

  if (!in_bracket(bracket_long_) && stats.clipped_fraction > config_.max_clipped_fraction)
    return Finding(HealthCheck::kClipped, step, stats.clipped_fraction, config_.max_clipped_fraction);

  // Against the latest accepted frame of the same pattern and gain: the
  // response scales with exposure. Only where both responses stand well
  // above the noise (a mirror sphere's frames are mostly black) and neither
  // frame clips (clipping compresses the mean).
  if (known && IsLit(step) && !step.pose && stats.clipped_fraction <= 0.001) {
    for (auto it = lit_.rbegin(); it != lit_.rend(); ++it) {
      if (it->pattern.levels != step.pattern->levels || it->gain_db != step.gain_db) continue;
      const double expected = it->mean_response_dn * step.exposure_us / it->exposure_us;
      if (it->clipped_fraction > 0.001 || expected < lit_dn) break;
      const double ratio = stats.mean_response_dn / expected;
      if (ratio > config_.max_brightness_ratio || ratio < 1.0 / config_.max_brightness_ratio) {
        HealthFinding finding = Finding(HealthCheck::kBrightness, step, ratio, config_.max_brightness_ratio);
        finding.mean_response_dn = stats.mean_response_dn;
        finding.reference = "frame " + it->label;
        return finding;
      }
      break;
    }
  }
  return std::nullopt;
}

double FrameHealth::LedScale(const config::CaptureStep& step) const {
  const double intensity = step.led >= 0 && step.led < static_cast<int>(leds_.size()) ? leds_[step.led].intensity : 1.0;
  const double level = step.led >= 0 && step.led < static_cast<int>(step.pattern->levels.size())
                           ? step.pattern->levels[step.led]
                           : 1.0;
  return step.exposure_us * Gain(step.gain_db) * level * intensity;
}

void FrameHealth::Accept(const config::CaptureStep& step, const cv::Mat& frame, const FrameStats& stats) {
  if (!config_.enabled) return;
  previous_hash_ = stats.pixel_hash;
  previous_step_ = step;
  if (!IsLit(step)) {
    cv::Mat dark;
    frame.convertTo(dark, CV_32F);
    if (darks_ == 0) {
      dark_sum_ = cv::Mat::zeros(frame.size(), CV_64F);
      first_dark_ = dark;
      dark_sigma_dn_ = RobustSigma(dark);
    } else if (darks_ == 1 && dark.size() == first_dark_.size()) {
      // Two darks give the temporal noise alone: their difference cancels
      // the fixed pattern that inflates a single dark's spread.
      dark_sigma_dn_ = RobustSigma(dark - first_dark_) / std::sqrt(2.0);
    }
    if (dark.size() != dark_sum_.size()) return;  // a frame of another size cannot be a reference
    cv::add(dark_sum_, dark, dark_sum_, cv::noArray(), CV_64F);
    ++darks_;
    dark_sum_.convertTo(dark_mean_, CV_32F, 1.0 / darks_);
    dark_sigma_dn_ = std::max(dark_sigma_dn_, kQuantisationSigmaDn);
    return;
  }
  if (std::isnan(stats.mean_response_dn)) return;
  // A bracket's short exposure in the noise (the only lit frame without light
  // that is accepted) scales to nothing: it is no reference for the others.
  if (darks_ > 0 && stats.peak_response_dn < config_.lit_sigma * response_sigma_dn()) return;
  lit_.push_back({*step.pattern, step.gain_db, step.exposure_us, stats.mean_response_dn, stats.clipped_fraction,
                  step.label});
  if (step.kind == config::CaptureStep::Kind::kLight && step.led >= 0 && stats.clipped_fraction <= config_.max_clipped_fraction)
    led_responses_[step.led].push_back({stats.mean_response_dn, LedScale(step)});
}

std::vector<HealthFinding> FrameHealth::CompareNeighbours() const {
  std::vector<HealthFinding> findings;
  if (!config_.enabled || config_.min_neighbour_ratio <= 0.0 || darks_ == 0) return findings;
  // Response per unit of drive (exposure, gain, level, calibrated intensity),
  // averaged over the LED's frames, so brackets and repeats compare alike.
  std::map<int, double> per_unit;
  std::map<int, double> mean_scale;
  for (const auto& [led, samples] : led_responses_) {
    if (led >= static_cast<int>(leds_.size())) return findings;  // no directions to find neighbours by
    double sum = 0.0, scale = 0.0;
    for (const auto& [response, s] : samples) {
      sum += response / s;
      scale += s;
    }
    per_unit[led] = sum / samples.size();
    mean_scale[led] = scale / samples.size();
  }
  const double lit_dn = config_.lit_sigma * response_sigma_dn();
  for (const auto& [led, response] : per_unit) {
    std::vector<std::pair<double, int>> by_angle;  // (cosine, LED) of the others
    for (const auto& [other, unused] : per_unit)
      if (other != led) by_angle.push_back({-leds_[led].direction.dot(leds_[other].direction), other});
    if (by_angle.empty()) continue;
    const std::size_t k = std::min<std::size_t>(config_.neighbours, by_angle.size());
    std::partial_sort(by_angle.begin(), by_angle.begin() + k, by_angle.end());
    std::vector<double> neighbours;
    std::vector<int> ids;
    for (std::size_t i = 0; i < k; ++i) {
      neighbours.push_back(per_unit.at(by_angle[i].second));
      ids.push_back(leds_[by_angle[i].second].id);
    }
    std::nth_element(neighbours.begin(), neighbours.begin() + neighbours.size() / 2, neighbours.end());
    const double median = neighbours[neighbours.size() / 2];
    // Only where the neighbours' mean response stands well above the noise:
    // on a mirror sphere every LED lights a few pixels and means say nothing.
    if (!(median * mean_scale.at(led) >= lit_dn)) continue;
    const double ratio = response / median;
    if (ratio >= config_.min_neighbour_ratio) continue;
    HealthFinding finding;
    finding.check = HealthCheck::kDimLed;
    finding.led_id = leds_[led].id;
    finding.label = "led" + std::to_string(leds_[led].id);
    finding.value = ratio;
    finding.threshold = config_.min_neighbour_ratio;
    finding.noise_sigma_dn = response_sigma_dn();
    finding.mean_response_dn = response * mean_scale.at(led);
    finding.reference = (ids.size() == 1 ? "LED " : "LEDs ") + [&ids] {
      std::sort(ids.begin(), ids.end());
      std::string text;
      for (int id : ids) text += (text.empty() ? "" : ", ") + std::to_string(id);
      return text;
    }();
    findings.push_back(finding);
  }
  return findings;
}

std::string FrameHealth::Describe(const std::vector<HealthFinding>& findings) {
  std::vector<HealthCheck> order;
  std::map<HealthCheck, std::vector<const HealthFinding*>> groups;
  for (const HealthFinding& f : findings) {
    if (!groups.count(f.check)) order.push_back(f.check);
    groups[f.check].push_back(&f);
  }
  std::string text;
  for (HealthCheck check : order) text += (text.empty() ? "" : "; also ") + DescribeGroup(check, groups[check]);
  return text;
}

}  // namespace photorig::daemon
