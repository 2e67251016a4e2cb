#pragma once
// Where every ray of a scan runs, in the frame of the sample (the volume grid's
// frame, millimetres). The sample turns about the z axis; at view angle theta
// the beam travels along d = (cos theta, sin theta, 0) and the detector's
// columns run along u = (-sin theta, cos theta, 0), its rows downwards along -z
// (image rows grow downwards, as on every camera of the rig).
//
// Detector coordinates of the centre of pixel (col, row), in detector mm:
//   u = (col + 0.5 - cols/2) pixel_mm - cor_offset_mm,   v = (rows/2 - row - 0.5) pixel_mm
// cor_offset_mm is where the rotation axis falls on the detector, measured
// from its centre along +u: a rig whose axis is off the centre column by
// 0.3 mm has cor_offset_mm = 0.3, and ignoring it smears every edge into an arc.
//
//   parallel: the ray through (u, v) runs along d through the point u*u_hat + v*z_hat
//             (an orthographic camera, or a telecentric lens);
//   cone:     the ray runs from the source at -source_to_axis_mm * d to the detector
//             point axis_to_detector_mm * d + u*u_hat + v*z_hat (a pinhole camera whose
//             centre is the source; a backlight fills the field).

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace photorig::solvers::tomography {

enum class Beam { kParallel, kCone };

struct Geometry {
  Beam beam = Beam::kParallel;
  int detector_cols = 64;
  int detector_rows = 64;
  double pixel_mm = 0.5;           // detector pitch; cone: on the detector plane
  std::vector<double> angles_rad;  // the sample's rotation at each view (no default: the scan says)
  double cor_offset_mm = 0.0;      // the rotation axis on the detector, from its centre along +u
  double source_to_axis_mm = 500.0;    // cone only
  double axis_to_detector_mm = 100.0;  // cone only

  bool IsValid(std::string* why) const;
  int views() const { return static_cast<int>(angles_rad.size()); }
  std::int64_t pixels_per_view() const { return static_cast<std::int64_t>(detector_cols) * detector_rows; }
  std::int64_t rays() const { return views() * pixels_per_view(); }
  // b and every per-ray array are laid out view by view, each view row by row.
  std::int64_t RayIndex(int view, int row, int col) const {
    return (static_cast<std::int64_t>(view) * detector_rows + row) * detector_cols + col;
  }
  // The ray through the centre of pixel (col, row) of view `view`: a point on
  // it and its unit direction.
  void Ray(int view, int row, int col, Eigen::Vector3d* origin, Eigen::Vector3d* direction) const;
};

// `views` angles evenly over `span_deg` starting at 0; with include_end the
// last view sits at span_deg (a 0..180 scan that keeps the view opposite the
// first, which the centre-of-rotation estimate pairs with it).
std::vector<double> EvenAngles(int views, double span_deg, bool include_end = false);

}  // namespace photorig::solvers::tomography
