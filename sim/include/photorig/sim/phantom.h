#pragma once
// Tomography phantoms made of ellipsoids, with their exact line integrals
// (chord length times amplitude, summed), so that simulated projections never
// come from the projector that reconstructs them (the "inverse crime"), and
// the scan of a backlit phantom as a rig captures it: dark, flat and
// projection frames through the sensor model, noise included.

#include "photorig/sim/sensor.h"
#include "photorig/solvers/tomography/geometry.h"
#include "photorig/solvers/tomography/volume_grid.h"

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace photorig::sim {

// One ellipsoid in the phantom's unit cube [-1, 1]^3: amplitude, semi-axes
// (a, b, c), centre, and Euler angles in degrees (z-x-z: phi about z, theta
// about the new x, psi about the new z). c = infinity makes it a cylinder
// along z (a 2D ellipse).
struct Ellipsoid {
  double amplitude, a, b, c, x0, y0, z0, phi_deg, theta_deg, psi_deg;
};

struct Phantom {
  std::vector<Ellipsoid> ellipsoids;
  double half_extent_mm = 16.0;     // the unit cube's half side, in mm
  double sigma_per_mm = 0.1;        // sigma of amplitude 1

  // The 3D Shepp-Logan head phantom with Toft's higher-contrast amplitudes
  // ("modified" Shepp-Logan). Ellipsoid table as in Schabel's phantom3d
  // (MATLAB Central File Exchange 9416), after Kak & Slaney, "Principles of
  // Computerized Tomographic Imaging" (1988), section 3.2, and P. Toft, "The
  // Radon Transform" (1996), pp. 199-200.
  static Phantom SheppLogan3d(double half_extent_mm, double sigma_per_mm);
  // Its 2D form (Toft's modified Shepp-Logan ellipses, the table behind
  // scikit-image's shepp_logan_phantom) extruded along z.
  static Phantom SheppLogan2d(double half_extent_mm, double sigma_per_mm);

  // One point or line: each builds the ellipsoids' frames again (a few
  // trigonometric calls each); PhantomSampler builds them once for many.
  double Sigma(const Eigen::Vector3d& point_mm) const;  // 1/mm
  // The exact integral of sigma along the line (origin, unit direction).
  double LineIntegral(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) const;
  // The phantom averaged over each voxel (supersample^3 points per voxel; a
  // single z sample for a one-slice grid).
  std::vector<float> Rasterise(const solvers::tomography::VolumeGrid& grid, int supersample = 4) const;
};

// A phantom with each ellipsoid's frame (its rotation and axes) computed
// once, for evaluating many points or lines: the same values as Phantom's own
// Sigma and LineIntegral, bit for bit. It copies what it needs; the phantom
// may change or go afterwards.
class PhantomSampler {
 public:
  explicit PhantomSampler(const Phantom& phantom);

  double Sigma(const Eigen::Vector3d& point_mm) const;  // 1/mm
  double LineIntegral(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) const;

 private:
  struct EllipsoidFrame {
    Eigen::Matrix3d to_unit;  // into the ellipsoid's frame, where it is the unit ball
    Eigen::Vector3d centre;   // mm
    double amplitude;
  };
  std::vector<EllipsoidFrame> frames_;
  double sigma_per_mm_;
};

// The line integrals every pixel of the scan sees, laid out as b: exact
// integrals along supersample x supersample rays spread over the pixel,
// averaged, as a pixel integrates the light over its area (1: the pixel's
// centre ray alone).
std::vector<float> ProjectPhantom(const Phantom& phantom, const solvers::tomography::Geometry& geometry, int supersample = 4);

struct TomographyScanOptions {
  SensorModel sensor;                 // its noise is the noise of every frame
  double backlight_radiance = 1.0;
  double exposure_us = 8000.0;        // default sensor: 12000 electrons in the flat, 3/4 of full scale
  double gain_db = 0.0;
  int flats = 8;
  int darks = 8;
  std::uint64_t seed = 1;
  int supersample = 4;  // rays per pixel side (ProjectPhantom)
};

struct TomographyScan {
  std::vector<std::vector<std::uint16_t>> projections, flats, darks;  // raw DN, one frame per view
};

// The scan a camera behind the phantom records against the backlight:
// radiance backlight * exp(-tau) per pixel (tau averaged over the pixel, which
// for pixels small against the sample's detail is the mean of exp(-tau)),
// exposed through the sensor.
TomographyScan ScanPhantom(const Phantom& phantom, const solvers::tomography::Geometry& geometry,
                           const TomographyScanOptions& options);

}  // namespace photorig::sim
