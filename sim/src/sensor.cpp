#include "photorig/sim/sensor.h"

#include <algorithm>
#include <cmath>

namespace photorig::sim {
namespace {

// SplitMix64: a fast, well-mixed hash; used as a counter-based generator.
std::uint64_t Mix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

double Uniform(std::uint64_t key) { return (static_cast<double>(Mix(key) >> 11) + 0.5) * 0x1.0p-53; }

// Standard normal by Box-Muller from two independent uniforms.
double Normal(std::uint64_t key) {
  const double u1 = Uniform(key), u2 = Uniform(key ^ 0x5851f42d4c957f2dull);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

// Poisson variate: exact (Knuth) for small means, where the skew matters;
// Gaussian with matched mean and variance above, where it does not.
double Poisson(double mean, std::uint64_t key) {
  if (mean <= 0.0) return 0.0;
  if (mean > 30.0) return std::max(0.0, mean + std::sqrt(mean) * Normal(key));
  const double limit = std::exp(-mean);
  double product = Uniform(key);
  int count = 0;
  while (product > limit) {
    ++count;
    product *= Uniform(key + 0x632be59bd9b4e019ull * static_cast<std::uint64_t>(count));
  }
  return count;
}

}  // namespace

double SensorModel::DnPerRadiance(double exposure_us, double gain_db) const {
  return response_e_per_us * exposure_us / e_per_dn * std::pow(10.0, gain_db / 20.0);
}

double ApplyResponse(const SensorModel& sensor, double signal_dn) {
  if (sensor.IsLinear()) return sensor.black_level_dn + signal_dn;
  const double full_scale = sensor.max_dn() - sensor.black_level_dn;
  const double x = signal_dn / full_scale;
  // Odd about black, so read noise below black stays symmetric about it.
  return sensor.black_level_dn + full_scale * std::copysign(std::pow(std::abs(x), 1.0 / sensor.response_gamma), x);
}

std::vector<std::uint16_t> ExposeFrame(const SensorModel& sensor, const cv::Mat& radiance, double exposure_us,
                                       double gain_db, std::uint64_t seed, std::uint64_t frame_index) {
  const int rows = radiance.rows, cols = radiance.cols;
  std::vector<std::uint16_t> pixels(static_cast<std::size_t>(rows) * cols);
  const double gain = std::pow(10.0, gain_db / 20.0);
  const double max_dn = sensor.max_dn();
  const std::uint64_t frame_key = Mix(seed ^ Mix(frame_index));
#pragma omp parallel for schedule(static)
  for (int r = 0; r < rows; ++r) {
    const float* in = radiance.ptr<float>(r);
    for (int c = 0; c < cols; ++c) {
      const std::uint64_t key = Mix(frame_key + static_cast<std::uint64_t>(r) * cols + c) * 4;
      const double mean_e = std::max(0.0, double(in[c]) * sensor.response_e_per_us * exposure_us);
      double electrons = sensor.shot_noise ? Poisson(mean_e, key) : mean_e;
      electrons = std::min(electrons, sensor.full_well_e);
      electrons += sensor.read_noise_e * Normal(key + 1);
      const double dn = std::round(ApplyResponse(sensor, electrons / sensor.e_per_dn * gain));
      pixels[static_cast<std::size_t>(r) * cols + c] = static_cast<std::uint16_t>(std::clamp(dn, 0.0, max_dn));
    }
  }
  return pixels;
}

}  // namespace photorig::sim
