#pragma once
// A pinhole lens (intrinsics and OpenCV's k1, k2, p1, p2, k3) from photographs
// of a planar checkerboard in several poses: OpenCV finds the inner corners
// (findChessboardCorners, refined by cornerSubPix) and fits the lens to all
// of them (calibrateCamera). One of the photographs shows the board lying
// flat on the sample plane: its pose gives the camera's height above the
// plane (PinholeLens::distance_mm) and its tilt from the dome's axis, which
// must be small because Camera models a lens looking straight down.

#include "photorig/solvers/camera/camera.h"
#include "photorig/solvers/core/names.h"
#include "photorig/solvers/core/progress.h"
#include "photorig/solvers/core/summary.h"

#include <opencv2/core.hpp>

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace photorig::solvers::camera {

// The lens distortion a calibration fits: OpenCV's coefficients (k1, k2, p1,
// p2, k3) in nested models, from none to all five; the others stay 0.
enum class DistortionModel {
  kNone,               // a distortion-free pinhole
  kRadial1,            // k1
  kRadial2,            // k1, k2
  kRadial2Tangential,  // k1, k2, p1, p2 (a lens decentred from the sensor)
  kRadial3Tangential,  // k1, k2, p1, p2, k3 (a wide lens)
};
inline constexpr core::NameTable<DistortionModel, 5> kDistortionModelNames = {{
    {DistortionModel::kNone, "none"},
    {DistortionModel::kRadial1, "k1"},
    {DistortionModel::kRadial2, "k1-k2"},
    {DistortionModel::kRadial2Tangential, "k1-k2-p1-p2"},
    {DistortionModel::kRadial3Tangential, "k1-k2-p1-p2-k3"},
}};

struct CheckerboardCalibrationOptions {
  // Inner corners (where four squares meet) along a row and along a column
  // of the board: a board of 10 x 7 squares has 9 x 6.
  int inner_corners_cols = 0;
  int inner_corners_rows = 0;
  double square_mm = 0.0;  // side of one square
  // The image (index into the images) of the board lying flat on the sample plane.
  int plane_image = 0;
  // Images with a board needed: 9 intrinsics and 6 pose parameters per image
  // are fitted, and fewer than 4 poses leave the distortion ill-conditioned.
  int min_images = 4;
  // Above this overall RMS reprojection error (px) the corners or the model
  // are wrong (a warped board, a lens the 5 coefficients do not describe).
  double max_rms_px = 0.5;
  // Above this angle between the optical axis and the sample plane's normal
  // the looking-straight-down model misplaces pixels by more than it saves.
  double max_tilt_deg = 2.0;
  // The distortion model; empty (the default): chosen, the one of lowest
  // BIC on the corners. A model with more coefficients than the lens needs
  // fits the corners' noise and drags the principal point and the focal
  // length with it: a dome's narrow lens (tens of degrees across) bends its
  // corners too little for p1, p2 to tell a decentred lens from a shifted
  // principal point, or r^6 to tell k3 from k1, k2 and the focal length
  // (docs/cameras.md: a pixel's point on the sample plane moves by 1-2 px).
  std::optional<DistortionModel> distortion;
  // The corners found must reach at least this fraction of the way from the
  // principal point to the image's farthest corner (corner_reach). Beyond
  // them the distortion is extrapolated, and its highest terms grow with r^5:
  // at 0.6 the image's corners lie 1.7x out, where such a term is 13x what
  // the fit saw at the reach (sub-pixel for a corner noise of 0.05 px); at
  // 0.44, four central photographs' reach, 60x, and a full model misses by
  // 9 px there (docs/cameras.md).
  double min_corner_reach = 0.6;
  // cornerSubPix's search window: half its side (px). Must stay below half a
  // square's size in the image.
  int subpixel_half_window_px = 5;
  // Stage "corners": one unit per image; stage "fit": one unit, at the end.
  core::ProgressCallback progress;

  bool IsValid(std::string* why) const;
};

// One distortion model fitted to the corners.
struct DistortionCandidate {
  DistortionModel model = DistortionModel::kNone;
  double rms_px = 0.0;  // reprojection error over every corner
  // Schwarz's criterion on the 2 x corners residuals with 4 intrinsics, the
  // model's coefficients and 6 pose parameters per image.
  double bic = 0.0;
};

struct CheckerboardCalibrationSummary : core::Summary {
  int width_px = 0, height_px = 0;
  PinholeLens lens;  // usable only when IsSolutionUsable()
  // One standard deviation of fx, fy, cx, cy (px) and of the five distortion
  // coefficients, from the fit's covariance.
  double fx_std_px = 0.0, fy_std_px = 0.0, cx_std_px = 0.0, cy_std_px = 0.0;
  std::array<double, 5> distortion_std{};
  double rms_px = 0.0;     // reprojection error over every corner of every used image
  double tilt_deg = 0.0;   // optical axis from the plane image's board normal
  // How far out the corners found reach: the largest distance of one from
  // the principal point, as a fraction of the farthest image corner's.
  // Beyond it the distortion is extrapolated.
  double corner_reach = 0.0;
  // The images whose board was found, each with its RMS reprojection error
  // (px), and those without a board (by name).
  std::vector<std::string> used;
  std::vector<double> image_rms_px;
  std::vector<std::string> rejected;
  // The distortion model of `lens`, every model fitted (the simplest first;
  // one when the options fix it) and why this one was chosen.
  DistortionModel distortion_model = DistortionModel::kNone;
  std::vector<DistortionCandidate> candidates;
  std::string distortion_reason;
};

// Calibrates the lens from `images` (all the same size; 8- or 16-bit, grey
// or colour), named in messages by `names` (when as many as the images,
// otherwise "image <index>"). The corners are found once and every
// candidate distortion model is fitted to them. kSuccess with the lens; kInvalidOptions,
// kInvalidInput (empty or mixed-size images, no plane image), or kFailure
// (too few boards found, the plane image without one, RMS, tilt or the
// corners' reach beyond their limits) with the message naming the images and
// figures concerned.
CheckerboardCalibrationSummary CalibrateFromCheckerboards(const CheckerboardCalibrationOptions& options,
                                                          const std::vector<cv::Mat>& images,
                                                          const std::vector<std::string>& names = {});

}  // namespace photorig::solvers::camera
