#pragma once
// Environment maps: unwrap an orthographic mirror-ball image to an
// equirectangular (lat-long) map and back, merge exposure brackets into HDR,
// project a map onto spherical harmonics or onto a dome's LEDs.
//
// Lat-long convention: row 0 is straight up (+y); polar angle theta = pi (v + 0.5) / H
// from +y; azimuth phi = 2 pi (u + 0.5) / W - pi, measured from +z (towards the
// camera) to +x: direction = (sin theta sin phi, cos theta, sin theta cos phi).
// The direction straight behind the ball (-z), which a mirror ball cannot see, lies on the seam.

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

}  // namespace photorig::solvers::lighting
