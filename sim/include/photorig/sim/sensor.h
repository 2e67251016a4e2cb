#pragma once
// A linear image sensor: radiance -> photo-electrons -> digital numbers.
//   electrons = radiance * response_e_per_us * exposure_us       (mean)
//   + photon shot noise (Poisson) + read noise (Gaussian, electrons)
//   clipped at the full-well capacity, then
//   DN = round(electrons / e_per_dn * gain + black_level), clipped to the bit depth.
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

  double max_dn() const { return static_cast<double>((1u << bit_depth) - 1u); }
  // DN produced per unit radiance at this exposure and gain (noise-free mean).
  double DnPerRadiance(double exposure_us, double gain_db) const;
};

std::vector<std::uint16_t> ExposeFrame(const SensorModel& sensor, const cv::Mat& radiance, double exposure_us,
                                       double gain_db, std::uint64_t seed, std::uint64_t frame_index);

}  // namespace photorig::sim
