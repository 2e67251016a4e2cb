#include "photorig/solvers/color/region_demosaic.h"

#include <algorithm>
#include <limits>
#include <string>

namespace photorig::solvers::color {
namespace {

using solvers::core::Ended;
using solvers::core::Termination;

bool IsBayer(const std::string& pattern) {
  return pattern == "RGGB" || pattern == "BGGR" || pattern == "GRBG" || pattern == "GBRG";
}

// Output channel (B = 0, G = 1, R = 2) of the site at (y & 1, x & 1).
void SiteChannels(const std::string& pattern, int (*site_channel)[2]) {
  for (int i = 0; i < 4; ++i) site_channel[i / 2][i % 2] = pattern[i] == 'B' ? 0 : pattern[i] == 'G' ? 1 : 2;
}

solvers::core::Summary CheckRaw(const cv::Mat& raw) {
  if (raw.empty() || raw.channels() != 1)
    return Ended(Termination::kInvalidInput, "a Bayer raw has one channel, got " + std::to_string(raw.channels()));
  if (raw.depth() != CV_8U && raw.depth() != CV_16U && raw.depth() != CV_32F)
    return Ended(Termination::kInvalidInput, "a Bayer raw must be 8- or 16-bit (or float once dark subtracted)");
  return Ended(Termination::kSuccess, "");
}

solvers::core::Summary UnknownPattern(const std::string& pattern) {
  return Ended(Termination::kInvalidOptions, "unknown Bayer pattern '" + pattern + "' (expected RGGB, BGGR, GRBG or GBRG)");
}

}  // namespace

solvers::core::Summary DemosaicWithinRegions(const cv::Mat& raw, const std::string& pattern, const cv::Mat& regions,
                                       cv::Mat* bgr) {
  const solvers::core::SolveTimer timer;
  if (const solvers::core::Summary checked = CheckRaw(raw); !checked.IsSolutionUsable()) return checked;
  if (regions.type() != CV_8U || regions.size() != raw.size())
    return Ended(Termination::kInvalidInput, "the region labels must be CV_8U and the raw's size");
  if (!IsBayer(pattern)) return UnknownPattern(pattern);
  cv::Mat values;
  raw.convertTo(values, CV_32F);
  int site_channel[2][2];
  SiteChannels(pattern, site_channel);
  const int rows = raw.rows, cols = raw.cols;
  cv::Mat out(raw.size(), CV_32FC3);
#pragma omp parallel for schedule(static)
  for (int y = 0; y < rows; ++y) {
    float* o = out.ptr<float>(y);
    for (int x = 0; x < cols; ++x) {
      const std::uint8_t label = regions.at<std::uint8_t>(y, x);
      const int own = site_channel[y & 1][x & 1];
      for (int c = 0; c < 3; ++c) {
        if (c == own) {
          o[3 * x + c] = values.at<float>(y, x);
          continue;
        }
        // Mean of channel c's sites within `reach` (of the pixel's label only
        // when `same_label`); false when there are none.
        auto mean_of_sites = [&](int reach, bool same_label, float* mean) {
          float sum = 0.0f;
          int n = 0;
          for (int yy = std::max(0, y - reach); yy <= std::min(rows - 1, y + reach); ++yy)
            for (int xx = std::max(0, x - reach); xx <= std::min(cols - 1, x + reach); ++xx) {
              if (site_channel[yy & 1][xx & 1] != c) continue;
              if (same_label && regions.at<std::uint8_t>(yy, xx) != label) continue;
              sum += values.at<float>(yy, xx);
              ++n;
            }
          if (n > 0) *mean = sum / static_cast<float>(n);
          return n > 0;
        };
        float& value = o[3 * x + c];
        if (label != kNoRegion && (mean_of_sites(1, true, &value) || mean_of_sites(2, true, &value))) continue;
        mean_of_sites(1, false, &value);
      }
    }
  }
  *bgr = out;
  return timer.Succeeded();
}

bool RegionEdgeVote::Options::IsValid(std::string* why) const {
  if (!(switch_ratio > 0.0 && switch_ratio <= 1.0)) return core::Refuse(why, "switch_ratio must be in (0, 1]");
  if (!(min_difference >= 0.0)) return core::Refuse(why, "min_difference must be >= 0");
  if (!(floor_dn > 0.0)) return core::Refuse(why, "floor_dn must be > 0");
  return true;
}

RegionEdgeVote::RegionEdgeVote(const std::string& pattern, const cv::Mat& regions, const Options& options)
    : options_(options) {
  if (std::string why; !options.IsValid(&why)) {
    status_ = Ended(Termination::kInvalidOptions, "invalid options: " + why);
    return;
  }
  if (!IsBayer(pattern)) {
    status_ = UnknownPattern(pattern);
    return;
  }
  if (regions.type() != CV_8U || regions.empty()) {
    status_ = Ended(Termination::kInvalidInput, "the region labels must be a non-empty CV_8U image");
    return;
  }
  regions_ = regions.clone();
  SiteChannels(pattern, site_channel_);
  for (int y = 0; y < regions_.rows; ++y)
    for (int x = 0; x < regions_.cols; ++x) {
      const std::uint8_t own = regions_.at<std::uint8_t>(y, x);
      if (own == kNoRegion) continue;
      Contested c;
      c.y = y, c.x = x;
      bool other = false;
      for (int yy = std::max(0, y - 2); yy <= std::min(regions_.rows - 1, y + 2); ++yy)
        for (int xx = std::max(0, x - 2); xx <= std::min(regions_.cols - 1, x + 2); ++xx) {
          if ((yy == y && xx == x) || site_channel_[yy & 1][xx & 1] != site_channel_[y & 1][x & 1]) continue;
          const std::uint8_t label = regions_.at<std::uint8_t>(yy, xx);
          if (label == kNoRegion) continue;
          other = other || label != own;
          const auto end = c.label.begin() + c.labels;
          if (std::find(c.label.begin(), end, label) == end && c.labels < kMaxLabels) c.label[c.labels++] = label;
        }
      if (other) contested_.push_back(c);
    }
  status_ = Ended(Termination::kSuccess, "");
}

solvers::core::Summary RegionEdgeVote::Add(const cv::Mat& raw, const cv::Mat& clipped) {
  if (!status_.IsSolutionUsable()) return status_;
  if (const solvers::core::Summary checked = CheckRaw(raw); !checked.IsSolutionUsable()) return checked;
  if (raw.size() != regions_.size()) return Ended(Termination::kInvalidInput, "the frame differs in size from the labels");
  if (!clipped.empty() && (clipped.type() != CV_8U || clipped.size() != regions_.size()))
    return Ended(Termination::kInvalidInput, "the clipped mask must be CV_8U and the frame's size");
  cv::Mat values;
  raw.convertTo(values, CV_32F);
  const int rows = values.rows, cols = values.cols;
  const double floor_dn = options_.floor_dn;
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < contested_.size(); ++i) {
    Contested& c = contested_[i];
    const int colour = site_channel_[c.y & 1][c.x & 1];
    bool any_clipped = !clipped.empty() && clipped.at<std::uint8_t>(c.y, c.x);
    std::array<double, kMaxLabels> sum{};
    std::array<int, kMaxLabels> count{};
    for (int yy = std::max(0, c.y - 2); yy <= std::min(rows - 1, c.y + 2); ++yy)
      for (int xx = std::max(0, c.x - 2); xx <= std::min(cols - 1, c.x + 2); ++xx) {
        if ((yy == c.y && xx == c.x) || site_channel_[yy & 1][xx & 1] != colour) continue;
        any_clipped = any_clipped || (!clipped.empty() && clipped.at<std::uint8_t>(yy, xx));
        const std::uint8_t label = regions_.at<std::uint8_t>(yy, xx);
        for (int k = 0; k < c.labels; ++k)
          if (c.label[k] == label) sum[k] += values.at<float>(yy, xx), ++count[k];
      }
    if (any_clipped) continue;
    const double own = values.at<float>(c.y, c.x);
    ++c.frames;
    for (int k = 0; k < c.labels; ++k) {
      const double mean = sum[k] / std::max(count[k], 1);
      c.mismatch[k] += std::abs(own - mean) / (std::abs(own) + std::abs(mean) + floor_dn);
    }
  }
  return Ended(Termination::kSuccess, "");
}

cv::Mat RegionEdgeVote::Regions(int* changed) const {
  if (changed) *changed = 0;
  if (!status_.IsSolutionUsable()) return regions_.clone();
  cv::Mat out = regions_.clone();
  for (const Contested& c : contested_) {
    const std::uint8_t present = regions_.at<std::uint8_t>(c.y, c.x);
    double present_mismatch = std::numeric_limits<double>::infinity();
    int best = -1;
    for (int k = 0; k < c.labels; ++k) {
      if (c.label[k] == present) present_mismatch = c.mismatch[k];
      if (best < 0 || c.mismatch[k] < c.mismatch[best]) best = k;
    }
    if (best >= 0 && c.label[best] != present && c.mismatch[best] < options_.switch_ratio * present_mismatch &&
        present_mismatch - c.mismatch[best] > options_.min_difference * c.frames) {
      out.at<std::uint8_t>(c.y, c.x) = c.label[best];
      if (changed) ++*changed;
    }
  }
  return out;
}

}  // namespace photorig::solvers::color
