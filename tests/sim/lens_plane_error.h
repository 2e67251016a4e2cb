#pragma once
// How far a calibrated lens puts each pixel's view of the sample plane from
// where the simulated lens puts it: the error that matters downstream (near
// lights and perspective solves place every pixel's point on the plane).

#include "photorig/sim/camera_model.h"
#include "photorig/solvers/camera/camera.h"

#include <algorithm>
#include <cmath>

namespace photorig::testing {

struct PlaneError {
  double rms_px = 0.0, max_px = 0.0;  // on the sample plane, in pixels of the true lens at its centre
};

// Every `step`-th pixel's line of sight met with the plane z = 0, by the
// truth and by `fitted`.
inline PlaneError LensPlaneError(const sim::CameraModel& truth, const solvers::camera::PinholeLens& fitted,
                                 int step = 4) {
  solvers::camera::Camera camera;
  camera.projection = solvers::camera::Projection::kPinhole;
  camera.width_px = truth.width;
  camera.height_px = truth.height;
  camera.pinhole = fitted;
  const solvers::camera::PixelRays rays(camera);
  const double pixel_mm = truth.distance_mm / truth.fx;
  double sum = 0.0;
  int count = 0;
  PlaneError error;
  for (int r = step / 2; r < truth.height; r += step)
    for (int c = step / 2; c < truth.width; c += step) {
      Eigen::Vector3d origin, direction;
      truth.Ray(c, r, &origin, &direction);
      const Eigen::Vector3d on_plane = origin - origin.z() / direction.z() * direction;
      const double miss_px = (rays.Point(r, c, 0.0) - on_plane).head<2>().norm() / pixel_mm;
      sum += miss_px * miss_px;
      error.max_px = std::max(error.max_px, miss_px);
      ++count;
    }
  error.rms_px = std::sqrt(sum / count);
  return error;
}

}  // namespace photorig::testing
