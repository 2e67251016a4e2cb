#pragma once
// An LED a few object sizes away, in the dome's frame (camera.h): every
// surface point sees it along its own direction and with its own
// irradiance, which falls with the square of the distance and with the
// angle to the LED's axis (cos^mu, the emitter's radiance profile). Shared
// by every solver that models a near dome: photometric stereo, the
// reflectance fits, the LED calibrations.

#include <Eigen/Core>

#include <cmath>
#include <vector>

namespace photorig::solvers::camera {

struct NearLight {
  Eigen::Vector3d position_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis{0.0, 0.0, -1.0};  // unit: the direction the LED emits along
  double cos_exponent = 1.0;             // mu in cos^mu(angle to the axis); 1: a Lambertian emitter
  // A light at infinity: position_mm is the unit direction towards it, and
  // every point sees it along that direction with the origin's irradiance
  // (RelativeIrradiance 1). Photometric stereo takes such lights to fit a
  // distant dome through a pinhole camera's lines of sight.
  bool at_infinity = false;

  // A distant light along `direction` (towards the light), so that solvers
  // built for near LEDs also take a distant dome, or a mix of both.
  static NearLight AtInfinity(const Eigen::Vector3d& direction);

  // The irradiance at `point_mm` at normal incidence relative to the one at
  // the origin (a dome's intensity calibration measures the latter), and the
  // unit vector towards the LED. 0 behind the LED.
  double RelativeIrradiance(const Eigen::Vector3d& point_mm, Eigen::Vector3d* towards_light) const;
};

// A NearLight with its per-light constants worked out once, for fits that
// evaluate it at every sample of every pixel.
struct PreparedNearLight {
  Eigen::Vector3d position_mm, axis;
  double cos_exponent = 1.0;
  double scale = 1.0;  // |p|^2 / cos^mu(origin): the relative irradiance's constant
  // The homogeneous coordinate of the position: 1 for an LED, 0 for a light
  // at infinity, whose vector towards it is its position for every point.
  double w = 1.0;

  explicit PreparedNearLight(const NearLight& light);
  // NearLight::RelativeIrradiance, without its constants' cost.
  double RelativeIrradiance(const Eigen::Vector3d& point_mm, Eigen::Vector3d* towards_light) const {
    const Eigen::Vector3d to = position_mm - w * point_mm;
    const double distance_squared = to.squaredNorm();
    *towards_light = to / std::sqrt(distance_squared);
    const double cos_axis = -axis.dot(*towards_light);
    if (cos_axis <= 0.0) return 0.0;
    const double profile = cos_exponent == 1.0 ? cos_axis : std::pow(cos_axis, cos_exponent);
    return scale * profile / distance_squared;
  }
};

}  // namespace photorig::solvers::camera
