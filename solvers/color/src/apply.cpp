#include "photorig/solvers/color/apply.h"

#include "photorig/solvers/color/colorimetry.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <string>

namespace photorig::solvers::color {

bool ApplyOptions::IsValid(std::string* why) const {
  if (!(exposure_ratio > 0.0)) {
    if (why) *why = "exposure_ratio must be > 0";
    return false;
  }
  return true;
}

using solvers::core::Ended;
using solvers::core::Termination;

solvers::core::Summary CameraToXyz(const ColorModel& model, const cv::Mat& camera_bgr, const cv::Mat& dark_bgr,
                             const ApplyOptions& options, cv::Mat* xyz_out) {
  const solvers::core::SolveTimer timer;
  std::string why;
  if (!options.IsValid(&why)) return Ended(Termination::kInvalidOptions, "invalid options: " + why);
  if (!model.IsValid(&why)) return Ended(Termination::kInvalidInput, "colour model: " + why);
  if (camera_bgr.empty() || camera_bgr.channels() != 3) {
    return Ended(Termination::kInvalidInput, "colour correction needs a 3-channel image, got " +
                                                 std::to_string(camera_bgr.channels()) + " channel(s)");
  }
  if (!dark_bgr.empty() && (dark_bgr.size() != camera_bgr.size() || dark_bgr.channels() != 3)) {
    return Ended(Termination::kInvalidInput, "dark frame must be 3-channel and the image's size");
  }
  const int terms = model.spec.TermCount();
  float c[3][kMaxModelTerms];
  for (int out = 0; out < 3; ++out)
    for (int t = 0; t < terms; ++t) c[out][t] = static_cast<float>(model.coefficients(t, out));
  const float scale = static_cast<float>(model.input_scale / options.exposure_ratio);
  const float black = dark_bgr.empty() ? static_cast<float>(options.black_level) : 0.0f;
  cv::Mat xyz(camera_bgr.size(), CV_32FC3);
  // Rows in blocks of kBlock pixels, held as structure of arrays so that every
  // step (dark subtraction, features, the 3 x terms product) is a loop the
  // compiler vectorises; the whole block stays in L1.
  constexpr int kBlock = 256;
#pragma omp parallel
  {
    cv::Mat row_rgb, row_dark;
    alignas(64) float f[kMaxModelTerms][kBlock], acc[3][kBlock];
    float* features[kMaxModelTerms];
    for (int t = 0; t < kMaxModelTerms; ++t) features[t] = f[t];
    float* r = f[0];
    float* g = f[1];
    float* b = f[2];
#pragma omp for schedule(static)
    for (int y = 0; y < camera_bgr.rows; ++y) {
      camera_bgr.row(y).convertTo(row_rgb, CV_32FC3);
      if (!dark_bgr.empty()) dark_bgr.row(y).convertTo(row_dark, CV_32FC3);
      const float* in = row_rgb.ptr<float>();
      const float* dark = dark_bgr.empty() ? nullptr : row_dark.ptr<float>();
      float* out = xyz.ptr<float>(y);
      for (int x0 = 0; x0 < camera_bgr.cols; x0 += kBlock) {
        const int n = std::min(kBlock, camera_bgr.cols - x0);
        const float* p = in + 3 * x0;
        if (dark) {
          const float* d = dark + 3 * x0;
          for (int i = 0; i < n; ++i)
            b[i] = scale * (p[3 * i] - d[3 * i]), g[i] = scale * (p[3 * i + 1] - d[3 * i + 1]),
            r[i] = scale * (p[3 * i + 2] - d[3 * i + 2]);
        } else {
          for (int i = 0; i < n; ++i)
            b[i] = scale * (p[3 * i] - black), g[i] = scale * (p[3 * i + 1] - black), r[i] = scale * (p[3 * i + 2] - black);
        }
        FillModelFeatures(model.spec, n, features);
        for (int k = 0; k < 3; ++k) {
          for (int i = 0; i < n; ++i) acc[k][i] = c[k][0] * f[0][i];
          for (int t = 1; t < terms; ++t)
            for (int i = 0; i < n; ++i) acc[k][i] += c[k][t] * f[t][i];
        }
        float* o = out + 3 * x0;
        for (int i = 0; i < n; ++i) o[3 * i] = acc[0][i], o[3 * i + 1] = acc[1][i], o[3 * i + 2] = acc[2][i];
      }
    }
  }
  *xyz_out = xyz;
  return timer.Succeeded();
}

solvers::core::Summary Demosaic(const cv::Mat& raw, const std::string& pattern, cv::Mat* bgr, DemosaicMethod method) {
  const solvers::core::SolveTimer timer;
  if (raw.empty() || raw.channels() != 1) {
    return Ended(Termination::kInvalidInput, "a Bayer raw has one channel, got " + std::to_string(raw.channels()));
  }
  if (raw.depth() != CV_8U && raw.depth() != CV_16U) {
    return Ended(Termination::kInvalidInput, "a Bayer raw must be 8- or 16-bit");
  }
  const bool ea = method == DemosaicMethod::kEdgeAware;
  int code = 0;
  if (pattern == "RGGB") code = ea ? cv::COLOR_BayerRGGB2BGR_EA : cv::COLOR_BayerRGGB2BGR;
  else if (pattern == "BGGR") code = ea ? cv::COLOR_BayerBGGR2BGR_EA : cv::COLOR_BayerBGGR2BGR;
  else if (pattern == "GRBG") code = ea ? cv::COLOR_BayerGRBG2BGR_EA : cv::COLOR_BayerGRBG2BGR;
  else if (pattern == "GBRG") code = ea ? cv::COLOR_BayerGBRG2BGR_EA : cv::COLOR_BayerGBRG2BGR;
  else {
    return Ended(Termination::kInvalidOptions,
                 "unknown Bayer pattern '" + pattern + "' (expected RGGB, BGGR, GRBG or GBRG)");
  }
  cv::cvtColor(raw, *bgr, code);
  return timer.Succeeded();
}

solvers::core::Summary XyzToLinearSrgbBgr(const cv::Mat& xyz, const Eigen::Vector3d& white_xyz, cv::Mat* bgr) {
  const solvers::core::SolveTimer timer;
  if (xyz.type() != CV_32FC3) return Ended(Termination::kInvalidInput, "XYZ image must be CV_32FC3");
  if (!white_xyz.allFinite() || !(white_xyz.y() > 0.0)) {
    return Ended(Termination::kInvalidInput, "the white point must be finite with Y > 0");
  }
  const Eigen::Vector3d d65 = LinearSrgbToXyzD65() * Eigen::Vector3d::Ones();
  const Eigen::Matrix3d m = XyzD65ToLinearSrgb() * BradfordAdaptation(white_xyz, d65);
  // Output rows in B, G, R order.
  cv::Matx33f to_bgr;
  for (int r = 0; r < 3; ++r)
    for (int col = 0; col < 3; ++col) to_bgr(r, col) = static_cast<float>(m(2 - r, col));
  cv::transform(xyz, *bgr, to_bgr);
  return timer.Succeeded();
}

solvers::core::Summary XyzToSrgb8(const cv::Mat& xyz, const Eigen::Vector3d& white_xyz, cv::Mat* bgr) {
  const solvers::core::SolveTimer timer;
  cv::Mat linear;
  const solvers::core::Summary converted = XyzToLinearSrgbBgr(xyz, white_xyz, &linear);
  if (!converted.IsSolutionUsable()) return converted;
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
  *bgr = out;
  return timer.Succeeded();
}

}  // namespace photorig::solvers::color
