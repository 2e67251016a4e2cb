#pragma once
// Colour calibration from a capture of a 24-patch ColorChecker (or the
// simulated rig's rendering of one): the chart located, measured and fitted
// by solvers/color's CalibrateChartImage, and the results written as
// report.json, report.txt, model.json, model.yaml and corrected_srgb.png
// (docs/color.md). Used by `photorig calibrate color` and photorig.calibrate_color.

#include "photorig/solvers/color/calibration.h"

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace photorig::daemon {

struct ColorCalibrationRequest {
  // Exactly one of: a chart capture (B, G, R; 8/16-bit or float, or a Bayer
  // raw with `bayer`) with an optional dark frame at the same exposure, or the
  // name of a simulated camera whose chart capture is rendered into the output
  // folder as chart.png and dark.png.
  std::string image, dark;
  std::string sim_camera;
  std::uint64_t seed = 1;  // the rendering's noise
  solvers::color::Illuminant illuminant = solvers::color::Illuminant::kD65;
  // A rig file: its camera.color_chart is the fixed chart position (with
  // sim_camera: the rig's sensor, frame and chart placement too).
  std::string rig;
  std::string chart_roi;  // x,y,w,h or the four corners; overrides the rig's
  std::string chart_roi_name = "chart_roi";  // how messages name it (the CLI: --chart-roi)
  bool detect = true;     // the mcc detector first; false: the fixed position only
  std::string bayer;      // RGGB, BGGR, GRBG, GBRG: the captures are one-channel raws
  double white_level = 0.0;  // raw value at which pixels clip (0: the type's maximum; the rendering's with sim_camera)
  double black_level = 0.0;  // subtracted when there is no dark frame
  solvers::color::CalibrationOptions calibration;
};

struct ColorCalibrationResult {
  solvers::color::ChartCalibration chart;
  nlohmann::json report;  // report.json
  std::string table;      // report.txt: each model's errors, the chosen one's per patch
  std::string rendered;   // with sim_camera: what was rendered, in words
  // The chosen model applied to the chart failed: why (the model files are
  // written; corrected_srgb.png is not). Empty otherwise.
  std::string apply_failure;
  bool usable() const { return chart.summary.IsSolutionUsable() && apply_failure.empty(); }
};

// Throws std::invalid_argument for a request that cannot run: both or
// neither of image and sim_camera, an unknown camera, options
// CalibrationOptions::IsValid refuses, a bad chart_roi, a rig file that does
// not load (all before anything is written), or a capture that cannot be
// read or looks like an unnamed Bayer raw (before anything but the
// rendering is written). A chart that is not found or gives no usable model
// is a result whose summary says why; report.json is written either way,
// the model files only for a usable model.
ColorCalibrationResult CalibrateColor(ColorCalibrationRequest request, const std::string& out_directory);

// The candidates named (linear, affine, root-poly-2, ...), in order. Throws
// std::invalid_argument naming an unknown one and the known ones.
std::vector<solvers::color::ModelSpec> ParseColorModels(const std::vector<std::string>& names);

// A capture as the colour commands read it: a one-channel Bayer raw
// demosaiced to B, G, R with `bayer`, anything else as read. Throws
// std::invalid_argument for a file that cannot be read, a one-channel image whose 2x2 phases differ as a
// mosaic's do when `bayer` is empty, or that cannot be demosaiced.
cv::Mat ReadColorCapture(const std::string& path, const std::string& bayer);

}  // namespace photorig::daemon
