#include "photorig/solvers/lighting/relight.h"

#include "photorig/solvers/lighting/spherical_harmonics.h"

#include <cmath>
#include <string>

namespace photorig::solvers::lighting {
namespace {

using solvers::core::Ended;
using solvers::core::Termination;

// The band whose coefficient count is `rows`; -1 if `rows` is not a square.
int ShBandOf(Eigen::Index rows) {
  const int band = static_cast<int>(std::lround(std::sqrt(static_cast<double>(rows)))) - 1;
  return band >= 0 && ShCoefficientCount(band) == rows ? band : -1;
}

// Output channel k of a 3-channel image is stored BGR: colour column 2 - k.
int ColourColumn(int stored_channel, int channels) { return channels == 3 ? 2 - stored_channel : 0; }

}  // namespace

solvers::core::Summary RenderShLighting(const cv::Mat& normals, const cv::Mat& albedo, const Eigen::MatrixXd& coefficients,
                                  cv::Mat* image) {
  const solvers::core::SolveTimer timer;
  if (normals.type() != CV_32FC3 || albedo.size() != normals.size() || albedo.depth() != CV_32F) {
    return Ended(Termination::kInvalidInput, "normals must be CV_32FC3 and albedo CV_32F of the same size");
  }
  const int band = ShBandOf(coefficients.rows());
  if (band < 0) {
    return Ended(Termination::kInvalidInput,
                 std::to_string(coefficients.rows()) + " SH coefficients is not (band + 1)^2 for any band");
  }
  const int channels = static_cast<int>(coefficients.cols());
  if (channels != 1 && channels != 3) {
    return Ended(Termination::kInvalidInput, "1 or 3 coefficient columns, got " + std::to_string(channels));
  }
  if (albedo.channels() != 1 && albedo.channels() != channels) {
    return Ended(Termination::kInvalidInput, "albedo must have 1 channel or one per coefficient column");
  }
  // Irradiance coefficients E_lm = A_l L_lm, scaled by 1/pi for radiance.
  Eigen::MatrixXd irradiance = coefficients;
  for (int l = 0; l <= band; ++l) irradiance.middleRows(l * l, 2 * l + 1) *= LambertianKernel(l) / M_PI;
  cv::Mat out(normals.size(), CV_MAKETYPE(CV_32F, channels), cv::Scalar::all(0));
#pragma omp parallel for
  for (int r = 0; r < normals.rows; ++r) {
    Eigen::VectorXd y(ShCoefficientCount(band));
    const cv::Vec3f* n_row = normals.ptr<cv::Vec3f>(r);
    const float* a_row = albedo.ptr<float>(r);
    float* out_row = out.ptr<float>(r);
    for (int c = 0; c < normals.cols; ++c) {
      const Eigen::Vector3d n(n_row[c][0], n_row[c][1], n_row[c][2]);
      if (n.squaredNorm() < 0.5) continue;
      EvaluateSh(band, n.normalized(), y.data());
      for (int k = 0; k < channels; ++k) {
        const double a = a_row[albedo.channels() == 1 ? c : c * albedo.channels() + k];
        out_row[c * channels + k] = static_cast<float>(a * y.dot(irradiance.col(ColourColumn(k, channels))));
      }
    }
  }
  *image = out;
  return timer.Succeeded();
}

solvers::core::Summary RenderDirectionalLights(const cv::Mat& normals, const cv::Mat& albedo,
                                         const std::vector<Eigen::Vector3d>& directions,
                                         const std::vector<double>& intensities, cv::Mat* image) {
  const solvers::core::SolveTimer timer;
  if (normals.type() != CV_32FC3 || albedo.size() != normals.size() || albedo.type() != CV_32FC1) {
    return Ended(Termination::kInvalidInput, "normals must be CV_32FC3 and albedo CV_32FC1 of the same size");
  }
  if (directions.size() != intensities.size()) {
    return Ended(Termination::kInvalidInput, std::to_string(directions.size()) + " light directions for " +
                                                 std::to_string(intensities.size()) + " intensities");
  }
  cv::Mat out(normals.size(), CV_32F, cv::Scalar(0));
  for (int r = 0; r < normals.rows; ++r) {
    const cv::Vec3f* n_row = normals.ptr<cv::Vec3f>(r);
    for (int c = 0; c < normals.cols; ++c) {
      const Eigen::Vector3d n(n_row[c][0], n_row[c][1], n_row[c][2]);
      double sum = 0.0;
      for (std::size_t k = 0; k < directions.size(); ++k) {
        sum += intensities[k] * std::max(0.0, n.dot(directions[k].normalized()));
      }
      out.at<float>(r, c) = static_cast<float>(albedo.at<float>(r, c) / M_PI * sum);
    }
  }
  *image = out;
  return timer.Succeeded();
}

solvers::core::Summary RelightFromFrames(const std::vector<cv::Mat>& frames, const Eigen::MatrixXd& weights, cv::Mat* image) {
  const solvers::core::SolveTimer timer;
  if (frames.empty() || static_cast<Eigen::Index>(frames.size()) != weights.rows() ||
      (weights.cols() != 1 && weights.cols() != 3)) {
    return Ended(Termination::kInvalidInput, "needs one weight row per frame and 1 or 3 columns (" +
                                                 std::to_string(frames.size()) + " frames, " +
                                                 std::to_string(weights.rows()) + " x " +
                                                 std::to_string(weights.cols()) + " weights)");
  }
  for (std::size_t k = 0; k < frames.size(); ++k) {
    if (frames[k].empty() || frames[k].size() != frames[0].size() || frames[k].channels() != 1) {
      return Ended(Termination::kInvalidInput, "frame " + std::to_string(k) +
                                                   " is not single-channel or differs from frame 0 in size");
    }
  }
  const int channels = static_cast<int>(weights.cols());
  std::vector<cv::Mat> planes(static_cast<std::size_t>(channels));
  for (auto& p : planes) p = cv::Mat::zeros(frames[0].size(), CV_32F);
  cv::Mat frame;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    frames[k].convertTo(frame, CV_32F);
    for (int ch = 0; ch < channels; ++ch) {
      const double w = weights(static_cast<Eigen::Index>(k), ColourColumn(ch, channels));
      if (w != 0.0) cv::scaleAdd(frame, w, planes[static_cast<std::size_t>(ch)], planes[static_cast<std::size_t>(ch)]);
    }
  }
  cv::merge(planes, *image);
  return timer.Succeeded();
}

}  // namespace photorig::solvers::lighting
