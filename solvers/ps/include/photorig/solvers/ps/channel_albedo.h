#pragma once
// Albedo of one colour channel under normals that are already known.
//
// A colour camera's channels see the same surface orientation, so the normals
// are solved once (on luminance, where the signal is strongest) and each
// channel's albedo is then the one-parameter least-squares fit with n fixed:
//   b_k = (I_k - D) / s_k = rho / pi * (n . w_k)
//   rho = pi * sum_k b_k c_k / sum_k c_k^2,   c_k = n . w_k
// over the channel's usable samples (lit: c_k >= min_cosine; not shadowed, not
// saturated). Per-channel scales s_k carry the light's colour and the channel's
// calibration, so the result is the channel's albedo in the stack's units.

#include "photorig/solvers/ps/stack.h"
#include "photorig/solvers/ps/summary.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <array>
#include <limits>
#include <string>
#include <vector>

namespace photorig::solvers::ps {

struct ChannelAlbedoOptions {
  // As in LambertianOptions: samples with I - D <= shadow_threshold or
  // I >= saturation_level (input units) are left out.
  double shadow_threshold = 0.0;
  double saturation_level = std::numeric_limits<double>::infinity();
  // Grazing lights (n . w below this) carry little signal and most of the
  // normal's error; they are left out. Default 0.1 (about 84 degrees).
  double min_cosine = 0.1;
  // Pixels with fewer usable samples are flagged kTooFewLights (albedo NaN).
  int min_samples = 2;

  bool IsValid(std::string* why) const;
};

// `channel` holds one colour channel's frames (its light directions and
// scales); `normals` is CV_32FC3 of the stack's size, NaN where unsolved.
// *albedo becomes CV_32F, NaN where the normal is missing or too few samples
// are usable. Never throws on bad data: the summary says what went wrong.
// Pixels without a normal are counted with those outside the mask.
SolverSummary SolveChannelAlbedo(const ChannelAlbedoOptions& options, const PhotometricStack& channel,
                                 const cv::Mat& normals, cv::Mat* albedo);

// The same fit for the three channels of RGB frames at once: `frames` are
// CV_32FC3, one per light (towards light_directions[k], unit), dark
// subtracted; light_scales[k](c) is light k's scale in channel c and
// options[c] channel c's rules. Each frame is read once and no channel is
// copied out (for a 612 x 512 DiLiGenT object, three channels' frames made
// one at a time are 360 MB of fresh pages). *albedo becomes CV_32FC3 (the
// channels in the frames' order); each channel's answer is
// SolveChannelAlbedo's on that channel's frames alone, and summaries[c] its
// summary.
std::array<SolverSummary, 3> SolveRgbAlbedo(const std::array<ChannelAlbedoOptions, 3>& options,
                                            const std::vector<cv::Mat>& frames,
                                            const std::vector<Eigen::Vector3d>& light_directions,
                                            const std::vector<Eigen::Vector3d>& light_scales, const cv::Mat& normals,
                                            cv::Mat* albedo);

}  // namespace photorig::solvers::ps
