#pragma once
// A dome's camera with a distorting lens and a checkerboard photographed by
// it in poses that cover the field of view, flat on the sample plane first:
// the lens calibration's test and chart data, rendered by the simulator.

#include "photorig/sim/checkerboard.h"

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <vector>

namespace photorig::testing {

using photorig::sim::CameraModel;
using photorig::sim::Checkerboard;
using photorig::sim::RenderCheckerboard;

inline constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

// The dome's camera: 384 x 384 px, 30 deg across, 300 mm above the plane.
inline CameraModel TrueCamera() {
  CameraModel camera;
  camera.projection = CameraModel::Projection::kPinhole;
  camera.fx = camera.fy = 716.55;
  camera.cx = 195.0;  // off centre, so the fit has to find it
  camera.cy = 190.0;
  camera.distance_mm = 300.0;
  camera.distortion = {-0.05, 0.01, 0.0, 0.0, 0.0};
  return camera;
}

inline Checkerboard Board() {
  Checkerboard board;
  board.inner_corners_cols = 9;
  board.inner_corners_rows = 6;
  board.square_mm = 10.0;
  board.border_mm = 8.0;
  return board;
}

// The board turned by `tilt_x_deg`, `tilt_y_deg` and `spin_deg` about its
// centre, which is moved to `centre_mm`.
inline Eigen::Isometry3d Pose(double tilt_x_deg, double tilt_y_deg, double spin_deg, const Eigen::Vector3d& centre_mm) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translate(centre_mm);
  pose.rotate(Eigen::AngleAxisd(tilt_x_deg * kDegToRad, Eigen::Vector3d::UnitX()) *
              Eigen::AngleAxisd(tilt_y_deg * kDegToRad, Eigen::Vector3d::UnitY()) *
              Eigen::AngleAxisd(spin_deg * kDegToRad, Eigen::Vector3d::UnitZ()));
  return pose;
}

// Flat on the sample plane first, then tilted about its centre (for the
// focal length) and turned into the image's corners (for the distortion).
inline std::vector<Eigen::Isometry3d> Poses() {
  return {Pose(0, 0, 0, {0, 0, 0}),         Pose(40, 0, 0, {0, 0, 20}),        Pose(-40, 0, 0, {0, 0, 20}),
          Pose(0, 40, 0, {0, 0, 20}),       Pose(0, -40, 0, {0, 0, 20}),       Pose(20, 20, 0, {24, 36, 10}),
          Pose(20, -20, 0, {-24, 36, 10}),  Pose(-20, 20, 0, {24, -36, 10}),   Pose(-20, -20, 0, {-24, -36, 10}),
          Pose(30, 30, 20, {0, 0, 30}),     Pose(-30, 30, -20, {0, 0, 30}),    Pose(30, -30, -20, {0, 0, 30}),
          Pose(-30, -30, 20, {0, 0, 30})};
}

// Each pose photographed with noise of `noise_sigma` of full scale.
inline std::vector<cv::Mat> Render(const CameraModel& camera, const std::vector<Eigen::Isometry3d>& poses,
                                   double noise_sigma = 0.005) {
  std::vector<cv::Mat> images;
  photorig::sim::CheckerboardRenderOptions render;
  render.noise_sigma = noise_sigma;
  for (const Eigen::Isometry3d& pose : poses) {
    images.push_back(RenderCheckerboard(camera, Board(), pose, render));
    ++render.seed;
  }
  return images;
}

}  // namespace photorig::testing
