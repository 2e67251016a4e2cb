#include "photorig/color/apply.h"

#include "photorig/color/colorimetry.h"

#include <algorithm>
#include <stdexcept>

namespace photorig::color {

bool ApplyOptions::IsValid(std::string* why) const {
  if (!(exposure_ratio > 0.0)) {
    if (why) *why = "exposure_ratio must be > 0";
    return false;
  }
  return true;
}

cv::Mat CameraToXyz(const ColorModel& model, const cv::Mat& camera_bgr, const cv::Mat& dark_bgr,
                    const ApplyOptions& options) {
  std::string why;
  if (!model.IsValid(&why)) throw std::invalid_argument("colour model: " + why);
  if (!options.IsValid(&why)) throw std::invalid_argument("apply options: " + why);
  if (camera_bgr.channels() != 3)
    throw std::invalid_argument("colour correction needs a 3-channel image, got " +
                                std::to_string(camera_bgr.channels()) + " channel(s)");
  if (!dark_bgr.empty() && (dark_bgr.size() != camera_bgr.size() || dark_bgr.channels() != 3))
    throw std::invalid_argument("dark frame must be 3-channel and the image's size");
  cv::Mat rgb;
  camera_bgr.convertTo(rgb, CV_32FC3);
  if (!dark_bgr.empty()) {
    cv::Mat dark;
    dark_bgr.convertTo(dark, CV_32FC3);
    rgb -= dark;
  } else if (options.black_level != 0.0) {
    rgb -= cv::Scalar::all(options.black_level);
  }
  const int terms = model.spec.TermCount();
  // Row-major copy of C^T so the inner loop reads it contiguously.
  double c[3][kMaxModelTerms];
  for (int out = 0; out < 3; ++out)
    for (int t = 0; t < terms; ++t) c[out][t] = model.coefficients(t, out);
  const double scale = model.input_scale / options.exposure_ratio;
  cv::Mat xyz(rgb.size(), CV_32FC3);
#pragma omp parallel for schedule(static)
  for (int y = 0; y < rgb.rows; ++y) {
    const cv::Vec3f* in = rgb.ptr<cv::Vec3f>(y);
    cv::Vec3f* out = xyz.ptr<cv::Vec3f>(y);
    double f[kMaxModelTerms];
    for (int x = 0; x < rgb.cols; ++x) {
      FillModelFeatures(model.spec, scale * in[x][2], scale * in[x][1], scale * in[x][0], f);
      for (int k = 0; k < 3; ++k) {
        double sum = 0.0;
        for (int t = 0; t < terms; ++t) sum += c[k][t] * f[t];
        out[x][k] = static_cast<float>(sum);
      }
    }
  }
  return xyz;
}

std::vector<cv::Mat> CameraStackToXyz(const ColorModel& model, const std::vector<cv::Mat>& stack_bgr,
                                      const cv::Mat& dark_bgr, const ApplyOptions& options) {
  std::vector<cv::Mat> out;
  out.reserve(stack_bgr.size());
  for (const cv::Mat& frame : stack_bgr) out.push_back(CameraToXyz(model, frame, dark_bgr, options));
  return out;
}

cv::Mat XyzToLinearSrgbBgr(const cv::Mat& xyz, const Eigen::Vector3d& white_xyz) {
  if (xyz.type() != CV_32FC3) throw std::invalid_argument("XYZ image must be CV_32FC3");
  const Eigen::Vector3d d65 = LinearSrgbToXyzD65() * Eigen::Vector3d::Ones();
  const Eigen::Matrix3d m = XyzD65ToLinearSrgb() * BradfordAdaptation(white_xyz, d65);
  // Output rows in B, G, R order.
  cv::Matx33f to_bgr;
  for (int r = 0; r < 3; ++r)
    for (int col = 0; col < 3; ++col) to_bgr(r, col) = static_cast<float>(m(2 - r, col));
  cv::Mat bgr;
  cv::transform(xyz, bgr, to_bgr);
  return bgr;
}

cv::Mat XyzToSrgb8(const cv::Mat& xyz, const Eigen::Vector3d& white_xyz) {
  const cv::Mat linear = XyzToLinearSrgbBgr(xyz, white_xyz);
  // A 4096-entry table of the transfer function: exact to 8 bits and cheap per pixel.
  static const std::vector<std::uint8_t> table = [] {
    std::vector<std::uint8_t> t(4096);
    for (int i = 0; i < 4096; ++i) t[i] = cv::saturate_cast<std::uint8_t>(255.0 * SrgbEncode((i + 0.5) / 4096.0));
    return t;
  }();
  cv::Mat out(linear.size(), CV_8UC3);
  for (int y = 0; y < linear.rows; ++y) {
    const float* in = linear.ptr<float>(y);
    std::uint8_t* o = out.ptr<std::uint8_t>(y);
    for (int i = 0; i < linear.cols * 3; ++i) {
      const int index = static_cast<int>(std::clamp(in[i], 0.0f, 1.0f) * 4095.0f);
      o[i] = table[static_cast<std::size_t>(index)];
    }
  }
  return out;
}

}  // namespace photorig::color
