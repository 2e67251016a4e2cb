#pragma once
// Finding a 24-patch colour chart in an image and measuring its patches.
// Images are OpenCV's B, G, R order (8-bit, 16-bit or float); measurements come
// out as (r, g, b) in the image's units with the dark frame subtracted.

#include "photorig/solvers/color/spectrum.h"

#include "photorig/solvers/core/summary.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace photorig::solvers::color {

constexpr int kChartPatches = 24;
constexpr int kChartColumns = 6;
constexpr int kChartRows = 4;
constexpr int kWhitePatch = 18;  // patch 19, "white 9.5"

// Outer corners of the 6 x 4 grid of patch cells in image pixels: top-left
// (the dark-skin corner), top-right, bottom-right, bottom-left.
struct ChartLocation {
  std::array<cv::Point2f, 4> corners;
  std::string method;  // "detector" or "fixed-roi"

  cv::Point2f PatchCentre(int patch) const;
  // The central `fraction` of the patch's cell, as a polygon in the image.
  std::array<cv::Point2f, 4> SamplingQuad(int patch, double fraction) const;
};

struct LocateOptions {
  bool use_detector = true;  // OpenCV mcc CCheckerDetector first. Default on.
  // Where the chart sits on the rig (from the rig YAML or the command line);
  // used when detection is off or finds nothing. Finite corners, in order
  // round a convex quadrilateral (the grid's homography needs one). Default none.
  std::optional<std::array<cv::Point2f, 4>> fixed_corners;
  // Where fixed_corners came from, for messages and reports (e.g. "--chart-roi").
  std::string fixed_source = "the fixed chart position";

  bool IsValid(std::string* why) const;
};

// kSuccess with the location and how it was found (message); otherwise why
// nothing was found: kInvalidOptions, kInvalidInput (not a B, G, R image, a
// fixed corner outside it) or kFailure (no chart detected, no fixed position).
struct LocateResult : solvers::core::Summary {
  std::optional<ChartLocation> location;
};

// The detector first (if on), then the fixed position; a fixed position with a
// corner outside the image is refused with a message naming its source.
LocateResult LocateChart(const cv::Mat& image_bgr, const LocateOptions& options);

// Parses "x0,y0,x1,y1,x2,y2,x3,y3" (corners as in ChartLocation) or "x,y,w,h"
// (an axis-aligned rectangle), in pixels. nullopt, with *why (if given)
// saying what is wrong, for a field that is no number, a count other than 4
// or 8, or a width or height <= 0.
std::optional<std::array<cv::Point2f, 4>> ParseChartCorners(const std::string& text, std::string* why = nullptr);

enum class PatchFlag {
  kOk,
  kSaturated,     // too many clipped pixels to trust the mean
  kUnderexposed,  // mean not clearly above the noise
  kTooFewPixels,  // the sampling area is (partly) outside the image
};
const char* PatchFlagName(PatchFlag flag);

struct MeasureOptions {
  double sample_fraction = 0.5;     // central part of each cell that is averaged
  double trim_fraction = 0.1;       // dropped from each tail per channel (trimmed mean)
  // Raw values at or above this are clipped; 0 = the type's maximum (255, 65535) or none for float.
  double clip_level = 0.0;
  double black_level = 0.0;         // subtracted when no dark frame is given
  double max_clipped_fraction = 0.05;  // above this the patch is kSaturated
  double min_snr = 10.0;            // mean / standard error below this in any channel: kUnderexposed
  int min_pixels = 100;

  bool IsValid(std::string* why) const;
};

struct PatchMeasurement {
  Eigen::Vector3d rgb = Eigen::Vector3d::Zero();     // trimmed mean, dark subtracted
  Eigen::Vector3d stddev = Eigen::Vector3d::Zero();  // of the kept pixels
  int pixels = 0;          // sampled
  int clipped_pixels = 0;  // left out because a channel was clipped
  PatchFlag flag = PatchFlag::kOk;
};

// `dark_bgr` may be empty; otherwise it has the image's size and type.
// kInvalidOptions / kInvalidInput (with the reason) leave *patches untouched;
// patches that cannot be measured are flagged, not an error.
solvers::core::Summary MeasurePatches(const cv::Mat& image_bgr, const cv::Mat& dark_bgr, const ChartLocation& location,
                                const MeasureOptions& options, std::vector<PatchMeasurement>* patches);

// Reference XYZ (white Y = 1) of the BabelColor ColorChecker under an illuminant,
// summed over `grid_nm`, and that illuminant's white.
struct ChartReference {
  std::vector<Eigen::Vector3d> xyz;
  Eigen::Vector3d white_xyz;
};
ChartReference ColorCheckerReference(Illuminant illuminant, const std::vector<double>& grid_nm);

// What a spectral renderer needs to photograph the chart with a compiled-in
// camera under an illuminant, all resampled to `grid_nm`; nullopt for a
// camera not in CameraNames().
struct ChartCaptureSpectra {
  std::vector<double> wavelength_nm;
  std::vector<std::vector<double>> patch_reflectance;     // 24
  std::vector<double> illuminant;
  std::array<std::vector<double>, 3> camera_sensitivity;  // r, g, b
};
std::optional<ChartCaptureSpectra> ChartCaptureSpectraFor(const std::string& camera, Illuminant illuminant,
                                                          const std::vector<double>& grid_nm);

}  // namespace photorig::solvers::color
