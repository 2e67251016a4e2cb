#pragma once
// Direct lighting of the sampled surface, per pixel:
//   L(p) = sum_k level_k * f_r(w_i, w_o) * E_k(p) * max(0, n . w_i) * V_k(p)
// with w_o the pixel's view direction (SurfaceMaps::view) and V_k = 0 where
// the heightfield blocks light k (cast shadow). Delta BRDFs (mirror) instead
// reflect the radiance of the source seen along the mirror direction:
//   L(p) = level_k * R * E_k(p) / (pi sin^2 alpha_k)  if the mirror direction falls inside the source's disc
// where alpha_k is the angular radius of light k seen from p. A near LED's
// highlight is a pixel or less across: it is weighted by the fraction of the
// pixel whose mirror direction falls inside the disc, as a camera integrates it.
// Radiance, irradiance: arbitrary but consistent units (the sensor's
// response_e_per_us converts radiance to electrons).

#include "photorig/sim/brdf.h"
#include "photorig/sim/scene.h"

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace photorig::sim {

// A distant light (default), or a near LED when position_mm is set.
struct Light {
  Light() = default;
  // A distant light.
  Light(const Eigen::Vector3d& towards_light, double irradiance_at_object)
      : direction(towards_light), irradiance(irradiance_at_object) {}

  Eigen::Vector3d direction{0.0, 0.0, 1.0};  // distant: unit, towards the light
  // Irradiance at normal incidence at the object origin for drive level 1
  // (the figure a dome calibration measures, near or distant alike).
  double irradiance = 1.0;
  double angular_radius_rad = 0.01;  // distant: apparent radius of the source (mirror highlights)
  // Near LED: irradiance falls off as cos^m(angle to axis) / distance^2.
  std::optional<Eigen::Vector3d> position_mm;
  Eigen::Vector3d axis{0.0, 0.0, -1.0};  // unit, the LED's emission axis
  double cos_exponent = 1.0;             // m: 1 is a Lambertian emitter
  double emitter_radius_mm = 1.5;        // physical radius (mirror highlights)

  // Unit direction towards the light from `point`, and the irradiance there at
  // normal incidence (0 behind a near LED).
  double IrradianceAt(const Eigen::Vector3d& point_mm, Eigen::Vector3d* towards_light) const;
  // Angular radius of the source seen from `point`.
  double AngularRadiusAt(const Eigen::Vector3d& point_mm) const;
};

// `levels[k]` scales light k (0 = off). Threads over rows; the result does not
// depend on the thread count.
cv::Mat RenderRadiance(const SurfaceMaps& surface, const Brdf& brdf, bool cast_shadows,
                       const std::vector<Light>& lights, const std::vector<double>& levels);
// The Lambertian case, with the albedo map as rho_d.
cv::Mat RenderRadiance(const SurfaceMaps& surface, bool cast_shadows, const std::vector<Light>& lights,
                       const std::vector<double>& levels);

// 1 where the heightfield (surface.height on the orthographic pixel grid)
// blocks a distant light towards `direction`. Horizon sweep: lines parallel to
// the light's azimuth are walked away from the light keeping the highest
// shadow-casting height, so the cost is O(pixels) whatever the elevation.
cv::Mat CastShadowMask(const SurfaceMaps& surface, const Eigen::Vector3d& direction);
// Any light: the sweep for a distant one, a march from each pixel towards the
// LED for a near one (its direction changes across the frame).
cv::Mat CastShadowMask(const SurfaceMaps& surface, const Light& light);

// One bounce of inter-reflection on a heightfield seen orthographically: the
// radiance each pixel receives from the rest of the surface, reflected towards
// the camera. Per pixel, `samples` cosine-weighted directions (stratified,
// seeded per pixel, so the result is deterministic whatever the thread count)
// are marched over the bilinear heightfield; a hit at q brings the radiance q
// sends to the camera, `direct(q)`, which is the radiance it sends towards p
// when q is diffuse (for glossy surfaces this is the approximation). The
// estimator is pi * f_r(n, w_i, w_o) * L(q) averaged over the samples. Zero on
// convex surfaces, where no ray meets the surface again; delta BRDFs (mirror)
// are left out. Cost: samples x march length per pixel.
cv::Mat RenderOneBounce(const SurfaceMaps& surface, const Brdf& brdf, const cv::Mat& direct, int samples,
                        std::uint64_t seed);

// Light that reaches the object other than straight from the LEDs, spread
// evenly over the sky above it: radiance L_a from every direction with w.z > 0
// (the dome's interior and opening), none from below (a dark stage). Its
// level is given as E_a = pi L_a, the irradiance it brings to an upward-facing
// surface.
struct AmbientLight {
  // Light the dome's interior sends back: each LED at drive level l and
  // irradiance E adds dome_fraction * l * E to E_a. It is what a white
  // target facing up reads with the LED's direct light blocked, relative to
  // what it reads from the LED alone (a few per cent for a matt black dome).
  double dome_fraction = 0.0;
  // Light from outside the dome (room light), on whatever the LEDs do, so
  // also in dark frames: E_a grows by stray_irradiance.
  double stray_irradiance = 0.0;
  int samples = 256;  // directions per pixel for RenderSkyResponse

  bool IsOn() const { return dome_fraction > 0.0 || stray_irradiance > 0.0; }
  bool IsValid(std::string* why) const;
};

// Per pixel, the radiance reflected towards the camera under the sky of
// AmbientLight for E_a = 1:
//   A(p) = integral over w.z > 0 of f_r(n, w, w_o) (1 / pi) max(0, n.w) dw,
// estimated from `samples` stratified cosine-weighted directions about n (the
// estimator is the mean of f_r [w.z > 0]), seeded per pixel. A Lambertian
// pixel gets rho / pi (1 + n_z) / 2; a mirror rho_s / pi where its mirror
// direction points into the sky. The object's own occlusion of the sky is
// ignored: exact for convex objects, an overestimate in concavities.
cv::Mat RenderSkyResponse(const SurfaceMaps& surface, const Brdf& brdf, int samples, std::uint64_t seed);

// Transmission through an absorbing medium: L = L_backlight * exp(-tau).
cv::Mat RenderTransmission(const cv::Mat& line_integrals, double backlight_radiance);

}  // namespace photorig::sim
