#include "photorig/lighting/relight.h"

#include "photorig/lighting/spherical_harmonics.h"

#include <cmath>
#include <stdexcept>

namespace photorig::lighting {
namespace {

int ShBandOf(Eigen::Index rows) {
  const int band = static_cast<int>(std::lround(std::sqrt(static_cast<double>(rows)))) - 1;
  if (band < 0 || ShCoefficientCount(band) != rows) throw std::invalid_argument("SH coefficient count is not a square");
  return band;
}

// Output channel k of a 3-channel image is stored BGR: colour column 2 - k.
int ColourColumn(int stored_channel, int channels) { return channels == 3 ? 2 - stored_channel : 0; }

}  // namespace

cv::Mat RenderShLighting(const cv::Mat& normals, const cv::Mat& albedo, const Eigen::MatrixXd& coefficients) {
  if (normals.type() != CV_32FC3 || albedo.size() != normals.size() || albedo.depth() != CV_32F) {
    throw std::invalid_argument("RenderShLighting: normals CV_32FC3 and albedo CV_32F of the same size");
  }
  const int band = ShBandOf(coefficients.rows());
  const int channels = static_cast<int>(coefficients.cols());
  if (channels != 1 && channels != 3) throw std::invalid_argument("RenderShLighting: 1 or 3 coefficient columns");
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
  return out;
}

cv::Mat RenderDirectionalLights(const cv::Mat& normals, const cv::Mat& albedo,
                                const std::vector<Eigen::Vector3d>& directions,
                                const std::vector<double>& intensities) {
  if (normals.type() != CV_32FC3 || albedo.size() != normals.size() || albedo.type() != CV_32FC1 ||
      directions.size() != intensities.size()) {
    throw std::invalid_argument("RenderDirectionalLights: normals CV_32FC3, albedo CV_32FC1, one intensity per light");
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
  return out;
}

cv::Mat RelightFromFrames(const std::vector<cv::Mat>& frames, const Eigen::MatrixXd& weights) {
  if (frames.empty() || static_cast<Eigen::Index>(frames.size()) != weights.rows() ||
      (weights.cols() != 1 && weights.cols() != 3)) {
    throw std::invalid_argument("RelightFromFrames: one weight row per frame, 1 or 3 columns");
  }
  const int channels = static_cast<int>(weights.cols());
  std::vector<cv::Mat> planes(static_cast<std::size_t>(channels));
  for (auto& p : planes) p = cv::Mat::zeros(frames[0].size(), CV_32F);
  cv::Mat frame;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    if (frames[k].size() != frames[0].size() || frames[k].channels() != 1) {
      throw std::invalid_argument("RelightFromFrames: frames must be single-channel and the same size");
    }
    frames[k].convertTo(frame, CV_32F);
    for (int ch = 0; ch < channels; ++ch) {
      const double w = weights(static_cast<Eigen::Index>(k), ColourColumn(ch, channels));
      if (w != 0.0) cv::scaleAdd(frame, w, planes[static_cast<std::size_t>(ch)], planes[static_cast<std::size_t>(ch)]);
    }
  }
  cv::Mat out;
  cv::merge(planes, out);
  return out;
}

}  // namespace photorig::lighting
