#pragma once
// A flat checkerboard photographed by the simulated camera, evenly lit: the
// target of the lens calibration (solvers/camera/calibration.h). Each pixel
// averages a few rays through the lens (CameraModel's projection and
// distortion), each intersected with the board's plane.

#include "photorig/sim/camera_model.h"

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <cstdint>
#include <string>

namespace photorig::sim {

// The board in its own frame: the squares' grid centred on the origin in the
// plane z = 0, x along its rows, the white border around it.
struct Checkerboard {
  int inner_corners_cols = 9;  // inner corners along a row: squares per row - 1
  int inner_corners_rows = 6;
  double square_mm = 10.0;
  double border_mm = 10.0;      // white margin around the squares (the detector needs it)
  double dark = 0.05;           // reflectances: the dark squares,
  double light = 0.85;          // the light squares and the border,
  double background = 0.3;      // what lies beyond the board

  bool IsValid(std::string* why) const;
};

struct CheckerboardRenderOptions {
  int samples_per_axis = 4;  // n x n rays per pixel, jittered (anti-aliasing)
  int bit_depth = 8;         // 8 (CV_8U) or 16 (CV_16U); reflectance 1 is full scale
  double noise_sigma = 0.0;  // Gaussian noise, as a fraction of full scale
  std::uint64_t seed = 1;     // of the jitter and the noise

  bool IsValid(std::string* why) const;
};

// The board at `board_to_dome` (its frame into the dome's: x right, y up, z
// towards the camera) as `camera` sees it: one channel of `bit_depth`.
// Throws std::invalid_argument if the camera, board or options are invalid.
cv::Mat RenderCheckerboard(const CameraModel& camera, const Checkerboard& board, const Eigen::Isometry3d& board_to_dome,
                           const CheckerboardRenderOptions& options = {});

}  // namespace photorig::sim
