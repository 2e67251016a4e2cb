#pragma once
// From raw backlit frames to the right-hand side of W sigma = b:
//   b = -log((L - D) / (F - D))
// per pixel, with D the mean dark frame and F the mean flat frame (backlight,
// no sample). A ratio that is not positive (the sample blocks everything, or
// noise drove L below the dark), a pixel saturated in the frame or in the
// flat, or a flat with no signal above the dark is flagged and left out of the
// system (valid = 0): it is never clipped to a made-up value.
//
// With two or more flats and two or more darks the noise of every b is
// estimated from the frames themselves: the darks' temporal variance gives the
// read noise, the flats' variance above it the gain (DN per DN of signal,
// shot noise), and propagating both through the logarithm gives
//   var(b) = var(L) / (L - D)^2 + var(F) / (n_flats (F - D)^2).
// That is what the discrepancy principle stops on.

#include "photorig/solvers/core/summary.h"
#include "photorig/solvers/tomography/geometry.h"

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace photorig::solvers::tomography {

// The measurements a reconstruction fits: one entry per ray (Geometry::RayIndex).
struct Absorbance {
  Eigen::VectorXf b;                 // line integrals of sigma (dimensionless)
  std::vector<std::uint8_t> valid;   // 1: in the system; 0: flagged. Empty: every ray valid
  Eigen::VectorXf variance;          // var(b) per ray; empty: unknown (give ReconstructOptions::noise_sigma)
};

struct AbsorbanceOptions {
  // A raw value at or above this is saturated (0: no saturation check).
  // Default 4095, the top of a 12-bit camera.
  double saturation_dn = 4095.0;
  // Flats must rise this far above the darks to carry a signal (DN). Default 4.
  double min_flat_signal_dn = 4.0;

  bool IsValid(std::string* why) const;
};

struct AbsorbanceSummary : solvers::core::Summary {
  std::int64_t rays = 0;
  std::int64_t flagged_non_positive = 0;  // L - D <= 0
  std::int64_t flagged_saturated = 0;     // frame or flat at saturation_dn
  std::int64_t flagged_no_flat = 0;       // F - D below min_flat_signal_dn
  bool noise_estimated = false;           // variance filled from the flats and darks
  double read_variance_dn2 = 0.0;         // from the darks
  double gain_dn_per_dn = 0.0;            // from the flats: var = read + gain * signal
  double mean_b_sigma = 0.0;              // RMS of sqrt(var(b)) over the valid rays
  std::int64_t flagged() const { return flagged_non_positive + flagged_saturated + flagged_no_flat; }
};

// `projections`: one raw frame per view (detector_rows x detector_cols,
// row-major); `flats`, `darks`: at least one each, same size. Ends
// kInvalidInput on mismatched sizes and kFailure when no ray is usable.
AbsorbanceSummary ComputeAbsorbance(const Geometry& geometry, const std::vector<std::vector<std::uint16_t>>& projections,
                                    const std::vector<std::vector<std::uint16_t>>& flats,
                                    const std::vector<std::vector<std::uint16_t>>& darks,
                                    const AbsorbanceOptions& options, Absorbance* absorbance);

}  // namespace photorig::solvers::tomography
