#include "photorig/daemon/pipelines/brdf_measurement.h"

#include "photorig/solvers/color/colorimetry.h"
#include "photorig/config/color_model.h"
#include "photorig/daemon/pipelines/color_stack.h"
#include "photorig/solvers/brdf/half_diff.h"
#include "photorig/solvers/brdf/pose_plan.h"

#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <tuple>

namespace photorig::daemon {
using solvers::core::Refuse;

namespace {

namespace brdf = solvers::brdf;
using config::LoadedColorModel;
using config::LoadColorModelFile;
using solvers::core::Termination;

std::string Format(const char* format, double a, double b = 0.0, double c = 0.0) {
  char text[256];
  std::snprintf(text, sizeof(text), format, a, b, c);
  return text;
}

// The frames of one exposure at one pose (or the darks of one exposure), as
// the central block of pixels in DN.
struct Exposure {
  double exposure_us = 0.0, gain = 1.0, level = 1.0;
  std::vector<cv::Mat> blocks;  // CV_64F, block_px x block_px
};

// Everything taken at one pose, by exposure (ascending).
struct PoseFrames {
  config::GonioPose pose;
  std::map<double, Exposure> exposures;
};

using PoseKey = std::tuple<double, double, double, double>;
PoseKey KeyOf(const config::GonioPose& p) {
  return {p.light_arm_deg, p.camera_arm_deg, p.sample_rotation_deg, p.sample_changer_deg.value_or(0.0)};
}

// A mosaic's block starts on an even row and column, i.e. on its pattern's
// top-left site.
cv::Mat CentralBlock(const cv::Mat& frame, int block_px, bool mosaic) {
  int x = (frame.cols - block_px) / 2, y = (frame.rows - block_px) / 2;
  if (mosaic) {
    x -= x % 2;
    y -= y % 2;
  }
  cv::Mat block;
  frame(cv::Rect(x, y, block_px, block_px)).convertTo(block, CV_64F);
  return block;
}

cv::Mat MeanOf(const std::vector<cv::Mat>& blocks) {
  cv::Mat sum = cv::Mat::zeros(blocks.front().size(), CV_64F);
  for (const cv::Mat& b : blocks) sum += b;
  return sum / static_cast<double>(blocks.size());
}

// The darks of one exposure: their mean per pixel and how many.
struct Dark {
  cv::Mat mean;
  int count = 0;
};

// The channel (0 R, 1 G, 2 B) each pixel of the block records, row-major:
// a Bayer pattern's top-left 2 x 2 block repeated (the block starts on it,
// CentralBlock); a grey camera's pixels all give channel 0.
std::vector<int> BlockChannels(const std::string& mosaic, int block_px) {
  std::vector<int> channels(static_cast<std::size_t>(block_px) * block_px, 0);
  if (mosaic == "mono") return channels;
  for (int r = 0; r < block_px; ++r)
    for (int c = 0; c < block_px; ++c) {
      const char filter = mosaic[static_cast<std::size_t>((r % 2) * 2 + c % 2)];
      channels[static_cast<std::size_t>(r) * block_px + c] = filter == 'R' ? 0 : filter == 'G' ? 1 : 2;
    }
  return channels;
}

// A block's rate (DN per us at 0 dB) per camera channel, merged over a
// pose's exposures; a grey camera's three channels are equal.
struct Merged {
  Eigen::Vector3d rate = Eigen::Vector3d::Zero(), variance = Eigen::Vector3d::Zero();
  bool clipped = false;  // some pixel unclipped at no exposure
  int exposures_used = 0;
  double longest_used_exposure_us = 0.0;  // weighs most in the merge
  int frames_used = 0;                    // the repeats at the exposures used
};

class Merger {
 public:
  Merger(const std::map<double, Dark>& darks, double saturation_dn, double read_var, double shot,
         std::vector<int> site_channels, bool grey)
      : darks_(darks),
        saturation_dn_(saturation_dn),
        read_var_(read_var),
        shot_(shot),
        site_channels_(std::move(site_channels)),
        grey_(grey) {}

