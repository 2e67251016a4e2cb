#pragma once
// Environment maps: unwrap an orthographic mirror-ball image to an
// equirectangular (lat-long) map and back, merge exposure brackets into HDR,
// project a map onto spherical harmonics or onto a dome's LEDs.
//
// Lat-long convention: row 0 is straight up (+y); polar angle theta = pi (v + 0.5) / H
// from +y; azimuth phi = 2 pi (u + 0.5) / W - pi, measured from +z (towards the
// camera) to +x: direction = (sin theta sin phi, cos theta, sin theta cos phi).
// The direction straight behind the ball (-z), which a mirror ball cannot see, lies on the seam.

#include "photorig/solvers/camera/near_light.h"
#include "photorig/solvers/lighting/sphere.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace photorig::solvers::lighting {

Eigen::Vector3d LatLongDirection(double u, double v, int width, int height);
Eigen::Vector2d LatLongPixel(const Eigen::Vector3d& direction, int width, int height);

// Each operation below returns a solvers::core::Summary; on kInvalidOptions or
// kInvalidInput (with the reason) its output is left untouched. Nothing throws.

struct UnwrapOptions {
  int width = 512;                     // height is width / 2
  double blind_cone_deg = 10.0;        // directions this close to -z are left black and invalid
  bool IsValid(std::string* why) const;  // width even and >= 4, blind cone in [0, 90)
};
struct LatLongMap {
  cv::Mat radiance;  // CV_32F, channels of the input
  cv::Mat valid;     // CV_8U, 255 where the ball saw the direction
};
// sphere must be located and orthographic.
solvers::core::Summary MirrorBallToLatLong(const cv::Mat& ball_image, const SphereGeometry& sphere,
                                     const UnwrapOptions& options, LatLongMap* map);
// An orthographic mirror-ball image (size x size, sphere filling it) of a 2:1 lat-long map.
solvers::core::Summary LatLongToMirrorBall(const cv::Mat& latlong, int size_px, cv::Mat* ball);

struct ExposureMergeOptions {
  double black_level = 0.0;
  double saturation_level = 65535.0;  // values at or above are clipped and get no weight
  bool IsValid(std::string* why) const;  // saturation_level above black_level
};
struct HdrMerge {
  cv::Mat radiance;        // CV_32F, (value - black) / exposure_us, weighted over exposures
  cv::Mat unresolved;      // CV_8U, 255 where every exposure was saturated (the shortest one is used)
  int unresolved_pixels = 0;
};
// Frames of one size and type, one positive exposure each. Pixels saturated in
// every exposure are flagged in `unresolved` and named in the summary's message.
solvers::core::Summary MergeExposures(const std::vector<cv::Mat>& frames, const std::vector<double>& exposure_us,
                                const ExposureMergeOptions& options, HdrMerge* merge);

// L_lm = integral of L(w) Y_lm(w) dw over a 2:1 lat-long map: rows x channels; band in [0, 8].
solvers::core::Summary ProjectLatLongToSh(const cv::Mat& latlong, int band, Eigen::MatrixXd* coefficients);

// Drive weights (LEDs x channels) that make a dome of LEDs approximate the
// map: each direction of the upper hemisphere (z > 0) goes to its nearest LED,
// weighted by solid angle and divided by the LED's intensity (positive, one per direction).
solvers::core::Summary LatLongToLedWeights(const cv::Mat& latlong, const std::vector<Eigen::Vector3d>& led_directions,
                                     const std::vector<double>& led_intensities, Eigen::MatrixXd* weights);

// The same relighting from a dome of near LEDs (camera/near_light.h). Each
// surface point x sees LED k along its own direction l_k(x) and with its own
// irradiance E_k(x) = led_scales[k] * RelativeIrradiance_k(x), so the
// weights differ from pixel to pixel: each direction of the upper hemisphere
// goes to the LED nearest it as seen from x (of those that reach x),
// weighted by its solid angle and divided by E_k(x), and the image is
// sum_k w_k(x) frames[k](x). With one direction and intensity per LED
// (LatLongToLedWeights) an 80 mm dome leaves the relit object's shading
// tens of percent off across it: the falloff and the directions of its frames.
struct NearRelightOptions {
  // The weights are worked out at every grid_px-th pixel of every
  // grid_px-th row (and the last row and column) and bilinear between: they
  // follow l_k(x) and E_k(x), which change over millimetres, not pixels.
  int grid_px = 16;
  // The map is area-averaged to this width (2:1) first: the weights sum it
  // over each LED's cell, tens of degrees wide, which 2.8-degree texels resolve.
  int map_width_px = 128;
  bool IsValid(std::string* why) const;  // both at least 2 (the width even)
};
// frames: one single-channel image per LED, one size; points_mm: CV_32FC3 of
// that size, each pixel's surface point in the dome's frame (mm), finite;
// the map of 1 or 3 channels (as LatLongToLedWeights').
// *image: CV_32F with the map's channels (3: stored BGR).
solvers::core::Summary RelightNearFromEnvironment(const NearRelightOptions& options, const cv::Mat& latlong,
                                                  const std::vector<camera::NearLight>& leds,
                                                  const std::vector<double>& led_scales,
                                                  const std::vector<cv::Mat>& frames, const cv::Mat& points_mm,
                                                  cv::Mat* image);

}  // namespace photorig::solvers::lighting
