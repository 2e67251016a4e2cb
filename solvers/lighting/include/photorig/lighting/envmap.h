#pragma once
// Environment maps: unwrap an orthographic mirror-ball image to an
// equirectangular (lat-long) map and back, merge exposure brackets into HDR,
// project a map onto spherical harmonics or onto a dome's LEDs.
//
// Lat-long convention: row 0 is straight up (+y); polar angle theta = pi (v + 0.5) / H
// from +y; azimuth phi = 2 pi (u + 0.5) / W - pi, measured from +z (towards the
// camera) to +x: direction = (sin theta sin phi, cos theta, sin theta cos phi).
// The direction straight behind the ball (-z), which a mirror ball cannot see, lies on the seam.

#include "photorig/lighting/sphere.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <vector>

namespace photorig::lighting {

Eigen::Vector3d LatLongDirection(double u, double v, int width, int height);
Eigen::Vector2d LatLongPixel(const Eigen::Vector3d& direction, int width, int height);

struct UnwrapOptions {
  int width = 512;                     // height is width / 2
  double blind_cone_deg = 10.0;        // directions this close to -z are left black and invalid
};
struct LatLongMap {
  cv::Mat radiance;  // CV_32F, channels of the input
  cv::Mat valid;     // CV_8U, 255 where the ball saw the direction
};
// sphere must be orthographic.
LatLongMap MirrorBallToLatLong(const cv::Mat& ball_image, const SphereGeometry& sphere,
                               const UnwrapOptions& options = {});
// An orthographic mirror-ball image (size x size, sphere filling it) of a lat-long map.
cv::Mat LatLongToMirrorBall(const cv::Mat& latlong, int size_px);

struct ExposureMergeOptions {
  double black_level = 0.0;
  double saturation_level = 65535.0;  // values at or above are clipped and get no weight
};
struct HdrMerge {
  cv::Mat radiance;        // CV_32F, (value - black) / exposure_us, weighted over exposures
  cv::Mat unresolved;      // CV_8U, 255 where every exposure was saturated (the shortest one is used)
  int unresolved_pixels = 0;
};
HdrMerge MergeExposures(const std::vector<cv::Mat>& frames, const std::vector<double>& exposure_us,
                        const ExposureMergeOptions& options = {});

// L_lm = integral of L(w) Y_lm(w) dw over a lat-long map: rows x channels.
Eigen::MatrixXd ProjectLatLongToSh(const cv::Mat& latlong, int band);

// Drive weights (LEDs x channels) that make a dome of LEDs approximate the
// map: each direction of the upper hemisphere (z > 0) goes to its nearest LED,
// weighted by solid angle and divided by the LED's intensity.
Eigen::MatrixXd LatLongToLedWeights(const cv::Mat& latlong, const std::vector<Eigen::Vector3d>& led_directions,
                                    const std::vector<double>& led_intensities);

}  // namespace photorig::lighting
