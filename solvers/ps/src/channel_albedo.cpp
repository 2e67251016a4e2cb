#include "photorig/solvers/ps/channel_albedo.h"

#include <cmath>
#include <vector>

namespace photorig::solvers::ps {

bool ChannelAlbedoOptions::IsValid(std::string* why) const {
  if (!(min_cosine > 0.0 && min_cosine < 1.0)) return core::Refuse(why, "min_cosine must lie in (0, 1)");
  if (min_samples < 1) return core::Refuse(why, "min_samples must be >= 1");
  if (!(shadow_threshold >= 0.0)) return core::Refuse(why, "shadow_threshold must be >= 0");
  return true;
}

SolverSummary SolveChannelAlbedo(const ChannelAlbedoOptions& options, const PhotometricStack& channel,
                                 const cv::Mat& normals, cv::Mat* albedo) {
  const solvers::core::SolveTimer timer;
  SolverSummary summary;
  summary.method = "channel-albedo";
  if (solvers::core::EndIfInvalid(options, &summary)) return summary;
  if (std::string why; !channel.IsValid(&why)) {
    summary.End(Termination::kInvalidInput, "invalid stack: " + why);
    return summary;
  }
  if (normals.type() != CV_32FC3 || normals.rows != channel.height() || normals.cols != channel.width()) {
    summary.End(Termination::kInvalidInput, "normals must be CV_32FC3 of the stack's size");
    return summary;
  }
  const int width = channel.width(), height = channel.height(), lights = channel.light_count();
  summary.light_count = lights;
  summary.pixels_total = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  albedo->create(height, width, CV_32F);
  std::vector<double> inverse_scale(static_cast<std::size_t>(lights));
  for (int k = 0; k < lights; ++k) inverse_scale[static_cast<std::size_t>(k)] = 1.0 / channel.light_scales[static_cast<std::size_t>(k)];

  std::size_t solved = 0, too_few = 0, unsolved = 0, rejected = 0;
#pragma omp parallel for schedule(static) reduction(+ : solved, too_few, unsolved, rejected)
  for (int y = 0; y < height; ++y) {
    const cv::Vec3f* n_row = normals.ptr<cv::Vec3f>(y);
    const float* dark_row = channel.dark.empty() ? nullptr : channel.dark.ptr<float>(y);
    const std::uint8_t* mask_row = channel.mask.empty() ? nullptr : channel.mask.ptr<std::uint8_t>(y);
    float* out = albedo->ptr<float>(y);
    for (int x = 0; x < width; ++x) {
      out[x] = std::numeric_limits<float>::quiet_NaN();
      const cv::Vec3f n = n_row[x];
      if ((mask_row && !mask_row[x]) || !std::isfinite(n[0])) {
        ++unsolved;
        continue;
      }
      const double dark = dark_row ? dark_row[x] : 0.0;
      double numerator = 0.0, denominator = 0.0;
      int used = 0;
      for (int k = 0; k < lights; ++k) {
        const Eigen::Vector3d& w = channel.light_directions[static_cast<std::size_t>(k)];
        const double c = n[0] * w.x() + n[1] * w.y() + n[2] * w.z();
        if (c < options.min_cosine) continue;
        const double value = channel.images[static_cast<std::size_t>(k)].ptr<float>(y)[x];
        if (value >= options.saturation_level || value - dark <= options.shadow_threshold) {
          ++rejected;
          continue;
        }
        numerator += (value - dark) * inverse_scale[static_cast<std::size_t>(k)] * c;
        denominator += c * c;
        ++used;
      }
      if (used < options.min_samples) {
        ++too_few;
        continue;
      }
      out[x] = static_cast<float>(M_PI * numerator / denominator);
      ++solved;
    }
  }
  summary.pixels_solved = solved;
  summary.pixels_too_few_lights = too_few;
  summary.pixels_outside_mask = unsolved;
  summary.samples_rejected = rejected;
  timer.Finish(&summary);
  summary.End(Termination::kSuccess, std::to_string(solved) + " of " + std::to_string(summary.pixels_total) +
                                         " pixels given an albedo");
  return summary;
}

}  // namespace photorig::solvers::ps
