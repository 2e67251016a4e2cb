#pragma once
// What a lens calibration from the checkerboard scene promises of the lens it
// recovers.

#include "checkerboard_scene.h"
#include "photorig/solvers/camera/camera.h"

#include <gtest/gtest.h>

namespace photorig::testing {

// What a calibration promises of the lens it recovers from these photographs.
inline void ExpectLensMatches(const solvers::camera::PinholeLens& lens, const CameraModel& truth) {
  EXPECT_NEAR(lens.fx_px, truth.fx, 0.005 * truth.fx);
  EXPECT_NEAR(lens.fy_px, truth.fy, 0.005 * truth.fy);
  // OpenCV's principal point is half a pixel before the simulator's.
  EXPECT_NEAR(lens.cx_px, truth.cx - 0.5, 1.0);
  EXPECT_NEAR(lens.cy_px, truth.cy - 0.5, 1.0);
  EXPECT_NEAR(lens.distortion[0], truth.distortion[0], 0.01);
  EXPECT_NEAR(lens.distance_mm, truth.distance_mm, 0.01 * truth.distance_mm);
}

}  // namespace photorig::testing
