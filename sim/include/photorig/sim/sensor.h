#pragma once
// An image sensor: radiance -> photo-electrons -> digital numbers.
//   electrons = radiance * response_e_per_us * exposure_us       (mean)
//   + photon shot noise (Poisson) + read noise (Gaussian, electrons)
//   clipped at the full-well capacity, then
//   S  = electrons / e_per_dn * gain                              (linear signal, DN)
//   DN = round(black_level + F * R(S / F)), clipped to the bit depth,
// with F = max_dn - black_level the full scale above black and R the response
// curve: R(x) = sign(x) |x|^(1 / response_gamma), the identity for a linear
// camera (response_gamma 1). The curve acts on the analog signal, noise
// included, before quantisation, as a camera's non-linear readout or an
// encoding gamma does; it fixes black and full scale, so a gamma above 1
// lifts mid-tones (1.1: +3.2 % of full scale at half scale).
// Noise is drawn from a counter-based generator keyed on (seed, frame, pixel),
// so a frame is identical whatever the thread count or the order of rendering.

#include <opencv2/core.hpp>

#include <cstdint>
#include <vector>

namespace photorig::sim {

struct SensorModel {
  int bit_depth = 12;
  double response_e_per_us = 1.5;  // electrons per microsecond per unit radiance
  double e_per_dn = 4.0;           // conversion gain at 0 dB
  double black_level_dn = 64.0;
  double read_noise_e = 6.0;       // RMS
  double full_well_e = 15000.0;
  bool shot_noise = true;
  double response_gamma = 1.0;     // 1: linear; see R(x) above

  bool IsLinear() const { return response_gamma == 1.0; }

  double max_dn() const { return static_cast<double>((1u << bit_depth) - 1u); }
  // DN produced per unit radiance at this exposure and gain (noise-free mean
  // of the linear signal S; the response curve is what a calibration that
  // assumes linearity misses).
  double DnPerRadiance(double exposure_us, double gain_db) const;
};

// Black level plus the response curve applied to a linear signal S in DN above black.
double ApplyResponse(const SensorModel& sensor, double signal_dn);

std::vector<std::uint16_t> ExposeFrame(const SensorModel& sensor, const cv::Mat& radiance, double exposure_us,
                                       double gain_db, std::uint64_t seed, std::uint64_t frame_index);

}  // namespace photorig::sim
