#pragma once
// A near dome's LEDs photographed on chrome balls, for the LED-position
// tests and their chart: a 384 x 384 camera over a 50 cm dome, as
// config/rigs/sim-dome-near.yaml (orthographic at 0.35 mm per pixel, or a
// pinhole 250 mm above the plane seeing the same 0.35 mm per pixel there),
// frames rendered by the tests' own ray tracer (synthetic_sphere.h).

#include "photorig/solvers/camera/camera.h"
#include "photorig/solvers/lighting/led_positions.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <vector>

namespace photorig::solvers::lighting::testing {

inline constexpr int kDomeFrameSize = 384;

camera::Camera DomeCamera(bool pinhole);

// Three balls of `radius_mm` in a triangle, so every LED sees two baselines.
MirrorSphereLayout ThreeBalls(double radius_mm = 17.0);

// Every fourth LED of a dome of rings on a 250 mm hemisphere.
std::vector<Eigen::Vector3d> LedPositionsMm();

// One frame per LED showing every ball; read noise `noise_sigma` DN on a
// highlight of 3000 DN.
std::vector<cv::Mat> RenderLedFrames(bool pinhole, const MirrorSphereLayout& balls,
                                     const std::vector<Eigen::Vector3d>& leds, double noise_sigma = 2.0);

// Over the LEDs the summary calls usable (the others have no position); NaN
// figures when none is.
struct PositionErrors {
  double mean_mm = 0.0, max_mm = 0.0;
  int beyond_two_sigma = 0;  // usable LEDs further from the truth than twice their predicted sigma
};
PositionErrors ErrorsAgainst(const LedPositionSummary& summary, const std::vector<Eigen::Vector3d>& truth);

}  // namespace photorig::solvers::lighting::testing