  Merged Merge(const PoseFrames& pose) const {
    Merged out;
    const int n_pixels = pose.exposures.begin()->second.blocks.front().rows *
                         pose.exposures.begin()->second.blocks.front().cols;
    std::vector<bool> used(pose.exposures.size(), false);
    // The sample fills the block uniformly, so every site of a channel sees
    // the same radiance through the same filter: the channel's rate is the
    // mean over its own sites, with no demosaicing (which would only blend
    // neighbouring sites of other channels back in, and correlate their noise).
    Eigen::Vector3d rate_sum = Eigen::Vector3d::Zero(), variance_sum = Eigen::Vector3d::Zero();
    Eigen::Vector3d sites = Eigen::Vector3d::Zero();
    for (int p = 0; p < n_pixels; ++p) {
      // Rates of the exposures that do not clip this pixel, and the best one:
      // the longest exposure's, which carries the most signal.
      struct Reading {
        double rate, scale, gain, n, n_dark;
        std::size_t index;
      };
      std::vector<Reading> readings;
      std::size_t index = 0;
      for (const auto& [exposure_us, e] : pose.exposures) {
        const Dark& dark = darks_.at(exposure_us);
        double sum = 0.0;
        bool clips = false;
        for (const cv::Mat& b : e.blocks) {
          const double dn = b.at<double>(p);
          clips = clips || dn >= saturation_dn_;
          sum += dn;
        }
        const double scale = exposure_us * e.gain;
        if (!clips)
          readings.push_back({(sum / e.blocks.size() - dark.mean.at<double>(p)) / scale, scale, e.gain,
                              static_cast<double>(e.blocks.size()), static_cast<double>(dark.count), index});
        ++index;
      }
      if (readings.empty()) {
        out.clipped = true;
        return out;
      }
      const double best_rate = std::max(readings.back().rate, 0.0);
      double weight_sum = 0.0, weighted = 0.0;
      for (const Reading& r : readings) {
        // Per-frame variance at the signal the best rate predicts, averaged
        // over the repeats, plus the subtracted dark mean's.
        const double signal_dn = best_rate * r.scale;
        const double var_dn = (read_var_ + shot_ * r.gain * signal_dn) / r.n + read_var_ / r.n_dark;
        const double weight = r.scale * r.scale / var_dn;
        weight_sum += weight;
        weighted += weight * r.rate;
        used[r.index] = true;
      }
      const int channel = site_channels_[static_cast<std::size_t>(p)];
      rate_sum[channel] += weighted / weight_sum;
      variance_sum[channel] += 1.0 / weight_sum;
      sites[channel] += 1.0;
    }
    for (int c = 0; c < 3; ++c)
      if (sites[c] > 0.0) {
        out.rate[c] = rate_sum[c] / sites[c];
        out.variance[c] = variance_sum[c] / (sites[c] * sites[c]);
      }
    if (grey_) {
      out.rate.setConstant(out.rate[0]);
      out.variance.setConstant(out.variance[0]);
    }
    out.exposures_used = static_cast<int>(std::count(used.begin(), used.end(), true));
    std::size_t index = 0;
    for (const auto& [exposure_us, e] : pose.exposures) {
      if (used[index++]) {
        out.longest_used_exposure_us = exposure_us;  // ascending: the last used is the longest
        out.frames_used += static_cast<int>(e.blocks.size());
      }
    }
    return out;
  }

