#pragma once
// Photometric stereo under near LEDs (Queau, Durix, Wu, Cremers, Lauze,
// Durou, "LED-based photometric stereo: modeling, calibration and numerical
// solution", JMIV 2018). A dome whose LEDs stand a few object sizes away
// lights every surface point from its own directions, with irradiances that
// fall off with distance and with the angle to each LED's axis; taking one
// direction per LED for the whole object tilts the normals by degrees (a
// 34 mm sphere under LEDs 80 mm away: 12.6 deg). The light vectors depend on
// where the point is, which the normals give only once integrated, so normals
// and depth are solved in turn until the normals stop moving.
//
// Geometry: the frame of camera/camera.h (the rig's LED positions, the sample
// plane z = 0), with an orthographic or a pinhole camera: each pixel sees its
// own line, and the point on it follows from the surface's height. The
// integrated normals fix the shape; where it stands along the lines (an
// offset in z for an orthographic camera, a scale about the camera's centre
// for a pinhole one) is chosen where the Lambertian model explains the
// samples best, since both the falloff and the light directions change with
// it.

#include "photorig/solvers/camera/camera.h"
#include "photorig/solvers/camera/near_light.h"
#include "photorig/solvers/core/summary.h"
#include "photorig/solvers/ps/integration.h"
#include "photorig/solvers/ps/photometric_stereo.h"
#include "photorig/solvers/ps/stack.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace photorig::solvers::ps {

struct NearLightOptions {
  // The camera the stack was taken with (its size the stack's); no default:
  // an orthographic one needs its pixel pitch, a pinhole one its intrinsics.
  camera::Camera camera;
  // Rounds of normals then depth. They stop once the mean change of the
  // normals from one round to the next is below normal_change_tolerance_deg:
  // a tenth of the accuracy the solve aims at (half a degree) leaves the
  // rounds' own drift out of the error budget. Three to five rounds reach it
  // on the simulated domes (docs/photometric-stereo.md).
  int max_rounds = 12;
  double normal_change_tolerance_deg = 0.05;
  Integrator integrator = Integrator::kPoisson;
  // The depth's placement is chosen on every offset_stride-th pixel of every
  // offset_stride-th row (rounded up to the rounds' lattice). 0 picks the
  // stride that leaves 16 pixels across the object: a few hundred pixels
  // pin one number, and each step of the search fits them all. On the 80 mm
  // dome's sphere 32, 16 and 11 across give mean errors within 1e-4 deg of
  // each other (tested against every lattice pixel:
  // NearLights.ADepthSearchOnAGridAcrossTheObjectPlacesItAsEveryLatticePixelDoes).
  int offset_stride = 0;
  // The rounds fit and integrate only the lattice of every round_step_px-th
  // pixel of every round_step_px-th row; once they stop, every pixel is
  // fitted once at the surface the last round fitted on, interpolated
  // between the lattice's pixels. 0 picks the longest step that leaves 32
  // pixels across the object (the mask's longer side); 1 fits every pixel
  // in every round. A height error dz turns a light vector by about dz / d
  // (d the LED's distance) and changes its falloff by 2 dz / d, and the
  // interpolated surface is off by about its curvature times the step
  // squared over 8: 8 um on a 34 mm sphere in 1.06 mm steps, which turns
  // the light of LEDs 80 mm away by 0.006 deg, an eighth of
  // normal_change_tolerance_deg. So the normals do not notice (0.1752 deg
  // against 0.1748 with 64 pixels across; tested against every pixel:
  // NearLights.RoundsOnALatticeLeaveTheNormalsAsOnEveryPixel), while the
  // rounds cost a step squared less.
  int round_step_px = 0;
  bool IsValid(std::string* why) const;
};

struct NearLightSummary : SolverSummary {
  int rounds = 0;  // rounds of normals then depth (the last pass over every pixel not counted)
  std::vector<double> normal_change_deg;  // mean change from the previous round, one per round after the first
  // The height chosen for the integrated surface's mean (orthographic), or
  // for its geometric-mean distance from the camera (pinhole).
  double depth_offset_mm = 0.0;
  double depth_ms = 0.0;                  // of solve_ms: integrating the normals and placing the depth
};

// The mean normal error the distant model (one direction per LED, from the
// origin: `directions`) makes on a Lambertian hemisphere of `radius_mm`
// centred on the origin under `lights`: the bias to expect from solving a
// near dome as if it were distant, for an object of that size.
double DistantModelBiasDeg(const std::vector<camera::NearLight>& lights, const std::vector<Eigen::Vector3d>& directions,
                           double radius_mm);

// Photometric stereo with one camera::NearLight per image of `stack`: each round
// fits every pixel's Lambertian model (the thresholds of options.lambertian
// and options.shadow_threshold_read_sigmas), which places the surface; from
// the second round on, the pixels whose Lambertian fit the noise does not
// explain are refitted as the method says: kRobust by options.robust's IRLS,
// kBlinnPhong with a Blinn-Phong lobe (options.blinn_phong's bounds and
// tolerances; the lane fitter whatever its `derivative`), kAuto with the
// lobe kept where the information criterion prefers it; kL2 and kLambertian
// keep the Lambertian fit. Every refit sees the pixel's own light vectors,
// gains and line of sight; `auto` then climbs its steps 5 and 6 (shared and
// GGX lobes) on the final surface's rows. Lights at infinity
// (NearLight::AtInfinity) are taken too: with no LED near, nothing depends
// on the depth and the solve is one pass over the pixels (rounds 1). Fills *result as
// SolvePhotometricStereo does and *height_mm, unless null (CV_32F, NaN off
// the solved pixels), with the surface's z in the frame of the lights.
NearLightSummary SolveNearLightPhotometricStereo(const PhotometricStereoOptions& options,
                                                 const NearLightOptions& near_options,
                                                 const PhotometricStack& stack, const std::vector<camera::NearLight>& lights,
                                                 NormalMap* result, cv::Mat* height_mm);

}  // namespace photorig::solvers::ps
