#pragma once
// Rusinkiewicz's half/difference coordinates of an isotropic BRDF.
// Directions are unit vectors in the sample frame (normal = z), pointing away
// from the surface: w_i towards the light, w_o towards the camera.
//   h = normalize(w_i + w_o) at (theta_h, phi_h);
//   d = w_i rotated by -phi_h about z, then by -theta_h about y, at (theta_d, phi_d).
// An isotropic BRDF does not depend on phi_h. This is the convention of MERL's
// own code, so a direction pair lands in the same table bin as it does there.

#include <Eigen/Core>

namespace photorig::solvers::brdf {

struct HalfDiff {
  double theta_h = 0.0;  // radians, [0, pi]
  double theta_d = 0.0;  // radians, [0, pi]
  double phi_d = 0.0;    // radians, (-pi, pi]
};

struct DirectionPair {
  Eigen::Vector3d wi;  // towards the light
  Eigen::Vector3d wo;  // towards the camera
};

// (w_i, w_o) -> half/difference angles. w_i + w_o must not vanish.
HalfDiff ToHalfDiff(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo);

// Half/difference angles (and the half vector's azimuth, free for an
// isotropic BRDF) -> (w_i, w_o). The inverse of ToHalfDiff.
DirectionPair FromHalfDiff(const HalfDiff& angles, double phi_h = 0.0);

// Rodrigues' rotation of v by `angle` radians about the unit `axis`.
Eigen::Vector3d RotateAbout(const Eigen::Vector3d& v, const Eigen::Vector3d& axis, double angle);

}  // namespace photorig::solvers::brdf