 private:
  const std::map<double, Dark>& darks_;
  double saturation_dn_, read_var_, shot_;
  std::vector<int> site_channels_;
  bool grey_;
};

const char* const kChannelNames[3] = {"R", "G", "B"};

// The rig's colour model (camera.color_model, camera RGB -> XYZ) on f_r per
// camera channel. Only a linear (3 x 3) model is well defined there: it maps
// a sum of BRDF terms (diffuse + lobe) to the sum of their images and a
// sample's independent channel deviations to known ones, so the fitted models
// keep their form. A root-polynomial model is homogeneous but not linear
// (sqrt(r g) of a sum is not the sum of sqrt(r g)s): applied per sample it
// would bend every model's colour with the angle; f_r stays in camera
// channels and the summary says why.
void ApplyColorModel(const RunManifest& manifest, const Eigen::Vector3d& k_times_e, BrdfMeasurement* out) {
  out->color_model_path = manifest.color_model_path;
  LoadedColorModel loaded;
  try {
    loaded = LoadColorModelFile(manifest.color_model_path);
  } catch (const std::exception& e) {
    out->color_model_note = std::string("not applied: the colour model could not be read (") + e.what() +
                            "); f_r is per camera channel";
    return;
  }
  const solvers::color::ColorModel& model = loaded.model;
  out->color_model_kind = model.spec.Name();
  if (model.spec.kind != solvers::color::ModelSpec::Kind::kLinear) {
    out->color_model_note = "not applied: " + model.spec.Name() +
                            " is not a 3 x 3 matrix, and only a linear map carries a BRDF's sum of terms and its "
                            "deviations to linear sRGB; f_r is per camera channel, white-balanced by the grey "
                            "reference target";
    return;
  }
  // The camera's raw response to f_r is K_c f_r,c (K per channel from the
  // target); the model takes raw RGB to XYZ (relative to its white), adapted
  // to D65 and taken to linear sRGB. Scaled so the grey target keeps its
  // luminance: a grey f_r maps to the camera white's sRGB at the same Y.
  const Eigen::Vector3d d65 = solvers::color::LinearSrgbToXyzD65() * Eigen::Vector3d::Ones();
  const Eigen::Matrix3d to_srgb = solvers::color::XyzD65ToLinearSrgb() * solvers::color::BradfordAdaptation(model.white_xyz, d65) *
                                  model.coefficients.transpose() * k_times_e.asDiagonal();
  const Eigen::Vector3d white = to_srgb * Eigen::Vector3d::Ones();
  const double luminance = solvers::color::LinearSrgbToXyzD65().row(1).dot(white);
  if (!(luminance > 0.0) || !to_srgb.allFinite()) {
    out->color_model_note = "not applied: the linear colour model maps the camera's white to no luminance";
    return;
  }
  out->camera_to_linear_srgb = to_srgb / luminance;
  const Eigen::Matrix3d squared = out->camera_to_linear_srgb.cwiseAbs2();
  for (solvers::brdf::BrdfSample& s : out->samples) {
    s.value = out->camera_to_linear_srgb * s.value;
    s.sigma = (squared * s.sigma.cwiseAbs2()).cwiseSqrt();  // the channels' noise is independent
  }
  out->color_model_applied = true;
  char white_text[128];
  std::snprintf(white_text, sizeof(white_text), "(%.4f, %.4f, %.4f)", white[0] / luminance, white[1] / luminance,
                white[2] / luminance);
  out->color_model_note = "applied: f_r converted from camera channels to linear sRGB (D65) by the linear model's "
                          "3 x 3 matrix; a grey f_r of luminance 1 becomes " + std::string(white_text);
}

}  // namespace

bool BrdfMeasurementOptions::IsValid(std::string* why) const {
  if (block_px < 1 || block_px > 1024) return Refuse(why, "block_px must be within [1, 1024]");
  if (!(max_target_relative_sigma > 0.0 && max_target_relative_sigma < 1.0))
    return Refuse(why, "max_target_relative_sigma must be within (0, 1)");
  if (!(peak_theta_h_deg >= 0.0 && peak_theta_h_deg < 90.0)) return Refuse(why, "peak_theta_h_deg must be within [0, 90)");
  return true;
}

namespace {

// What the stages of a measurement share: the run's frames sorted by kind,
// the dark means and the noise model as they are found.
struct Measurement {
  const std::string& run_dir;
  const RunManifest& manifest;
  const BrdfMeasurementOptions& options;
  std::string where;  // "<run>: ", the start of every message
  bool grey = true;
  double saturation_dn = 0.0;
  // Filled as the measurement goes; {} so that MeasureBrdf initialises the inputs alone.
  std::map<double, std::vector<cv::Mat>> darks{};
  std::vector<PoseFrames> poses{}, target{};
  std::map<double, Dark> dark_means{};
  double read_var = 0.0;
};

// A grey or Bayer camera, blocks that tile the mosaic, a lamp.
bool CheckRun(Measurement& m, BrdfMeasurement* out) {
  if (std::string why; !m.options.IsValid(&why)) {
    out->End(Termination::kInvalidOptions, why);
    return false;
  }
  if (m.manifest.lights.empty()) {
    out->End(Termination::kInvalidInput, m.where + "the run has no lamp");
    return false;
  }
  m.grey = m.manifest.mosaic == "mono";
  if (!m.grey && !IsBayerPattern(m.manifest.mosaic)) {
    out->End(Termination::kInvalidInput, m.where + "frames of mosaic '" + m.manifest.mosaic +
                                             "' are not measured: a gonioreflectometer camera is grey (mono) or a "
                                             "Bayer mosaic (RGGB, BGGR, GRBG, GBRG)");
    return false;
  }
  if (!m.grey && m.options.block_px % 2 != 0) {
    out->End(Termination::kInvalidOptions, "block_px must be even for a Bayer mosaic (whole 2 x 2 blocks)");
    return false;
  }
  // A dome's run (one frame per LED) has no arm poses: say what it is
  // before any check of the darks a gonioreflectometer run would have.
  const bool posed = std::any_of(m.manifest.frames.begin(), m.manifest.frames.end(), [](const FrameRecord& record) {
    return record.kind == config::CaptureStep::Kind::kPose && record.pose;
  });
  if (!posed) {
    out->End(Termination::kInvalidInput,
             m.where + "no arm poses: not a gonioreflectometer run (config/recipes/brdf-gonio.yaml); a dome's run "
                       "is solved by `photorig solve ps` or `solve svbrdf`");
    return false;
  }
  out->mosaic = m.manifest.mosaic;
  const int bits = m.manifest.bit_depth > 0 ? m.manifest.bit_depth : 16;
  m.saturation_dn = m.manifest.saturation_dn > 0.0 ? m.manifest.saturation_dn : std::ldexp(1.0, bits) - 1.0;
  return true;
}

// Frames by kind: darks by exposure, poses and the target by pose and exposure.
void SortFrames(Measurement& m, BrdfMeasurement* out) {
  std::map<PoseKey, std::size_t> pose_index;
  for (const FrameRecord& r : m.manifest.frames) {
    if (r.kind != config::CaptureStep::Kind::kDark && !(r.kind == config::CaptureStep::Kind::kPose && r.pose)) continue;
    const cv::Mat block = CentralBlock(LoadFrame(m.run_dir, r), m.options.block_px, !m.grey);
    if (r.kind == config::CaptureStep::Kind::kDark) {
      m.darks[r.exposure_us].push_back(block);
      ++out->dark_frames;
      continue;
    }
    const bool is_target = r.group_kind == config::Recipe::Group::Kind::kReferenceTarget;
    std::vector<PoseFrames>& list = is_target ? m.target : m.poses;
    if (is_target) {
      ++out->target_frames;
      if (list.empty()) list.push_back({*r.pose, {}});
    } else {
      ++out->pose_frames;
      const auto [it, inserted] = pose_index.emplace(KeyOf(*r.pose), list.size());
      if (inserted) list.push_back({*r.pose, {}});
    }
    PoseFrames& pose = is_target ? list.front() : list[pose_index.at(KeyOf(*r.pose))];
    Exposure& e = pose.exposures[r.exposure_us];
    e.exposure_us = r.exposure_us;
    e.gain = std::pow(10.0, r.gain_db / 20.0);
    e.level = r.level > 0.0 ? r.level : 1.0;
    e.blocks.push_back(block);
  }
}

// Darks: the mean per exposure, and the read noise from their temporal
// spread; every exposure a pose was taken at needs its dark.
bool MeasureDarks(Measurement& m, BrdfMeasurement* out) {
  if (m.darks.empty()) {
    out->End(Termination::kInvalidInput, m.where + "no dark frames to subtract (add a dark step)");
    return false;
  }
  double squares = 0.0;
  long dof = 0;
  for (const auto& [exposure_us, blocks] : m.darks) {
    const cv::Mat mean = MeanOf(blocks);
    for (const cv::Mat& b : blocks) squares += cv::norm(b - mean, cv::NORM_L2SQR);
    dof += static_cast<long>(blocks.size() - 1) * mean.rows * mean.cols;
    m.dark_means[exposure_us] = {mean, static_cast<int>(blocks.size())};
  }
  if (dof == 0) {
    out->End(Termination::kInvalidInput,
             m.where + "the read noise needs two or more dark frames at one exposure (add `dark: {count: 2}`)");
    return false;
  }
  // Quantisation's 1/12 DN^2 is a floor even for a noise-free sensor.
  m.read_var = std::max(squares / dof, 1.0 / 12.0);
  out->read_sigma_dn = std::sqrt(m.read_var);
  for (const std::vector<PoseFrames>* list : {&m.poses, &m.target})
    for (const PoseFrames& pose : *list)
      for (const auto& [exposure_us, e] : pose.exposures)
        if (!m.dark_means.count(exposure_us)) {
          out->End(Termination::kInvalidInput,
                   m.where + Format("no dark frame at exposure %.0f us, which a pose was taken at: dark current and "
                                    "offsets depend on the exposure (add it to the dark step's exposures_us)",
                                    exposure_us));
          return false;
        }
  return true;
}

// Shot noise: the camera's conversion gain, else the repeats' per-pixel
// spread above the read noise, regressed on the signal.
bool MeasureShotNoise(const Measurement& m, BrdfMeasurement* out) {
  if (m.manifest.e_per_dn > 0.0) {
    out->shot_dn_per_dn = 1.0 / m.manifest.e_per_dn;
    return true;
  }
  double num = 0.0, den = 0.0;
  for (const PoseFrames& pose : m.poses)
    for (const auto& [exposure_us, e] : pose.exposures) {
      if (e.blocks.size() < 2) continue;
      const cv::Mat mean = MeanOf(e.blocks);
      for (int p = 0; p < mean.rows * mean.cols; ++p) {
        double var = 0.0;
        bool clips = false;
        for (const cv::Mat& b : e.blocks) {
          var += std::pow(b.at<double>(p) - mean.at<double>(p), 2);
          clips = clips || b.at<double>(p) >= m.saturation_dn;
        }
        // var = read_var + shot g S, S the signal in DN at gain g.
        const double x = e.gain * (mean.at<double>(p) - m.dark_means.at(exposure_us).mean.at<double>(p));
        if (clips || x <= 0.0) continue;
        num += (var / (e.blocks.size() - 1) - m.read_var) * x;
        den += x * x;
      }
    }
  if (den <= 0.0) {
    out->End(Termination::kInvalidInput, m.where + "the rig states no camera e_per_dn and no pose was repeated to "
                                                   "measure the shot noise from (give camera.e_per_dn, or count: 2 "
                                                   "or more in the poses step)");
    return false;
  }
  out->shot_dn_per_dn = std::max(num / den, 0.0);
  out->shot_estimated = true;
  return true;
}

// The radiometric scale: K E, DN per us at 0 dB per unit f_r cos theta_i,
// per camera channel. From the grey target each channel gets its own K, so
// the channels' gains (sensitivity, white balance) cancel and f_r comes out
// per camera channel; the camera's stated response is one K for all.
std::optional<Eigen::Vector3d> Calibrate(const Measurement& m, const Merger& merger, BrdfMeasurement* out) {
  out->camera_dn_per_radiance_per_us = m.manifest.dn_per_radiance_per_us;
  const double lamp = m.manifest.lights[0].intensity;
  if (m.options.calibration == BrdfMeasurementOptions::Calibration::kCameraResponse) {
    out->calibration = BrdfMeasurementOptions::Calibration::kCameraResponse;
    out->dn_per_radiance_per_us = m.manifest.dn_per_radiance_per_us;
    out->channel_dn_per_radiance_per_us.setConstant(m.manifest.dn_per_radiance_per_us);
    return Eigen::Vector3d::Constant(m.manifest.dn_per_radiance_per_us * lamp);
  }
  out->calibration = BrdfMeasurementOptions::Calibration::kReferenceTarget;
  const char* otherwise = ", or pass --calibration camera to trust the camera's stated response)";
  if (!m.manifest.reference_albedo) {
    out->End(Termination::kInvalidInput,
             m.where + "the rig names no reference_target to calibrate against (name one in the rig" + otherwise);
    return std::nullopt;
  }
  out->reference_albedo = *m.manifest.reference_albedo;
  if (m.target.empty()) {
    out->End(Termination::kInvalidInput,
             m.where + "the run has no reference_target frames (add a `reference_target:` step to the recipe" + otherwise);
    return std::nullopt;
  }
  const PoseFrames& t = m.target.front();
  const brdf::DirectionPair dirs =
      brdf::ArmDirections({t.pose.light_arm_deg, t.pose.camera_arm_deg, t.pose.sample_rotation_deg});
  const Merged merged = merger.Merge(t);
  if (merged.clipped) {
    out->End(Termination::kFailure, m.where + Format("the reference target is saturated even at its shortest "
                                                     "exposure (%.0f us): shorten the exposure or lower the lamp",
                                                     t.exposures.begin()->first));
    return std::nullopt;
  }
  for (int c = 0; c < 3; ++c) {
    const double relative = merged.rate[c] > 0.0 ? std::sqrt(merged.variance[c]) / merged.rate[c] : INFINITY;
    if (!(relative <= m.options.max_target_relative_sigma)) {
      out->End(Termination::kFailure,
               m.where + (m.grey ? std::string() : std::string("in channel ") + kChannelNames[c] + " ") +
                   Format("the reference target is too dark: %.4g DN/us known to %.2g %% (at most %.2g %%); "
                          "lengthen its exposure or raise the lamp",
                          merged.rate[c], 100.0 * relative, 100.0 * m.options.max_target_relative_sigma));
      return std::nullopt;
    }
    out->channel_calibration_relative_sigma[c] = relative;
  }
  const double level = t.exposures.begin()->second.level;
  const Eigen::Vector3d k_times_e = merged.rate * M_PI / (out->reference_albedo * level * dirs.wi.z());
  out->channel_dn_per_radiance_per_us = k_times_e / lamp;
  // The scalars: a grey camera's K, or a colour camera's green (twice the sites of red or blue).
  out->dn_per_radiance_per_us = out->channel_dn_per_radiance_per_us[1];
  out->calibration_relative_sigma = out->channel_calibration_relative_sigma.maxCoeff();
  return k_times_e;
}

// Repeats: a single frame's block mean scatters about the pose's by the
// propagated noise (the dark, common to all, drops out). Adds each unclipped
// exposure's (n - 1) s^2 / sigma^2 to *ratio_sum and its n - 1 to the dof.
void CheckRepeats(const Measurement& m, const PoseFrames& pose, double* ratio_sum, BrdfMeasurement* out) {
  for (const auto& [exposure_us, e] : pose.exposures) {
    const int n = static_cast<int>(e.blocks.size());
    if (n < 2) continue;
    bool clips = false;
    for (const cv::Mat& b : e.blocks) {
      double peak;
      cv::minMaxLoc(b, nullptr, &peak);
      clips = clips || peak >= m.saturation_dn;
    }
    if (clips) continue;
    const cv::Mat signal = MeanOf(e.blocks) - m.dark_means.at(exposure_us).mean;
    const double pixels = signal.rows * signal.cols;
    double propagated = 0.0;
    for (int p = 0; p < signal.rows * signal.cols; ++p)
      propagated += m.read_var + out->shot_dn_per_dn * e.gain * std::max(signal.at<double>(p), 0.0);
    propagated /= pixels * pixels;
    std::vector<double> means;
    double mean_of_means = 0.0;
    for (const cv::Mat& b : e.blocks) {
      means.push_back(cv::mean(b)[0]);
      mean_of_means += means.back() / n;
    }
    double spread = 0.0;
    for (double v : means) spread += (v - mean_of_means) * (v - mean_of_means);
    *ratio_sum += spread / propagated;
    out->repeat_dof += n - 1;
  }
}

// One sample per pose above the horizon on both sides and unclipped at its shortest exposure.
void AddSamples(const Measurement& m, const Merger& merger, const Eigen::Vector3d& k_times_e, BrdfMeasurement* out) {
  out->poses = static_cast<int>(m.poses.size());
  double ratio_sum = 0.0;
  for (const PoseFrames& pose : m.poses) {
    if (pose.exposures.size() > 1) ++out->bracketed_poses;
    const brdf::DirectionPair dirs =
        brdf::ArmDirections({pose.pose.light_arm_deg, pose.pose.camera_arm_deg, pose.pose.sample_rotation_deg});
    if (dirs.wi.z() <= 0.0 || dirs.wo.z() <= 0.0) {
      ++out->below_horizon;
      continue;
    }
    const Merged merged = merger.Merge(pose);
    if (merged.clipped) {
      const double theta_h = brdf::ToHalfDiff(dirs.wi, dirs.wo).theta_h;
      out->clipped.push_back({pose.pose, theta_h * 180.0 / M_PI, pose.exposures.begin()->first});
      out->peak_clipped = out->peak_clipped || out->clipped.back().theta_h_deg < m.options.peak_theta_h_deg;
      continue;
    }
    const Eigen::Vector3d scale = k_times_e * pose.exposures.begin()->second.level * dirs.wi.z();
    brdf::BrdfSample s;
    s.wi = dirs.wi;
    s.wo = dirs.wo;
    s.value = merged.rate.cwiseQuotient(scale);
    s.sigma = merged.variance.cwiseSqrt().cwiseQuotient(scale);
    s.origin = brdf::SampleOrigin{pose.pose.light_arm_deg, pose.pose.camera_arm_deg, pose.pose.sample_rotation_deg,
                                  merged.longest_used_exposure_us, merged.frames_used};
    out->samples.push_back(s);
    CheckRepeats(m, pose, &ratio_sum, out);
  }
  if (out->repeat_dof > 0) out->repeat_sigma_ratio = std::sqrt(ratio_sum / out->repeat_dof);
}

}  // namespace

BrdfMeasurement MeasureBrdf(const std::string& run_dir, const RunManifest& manifest,
                            const BrdfMeasurementOptions& options) {
  BrdfMeasurement out;
  solvers::core::SolveTimer timer;
  Measurement m{run_dir, manifest, options, run_dir + ": "};
  if (!CheckRun(m, &out)) return out;
  SortFrames(m, &out);
  if (!MeasureDarks(m, &out) || !MeasureShotNoise(m, &out)) return out;
  const std::vector<int> site_channels = BlockChannels(manifest.mosaic, options.block_px);
  for (int channel : site_channels) ++out.channel_sites[channel];
  if (m.grey) out.channel_sites.setConstant(static_cast<int>(site_channels.size()));
  const Merger merger(m.dark_means, m.saturation_dn, m.read_var, out.shot_dn_per_dn, site_channels, m.grey);
  const std::optional<Eigen::Vector3d> k_times_e = Calibrate(m, merger, &out);
  if (!k_times_e) return out;
  AddSamples(m, merger, *k_times_e, &out);
  if (!m.grey && !manifest.color_model_path.empty()) ApplyColorModel(manifest, *k_times_e, &out);
  timer.Finish(&out);
  out.termination = Termination::kSuccess;
  return out;
}

}  // namespace photorig::daemon
