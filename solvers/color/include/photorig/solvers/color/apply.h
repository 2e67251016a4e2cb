#pragma once
// Applying a colour model to images: a camera RGB image (OpenCV B, G, R order,
// any depth) -> CIE XYZ (relative to the calibration illuminant's white, Y = 1)
// -> sRGB for display. Works on any 3-channel capture or a per-channel
// photometric-stereo albedo map.

#include "photorig/solvers/color/model.h"

#include "photorig/solvers/core/names.h"
#include "photorig/solvers/core/summary.h"

#include <opencv2/core.hpp>

#include <string>

namespace photorig::solvers::color {

struct ApplyOptions {
  double black_level = 0.0;     // subtracted when no dark frame is given
  // Exposure x gain of the image relative to the chart capture: RGB is divided
  // by it, so a model keeps absolute luminance across exposures.
  double exposure_ratio = 1.0;
  bool IsValid(std::string* why) const;
};

// Each returns a solvers::core::Summary; on kInvalidOptions or kInvalidInput (the
// reason in its message) the output is left untouched. Nothing throws.

// *xyz: CV_32FC3 (X, Y, Z). camera_bgr: 3 channels, any depth; `dark_bgr` may
// be empty, else 3 channels of the image's size.
solvers::core::Summary CameraToXyz(const ColorModel& model, const cv::Mat& camera_bgr, const cv::Mat& dark_bgr,
                             const ApplyOptions& options, cv::Mat* xyz);

// How Bayer raws are interpolated (OpenCV).
enum class DemosaicMethod {
  // Bilinear (COLOR_Bayer*2BGR): linear in the raw values, so dark
  // subtraction, exposure scaling and averaging commute with it, and its
  // noise is a fixed linear filter of the raw noise. The default: photometric
  // stereo divides images by each other, and that is exact only for a linear
  // interpolation.
  kBilinear,
  // Edge-aware (COLOR_Bayer*2BGR_EA): interpolates along edges, fewer colour
  // fringes at texture edges, but chooses its direction from the data, so it
  // is not linear in the raw values.
  kEdgeAware,
};
inline constexpr core::NameTable<DemosaicMethod, 2> kDemosaicMethodNames = {
    {{DemosaicMethod::kBilinear, "bilinear"}, {DemosaicMethod::kEdgeAware, "edge-aware"}}};
inline const char* DemosaicMethodName(DemosaicMethod method) { return core::NameOf(kDemosaicMethodNames, method); }

// A single-chip sensor's raw Bayer mosaic (one channel, 8/16-bit) -> B, G, R of
// the same depth. `pattern` names the top-left 2 x 2 filter block: RGGB, BGGR,
// GRBG or GBRG. Bilinear demosaicing is linear, so a dark frame may be
// demosaiced the same way and subtracted afterwards.
solvers::core::Summary Demosaic(const cv::Mat& raw, const std::string& pattern, cv::Mat* bgr,
                          DemosaicMethod method = DemosaicMethod::kBilinear);

// XYZ (CV_32FC3, white = `white_xyz`) -> linear sRGB, adapting the white to
// D65 (Bradford). CV_32FC3 in B, G, R order, unclipped.
solvers::core::Summary XyzToLinearSrgbBgr(const cv::Mat& xyz, const Eigen::Vector3d& white_xyz, cv::Mat* bgr);
// The same, clipped to [0, 1], encoded with the sRGB transfer function, 8-bit B, G, R.
solvers::core::Summary XyzToSrgb8(const cv::Mat& xyz, const Eigen::Vector3d& white_xyz, cv::Mat* bgr);

}  // namespace photorig::solvers::color
