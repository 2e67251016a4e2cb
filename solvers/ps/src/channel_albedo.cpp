#include "photorig/solvers/ps/channel_albedo.h"

#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace photorig::solvers::ps {
namespace {

// What the fit reads for kChannels interleaved channels: per light its frame
// (kChannels floats a pixel) and direction, per light and channel the
// inverse scale, per channel its rules; optional dark (one channel) and mask.
template <int kChannels>
struct AlbedoInputs {
  const std::vector<cv::Mat>& frames;
  const std::vector<Eigen::Vector3d>& light_directions;
  std::vector<double> inverse_scale;  // [k * kChannels + c]
  std::array<ChannelAlbedoOptions, kChannels> options;
  cv::Mat dark, mask;
};

struct ChannelCounts {
  std::size_t solved = 0, too_few = 0, unsolved = 0, rejected = 0;
};

// Each pixel's albedo in every channel (albedo: CV_32FC(kChannels)): a
// light's cosine is made once for all channels, each channel keeps its own
// usable samples.
template <int kChannels>
std::array<ChannelCounts, kChannels> FitAlbedo(const AlbedoInputs<kChannels>& in, const cv::Mat& normals,
                                               cv::Mat* albedo) {
  const int width = normals.cols, height = normals.rows, lights = static_cast<int>(in.frames.size());
  albedo->create(height, width, CV_32FC(kChannels));
  // The options' thresholds as plain arrays for the inner loop.
  double min_cosine[kChannels], saturation[kChannels], shadow[kChannels];
  int min_samples[kChannels];
  for (int c = 0; c < kChannels; ++c) {
    min_cosine[c] = in.options[c].min_cosine, saturation[c] = in.options[c].saturation_level;
    shadow[c] = in.options[c].shadow_threshold, min_samples[c] = in.options[c].min_samples;
  }
  std::array<ChannelCounts, kChannels> totals{};
#pragma omp parallel
  {
    std::array<ChannelCounts, kChannels> mine{};
#pragma omp for schedule(static)
    for (int y = 0; y < height; ++y) {
      const cv::Vec3f* n_row = normals.ptr<cv::Vec3f>(y);
      const float* dark_row = in.dark.empty() ? nullptr : in.dark.template ptr<float>(y);
      const std::uint8_t* mask_row = in.mask.empty() ? nullptr : in.mask.template ptr<std::uint8_t>(y);
      float* out = albedo->ptr<float>(y);
      for (int x = 0; x < width; ++x) {
        for (int c = 0; c < kChannels; ++c) out[kChannels * x + c] = std::numeric_limits<float>::quiet_NaN();
        const cv::Vec3f n = n_row[x];
        if ((mask_row && !mask_row[x]) || !std::isfinite(n[0])) {
          for (ChannelCounts& counts : mine) ++counts.unsolved;
          continue;
        }
        const double dark = dark_row ? dark_row[x] : 0.0;
        double numerator[kChannels] = {}, denominator[kChannels] = {};
        int used[kChannels] = {};
        for (int k = 0; k < lights; ++k) {
          const Eigen::Vector3d& w = in.light_directions[static_cast<std::size_t>(k)];
          const double cosine = n[0] * w.x() + n[1] * w.y() + n[2] * w.z();
          const float* sample = in.frames[static_cast<std::size_t>(k)].template ptr<float>(y) + kChannels * x;
          for (int c = 0; c < kChannels; ++c) {
            if (cosine < min_cosine[c]) continue;
            const double value = sample[c];
            if (value >= saturation[c] || value - dark <= shadow[c]) {
              ++mine[c].rejected;
              continue;
            }
            numerator[c] += (value - dark) * in.inverse_scale[static_cast<std::size_t>(k) * kChannels + c] * cosine;
            denominator[c] += cosine * cosine;
            ++used[c];
          }
        }
        for (int c = 0; c < kChannels; ++c) {
          if (used[c] < min_samples[c]) {
            ++mine[c].too_few;
            continue;
          }
          out[kChannels * x + c] = static_cast<float>(M_PI * numerator[c] / denominator[c]);
          ++mine[c].solved;
        }
      }
    }
#pragma omp critical(photorig_channel_albedo_counts)
    for (int c = 0; c < kChannels; ++c) {
      totals[c].solved += mine[c].solved, totals[c].too_few += mine[c].too_few;
      totals[c].unsolved += mine[c].unsolved, totals[c].rejected += mine[c].rejected;
    }
  }
  return totals;
}

SolverSummary StartSummary(int lights, const cv::Mat& normals) {
  SolverSummary summary;
  summary.method = "channel-albedo";
  summary.light_count = lights;
  summary.pixels_total = static_cast<std::size_t>(normals.cols) * static_cast<std::size_t>(normals.rows);
  return summary;
}

void FinishSummary(const ChannelCounts& counts, const solvers::core::SolveTimer& timer, SolverSummary* summary) {
  summary->pixels_solved = counts.solved;
  summary->pixels_too_few_lights = counts.too_few;
  summary->pixels_outside_mask = counts.unsolved;
  summary->samples_rejected = counts.rejected;
  timer.Finish(summary);
  summary->End(Termination::kSuccess, std::to_string(counts.solved) + " of " + std::to_string(summary->pixels_total) +
                                          " pixels given an albedo");
}

// Empty when the RGB frames, their lights and the normals fit together; else why not.
std::string CheckRgbInputs(const std::vector<cv::Mat>& frames, const std::vector<Eigen::Vector3d>& light_directions,
                           const std::vector<Eigen::Vector3d>& light_scales, const cv::Mat& normals) {
  if (frames.empty()) return "no frames";
  if (light_directions.size() != frames.size() || light_scales.size() != frames.size())
    return std::to_string(frames.size()) + " frames but " + std::to_string(light_directions.size()) +
           " light directions and " + std::to_string(light_scales.size()) + " light scales";
  for (std::size_t k = 0; k < frames.size(); ++k) {
    if (frames[k].type() != CV_32FC3 || frames[k].size() != frames.front().size())
      return "frame " + std::to_string(k) + " is not CV_32FC3 of frame 0's size";
    if (!(std::abs(light_directions[k].norm() - 1.0) < 1e-6))
      return "light direction " + std::to_string(k) + " is not unit length";
    if (!(light_scales[k].array() > 0.0).all() || !light_scales[k].allFinite())
      return "light scale " + std::to_string(k) + " must be positive and finite in every channel";
  }
  if (normals.type() != CV_32FC3 || normals.size() != frames.front().size())
    return "normals must be CV_32FC3 of the frames' size";
  return {};
}

}  // namespace

