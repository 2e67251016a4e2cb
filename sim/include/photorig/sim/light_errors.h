#pragma once
// A dome as built, not as drawn: the true LED directions and irradiances the
// simulated lights render with differ from the rig's stated (calibrated)
// ones, by seeded random errors of a given RMS. The solvers keep the stated
// figures, so what a real capture suffers from an imperfect calibration shows
// in the simulated one too.

#include "photorig/sim/renderer.h"

#include <cstdint>
#include <vector>

namespace photorig::sim {

struct LightCalibrationError {
  // Each light turned about the object origin by a Gaussian offset in the
  // tangent plane of its direction, of this RMS angle (two components of
  // RMS direction_rms_deg / sqrt(2) each). Near LEDs swing with it, still aimed
  // at the origin.
  double direction_rms_deg = 0.0;
  // Each light's irradiance multiplied by 1 + this / 100 * N(0, 1): the RMS
  // relative error of the stated intensities, in percent. A draw that would
  // leave less than 1 % of the stated irradiance is clamped there (at the
  // largest error rig files accept, 30 %, a draw 3.3 sigma low).
  double intensity_rms_pct = 0.0;
};

// Deterministic in the seed; the direction errors do not depend on the
// intensity error (and vice versa), so adding one keeps the other's draws.
void PerturbLights(const LightCalibrationError& error, std::uint64_t seed, std::vector<Light>* lights);

}  // namespace photorig::sim
