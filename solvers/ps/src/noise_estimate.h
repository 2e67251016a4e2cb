#pragma once
// The noise model of a stack whose noise is not (fully) given: read noise and
// shot-noise gain fitted to the Lambertian residuals of a sample of pixels.

#include "photorig/solvers/ps/lambertian.h"
#include "photorig/solvers/ps/photometric_stereo.h"
#include "photorig/solvers/ps/stack.h"

namespace photorig::solvers::ps::internal {

// Noise of the data when the stack does not (fully) say: a photon-transfer fit
// var(I - D) = read^2 + gain * (I - D) to the Lambertian residual variance of a
// sparse set of pixels. Each pixel's variance v_p is a chi-square estimate, so
// the gain is taken as the lower decile of (v_p - read^2) / signal_p, and
// read^2 as the value at which the lower decile of v_p / (read^2 + gain
// signal_p) over the darkest tenth of the pixels is the chi-square lower
// decile (both corrected by that decile): pixels no
// Lambertian model explains (highlights) cannot inflate them as long as fewer
// than nine tenths of the pixels are such. (Under a dome most pixels of a
// glossy object see a highlight; a lower quartile breaks down there.) A read
// noise (from dark frames) or gain (from the camera) the stack already knows
// is kept fixed.
NoiseModel EstimateNoise(const PhotometricStack& stack, const LambertianOptions& thresholds);

// The noise model and shadow threshold a solve works with.
struct SolveNoise {
  NoiseModel model;
  bool estimated = false;  // (partly) by EstimateNoise
  double shadow_threshold = 0.0;  // input units; may fail LambertianOptions::IsValid
};
// What the stack gives, completed by EstimateNoise where options.estimate_noise
// allows and the solve needs it: the shot-noise gain for the adequacy tests of
// the methods that refine the Lambertian pass (refine), the read noise for a
// shadow threshold in read-noise sigmas (every method but `l2`).
// lambertian: the solve's Lambertian options, at the absolute threshold.
SolveNoise NoiseForSolve(const PhotometricStereoOptions& options, bool refine, const PhotometricStack& stack,
                         const LambertianOptions& lambertian);

}  // namespace photorig::solvers::ps::internal
