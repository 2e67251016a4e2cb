#pragma once
// A 24-patch colour chart (ColorChecker layout: 4 rows x 6 columns, dark skin
// top-left) photographed by an RGB camera, rendered spectrally:
//   signal_c(patch) = sum_lambda R_patch(lambda) E(lambda) S_c(lambda)
// normalised so a perfect white gives 1 in the camera's most sensitive channel,
// then exposed through the sensor model channel by channel (independent noise).
// The spectral tables are inputs: the sim holds no colour data of its own.

#include "photorig/sim/sensor.h"

#include <opencv2/core.hpp>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace photorig::sim {

// Every spectrum sampled on the same wavelengths.
struct ChartSpectra {
  std::vector<double> wavelength_nm;
  std::vector<std::vector<double>> patch_reflectance;  // 24, row-major patch order
  std::vector<double> illuminant;                       // relative spectral power
  std::array<std::vector<double>, 3> camera_sensitivity;  // r, g, b

  bool IsValid(std::string* why) const;
};

struct ChartGeometry {
  int patch_px = 40;                   // side of one patch
  int gap_px = 8;                      // chart body between patches
  int border_px = 16;                  // chart body around the grid
  int margin_px = 32;                  // background around the chart
  double body_reflectance = 0.03;      // the chart's black body
  double background_reflectance = 0.35;  // what the chart lies on (spectrally flat)
  // The chart (with its margin) sits at this offset in a frame of this size;
  // a zero frame size means the frame is just the chart and its margin.
  cv::Point offset_px{0, 0};
  cv::Size frame_px{0, 0};

  int chart_width() const { return 2 * (margin_px + border_px) + 6 * patch_px + 5 * gap_px; }
  int chart_height() const { return 2 * (margin_px + border_px) + 4 * patch_px + 3 * gap_px; }
  int width() const { return frame_px.width > 0 ? frame_px.width : chart_width(); }
  int height() const { return frame_px.height > 0 ? frame_px.height : chart_height(); }
  cv::Rect PatchRect(int patch) const;  // patch 0..23
  // Outer corners of the 6 x 4 grid of cells (patch + half a gap on every side):
  // top-left (patch 1 side), top-right, bottom-right, bottom-left.
  std::array<cv::Point2f, 4> GridCorners() const;

  // A chart whose grid of cells fills `grid_box` (x, y, w, h in pixels, about
  // 6 x 4 square cells) in a frame of `frame` pixels, as a rig places it.
  // Throws std::invalid_argument if the cells are not square to a pixel, too
  // small to measure, or the chart does not fit in the frame.
  static ChartGeometry PlacedIn(const cv::Rect2d& grid_box, cv::Size frame);
};

struct ChartRender {
  cv::Mat signal;       // CV_32FC3 (r, g, b) noise-free camera signal, white = 1 in the top channel
  cv::Mat raw;          // CV_16UC3 in OpenCV's B, G, R order: what the camera delivers
  cv::Mat dark;         // CV_16UC3 the same exposure with the light off
  double clip_level_dn = 0.0;  // raw values at or above this may be clipped (full well or bit depth)
  std::array<double, 3> white_signal{};  // signal of a perfect white per channel
};

// Renders the chart lit by `spectra.illuminant` and exposes it. `exposure_us`
// and `gain_db` go to the sensor as for any frame; `seed` keys the noise.
ChartRender RenderColorChart(const ChartSpectra& spectra, const ChartGeometry& geometry, const SensorModel& sensor,
                             double exposure_us, double gain_db, std::uint64_t seed);

// A one-channel Bayer mosaic of a B, G, R image (the colour filter array in
// front of a single-chip sensor): each pixel keeps the channel its filter
// passes. `pattern` names the top-left 2 x 2 block: RGGB, BGGR, GRBG or GBRG.
// Throws std::invalid_argument on another name or a non-3-channel image.
cv::Mat BayerMosaic(const cv::Mat& bgr, const std::string& pattern);

// The exposure that puts a perfect white at `fraction` of the sensor's full well.
double ExposureForWhite(const SensorModel& sensor, double fraction);

}  // namespace photorig::sim
