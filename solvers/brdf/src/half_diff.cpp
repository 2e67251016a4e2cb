#include "photorig/solvers/brdf/half_diff.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace photorig::solvers::brdf {

using Eigen::Vector3d;

Vector3d RotateAbout(const Vector3d& v, const Vector3d& axis, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  return v * c + axis * axis.dot(v) * (1.0 - c) + axis.cross(v) * s;
}

HalfDiff ToHalfDiff(const Vector3d& wi, const Vector3d& wo) {
  const Vector3d h = (wi + wo).normalized();
  HalfDiff out;
  out.theta_h = std::acos(std::clamp(h.z(), -1.0, 1.0));
  const double phi_h = std::atan2(h.y(), h.x());
  const Vector3d d = RotateAbout(RotateAbout(wi, Vector3d::UnitZ(), -phi_h), Vector3d::UnitY(), -out.theta_h);
  out.theta_d = std::acos(std::clamp(d.z(), -1.0, 1.0));
  out.phi_d = std::atan2(d.y(), d.x());
  return out;
}

DirectionPair FromHalfDiff(const HalfDiff& a, double phi_h) {
  const Vector3d d(std::sin(a.theta_d) * std::cos(a.phi_d), std::sin(a.theta_d) * std::sin(a.phi_d),
                   std::cos(a.theta_d));
  const Vector3d h(std::sin(a.theta_h) * std::cos(phi_h), std::sin(a.theta_h) * std::sin(phi_h), std::cos(a.theta_h));
  const Vector3d wi = RotateAbout(RotateAbout(d, Vector3d::UnitY(), a.theta_h), Vector3d::UnitZ(), phi_h);
  // w_o is w_i reflected about h.
  return {wi, (2.0 * h.dot(wi) * h - wi).normalized()};
}

}  // namespace photorig::solvers::brdf
