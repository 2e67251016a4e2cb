#include "photorig/sim/sensor.h"

#include <gtest/gtest.h>

#include <cmath>

namespace photorig::sim {
namespace {

struct Moments {
  double mean = 0, variance = 0;
};

Moments MeasureMoments(const std::vector<std::uint16_t>& pixels) {
  Moments m;
  for (auto p : pixels) m.mean += p;
  m.mean /= pixels.size();
  for (auto p : pixels) m.variance += (p - m.mean) * (p - m.mean);
  m.variance /= pixels.size() - 1;
  return m;
}

// Photon transfer: variance in DN^2 = mean_e / g^2 + read^2 / g^2 + 1/12 (quantisation).
TEST(ExposeFrame, MeanAndVarianceFollowThePhotonTransferCurve) {
  SensorModel sensor;
  sensor.bit_depth = 16;
  sensor.e_per_dn = 2.0;
  sensor.read_noise_e = 5.0;
  sensor.black_level_dn = 100;
  sensor.full_well_e = 1e9;
  for (double mean_e : {10.0, 200.0, 5000.0}) {
    const double exposure_us = 1000.0;
    const cv::Mat radiance(256, 256, CV_32F, cv::Scalar(mean_e / (sensor.response_e_per_us * exposure_us)));
    const Moments m = MeasureMoments(ExposeFrame(sensor, radiance, exposure_us, 0.0, 11, 0));
    const double expected_mean = 100 + mean_e / 2.0;
    const double expected_variance = mean_e / 4.0 + 25.0 / 4.0 + 1.0 / 12.0;
    // 65536 samples: the sample variance is within a few percent of the truth.
    EXPECT_NEAR(m.mean, expected_mean, 0.02 * std::sqrt(expected_variance) + 0.05) << mean_e;
    EXPECT_NEAR(m.variance / expected_variance, 1.0, 0.04) << mean_e;
  }
}

TEST(ExposeFrame, ClipsAtFullWellAndBitDepth) {
  SensorModel sensor;
  sensor.bit_depth = 12;
  sensor.full_well_e = 1000;
  sensor.e_per_dn = 1.0;
  sensor.read_noise_e = 0;
  sensor.shot_noise = false;
  const cv::Mat bright(4, 4, CV_32F, cv::Scalar(1e6));
  for (auto p : ExposeFrame(sensor, bright, 1000.0, 0.0, 1, 0)) EXPECT_EQ(p, 1000 + 64);
  sensor.full_well_e = 1e9;
  for (auto p : ExposeFrame(sensor, bright, 1000.0, 0.0, 1, 0)) EXPECT_EQ(p, 4095);
}

// DN = black + F (S / F)^(1 / gamma), F = max_dn - black: black and full
// scale stay where they are, a mid-scale signal is lifted.
TEST(ExposeFrame, ResponseCurveMapsAKnownRadianceToTheExpectedCode) {
  SensorModel sensor;
  sensor.bit_depth = 12;
  sensor.black_level_dn = 64;
  sensor.e_per_dn = 1.0;
  sensor.response_e_per_us = 1.0;
  sensor.read_noise_e = 0;
  sensor.shot_noise = false;
  sensor.full_well_e = 1e9;
  sensor.response_gamma = 2.0;
  const double full_scale = 4095 - 64;
  // 1000 DN of linear signal: 64 + sqrt(1000 * 4031) = 2071.74.
  const cv::Mat radiance(2, 2, CV_32F, cv::Scalar(1.0));
  for (auto p : ExposeFrame(sensor, radiance, 1000.0, 0.0, 1, 0)) EXPECT_EQ(p, 2072);
  EXPECT_DOUBLE_EQ(ApplyResponse(sensor, 0.0), 64.0);
  EXPECT_DOUBLE_EQ(ApplyResponse(sensor, full_scale), 4095.0);
  // Odd about black: read noise below black mirrors the noise above it.
  EXPECT_DOUBLE_EQ(ApplyResponse(sensor, -16.0) - 64.0, -(ApplyResponse(sensor, 16.0) - 64.0));
  sensor.response_gamma = 1.1;  // +3.2 % of full scale at half scale, as sensor.h says
  EXPECT_NEAR((ApplyResponse(sensor, full_scale / 2) - 64.0) / full_scale - 0.5, 0.0325, 5e-4);
  sensor.response_gamma = 1.0;
  for (auto p : ExposeFrame(sensor, radiance, 1000.0, 0.0, 1, 0)) EXPECT_EQ(p, 1064);
}

TEST(ExposeFrame, NoiseIsDeterministicPerSeedAndFrame) {
  SensorModel sensor;
  const cv::Mat radiance(32, 32, CV_32F, cv::Scalar(100.0));
  const auto a = ExposeFrame(sensor, radiance, 1000.0, 0.0, 5, 3);
  EXPECT_EQ(a, ExposeFrame(sensor, radiance, 1000.0, 0.0, 5, 3));
  EXPECT_NE(a, ExposeFrame(sensor, radiance, 1000.0, 0.0, 5, 4));
  EXPECT_NE(a, ExposeFrame(sensor, radiance, 1000.0, 0.0, 6, 3));
}

TEST(ExposeFrame, NoiseFreeSensorQuantisesTheMean) {
  SensorModel sensor;
  sensor.shot_noise = false;
  sensor.read_noise_e = 0;
  const double exposure_us = 2000.0;
  const cv::Mat radiance(2, 2, CV_32F, cv::Scalar(0.7));
  const double dn = 0.7 * sensor.DnPerRadiance(exposure_us, 6.0) + sensor.black_level_dn;
  for (auto p : ExposeFrame(sensor, radiance, exposure_us, 6.0, 1, 0)) EXPECT_EQ(p, std::lround(dn));
}

}  // namespace
}  // namespace photorig::sim