bool ChannelAlbedoOptions::IsValid(std::string* why) const {
  if (!(min_cosine > 0.0 && min_cosine < 1.0)) return core::Refuse(why, "min_cosine must lie in (0, 1)");
  if (min_samples < 1) return core::Refuse(why, "min_samples must be >= 1");
  if (!(shadow_threshold >= 0.0)) return core::Refuse(why, "shadow_threshold must be >= 0");
  return true;
}

SolverSummary SolveChannelAlbedo(const ChannelAlbedoOptions& options, const PhotometricStack& channel,
                                 const cv::Mat& normals, cv::Mat* albedo) {
  const solvers::core::SolveTimer timer;
  SolverSummary summary = StartSummary(channel.light_count(), normals);
  if (solvers::core::EndIfInvalid(options, &summary)) return summary;
  if (std::string why; !channel.IsValid(&why)) {
    summary.End(Termination::kInvalidInput, "invalid stack: " + why);
    return summary;
  }
  if (normals.type() != CV_32FC3 || normals.rows != channel.height() || normals.cols != channel.width()) {
    summary.End(Termination::kInvalidInput, "normals must be CV_32FC3 of the stack's size");
    return summary;
  }
  AlbedoInputs<1> in{channel.images, channel.light_directions, {}, {options}, channel.dark, channel.mask};
  for (const double scale : channel.light_scales) in.inverse_scale.push_back(1.0 / scale);
  FinishSummary(FitAlbedo(in, normals, albedo)[0], timer, &summary);
  return summary;
}

std::array<SolverSummary, 3> SolveRgbAlbedo(const std::array<ChannelAlbedoOptions, 3>& options,
                                            const std::vector<cv::Mat>& frames,
                                            const std::vector<Eigen::Vector3d>& light_directions,
                                            const std::vector<Eigen::Vector3d>& light_scales, const cv::Mat& normals,
                                            cv::Mat* albedo) {
  const solvers::core::SolveTimer timer;
  std::array<SolverSummary, 3> summaries;
  bool valid = true;
  for (int c = 0; c < 3; ++c) {
    summaries[c] = StartSummary(static_cast<int>(frames.size()), normals);
    valid = !solvers::core::EndIfInvalid(options[c], &summaries[c]) && valid;
  }
  if (!valid) return summaries;
  if (const std::string why = CheckRgbInputs(frames, light_directions, light_scales, normals); !why.empty()) {
    for (SolverSummary& summary : summaries) summary.End(Termination::kInvalidInput, "invalid RGB frames: " + why);
    return summaries;
  }
  AlbedoInputs<3> in{frames, light_directions, {}, options, cv::Mat(), cv::Mat()};
  for (const Eigen::Vector3d& scale : light_scales)
    for (int c = 0; c < 3; ++c) in.inverse_scale.push_back(1.0 / scale(c));
  const std::array<ChannelCounts, 3> counts = FitAlbedo(in, normals, albedo);
  for (int c = 0; c < 3; ++c) FinishSummary(counts[c], timer, &summaries[c]);
  return summaries;
}

}  // namespace photorig::solvers::ps
