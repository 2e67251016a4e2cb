#include "photorig/solvers/lighting/led_radiance.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace photorig::solvers::lighting {
namespace {

constexpr int kSize = 128;
constexpr double kPitchMm = 0.5;         // the image spans 64 mm of the sample plane
constexpr double kPlaneRadiusMm = 28.0;  // a round white target
constexpr double kAlbedo = 0.8;
constexpr double kDnPerRadiance = 20000.0;  // 3000 to 5000 DN on the plane, 1 % noise
constexpr double kReadSigmaDn = 2.0, kShotGain = 0.25;

struct Led {
  Eigen::Vector3d position_mm;
  double intensity, cos_exponent;
};

// Twelve LEDs on a 120 mm dome, three rings, each aimed at the origin.
std::vector<Led> Dome(double cos_exponent) {
  std::vector<Led> leds;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> intensity(0.8, 1.2);
  for (int ring = 0; ring < 3; ++ring)
    for (int i = 0; i < 4; ++i) {
      const double elevation = (30.0 + 20.0 * ring) * M_PI / 180.0, azimuth = (90.0 * i + 30.0 * ring) * M_PI / 180.0;
      const Eigen::Vector3d w(std::cos(elevation) * std::cos(azimuth), std::cos(elevation) * std::sin(azimuth),
                              std::sin(elevation));
      leds.push_back({120.0 * w, intensity(rng), cos_exponent});
    }
  return leds;
}

// Written out from the model rather than taken from the solver: the plane's
// radiance under each LED, with the sensor's noise, as photographs with the
// given stated exponent. `shade` darkens the plane's x > 0 half by a factor.
std::vector<LedPlaneFrame> Photograph(const std::vector<Led>& leds, double stated_exponent, double shade = 1.0) {
  std::vector<LedPlaneFrame> frames;
  std::mt19937 rng(9);
  std::normal_distribution<double> gauss(0.0, 1.0);
  for (const Led& led : leds) {
    LedPlaneFrame frame;
    frame.signal = cv::Mat::zeros(kSize, kSize, CV_32F);
    frame.dn_per_radiance = kDnPerRadiance;
    frame.position_mm = led.position_mm;
    frame.axis = -led.position_mm.normalized();
    frame.cos_exponent = stated_exponent;
    for (int r = 0; r < kSize; ++r)
      for (int c = 0; c < kSize; ++c) {
        const Eigen::Vector3d x((c + 0.5 - kSize / 2.0) * kPitchMm, (kSize / 2.0 - r - 0.5) * kPitchMm, 0.0);
        double signal = 0.0;
        if (x.norm() < kPlaneRadiusMm) {
          const Eigen::Vector3d to = led.position_mm - x;
          const Eigen::Vector3d l = to.normalized();
          const double irradiance = led.intensity * led.position_mm.squaredNorm() / to.squaredNorm() *
                                    std::pow(-frame.axis.dot(l), led.cos_exponent);
          signal = kDnPerRadiance * kAlbedo / M_PI * irradiance * l.z() * (x.x() > 0.0 ? shade : 1.0);
        }
        signal += std::sqrt(kReadSigmaDn * kReadSigmaDn + kShotGain * signal) * gauss(rng);
        frame.signal.at<float>(r, c) = static_cast<float>(signal);
      }
    frames.push_back(frame);
  }
  return frames;
}

LedRadianceOptions Options(ExponentRule rule = ExponentRule::kChoose) {
  LedRadianceOptions options;
  options.albedo = kAlbedo;
  options.exponent = rule;
  return options;
}

const camera::Camera kCamera = camera::Camera::Orthographic(kSize, kSize, kPitchMm);
const SensorNoise kNoise{kReadSigmaDn, kShotGain};

TEST(LedRadiance, IntensitiesAndANarrowerProfileThanStatedAreRecovered) {
  const std::vector<Led> leds = Dome(3.0);  // the rig says Lambertian emitters (1)
  const LedRadianceSummary summary = CalibrateLedRadiance(Options(), kCamera, kNoise, Photograph(leds, 1.0));
  ASSERT_EQ(summary.termination, core::Termination::kSuccess) << summary.message;
  EXPECT_EQ(summary.usable, 12);
  for (std::size_t k = 0; k < leds.size(); ++k) {
    const LedRadianceEstimate& e = summary.leds[k];
    EXPECT_TRUE(e.exponent_fitted) << k;
    EXPECT_NEAR(e.intensity, leds[k].intensity, 0.005 * leds[k].intensity) << k;
    EXPECT_NEAR(e.cos_exponent, 3.0, 0.3) << k;
    // The stated uncertainty covers the error (4 sigma).
    EXPECT_LT(std::abs(e.cos_exponent - 3.0), 4.0 * e.cos_exponent_std) << k;
    // The noise explains the scatter: what is left is the excess estimate's own
    // spread, (2 / n)^(1/4) of the 1 % noise with n ~ 2400 samples.
    EXPECT_LT(e.model_error, 0.003) << k;
  }
}

TEST(LedRadiance, AnExponentTheDataDoNotContradictIsKept) {
  const std::vector<Led> leds = Dome(1.0);
  const LedRadianceSummary summary = CalibrateLedRadiance(Options(), kCamera, kNoise, Photograph(leds, 1.0));
  ASSERT_EQ(summary.termination, core::Termination::kSuccess) << summary.message;
  int kept = 0;
  for (std::size_t k = 0; k < leds.size(); ++k) {
    EXPECT_NEAR(summary.leds[k].intensity, leds[k].intensity, 0.005 * leds[k].intensity) << k;
    EXPECT_NEAR(summary.leds[k].cos_exponent, 1.0, 0.3) << k;
    kept += !summary.leds[k].exponent_fitted;
  }
  // The information criterion keeps the stated profile for most LEDs (a
  // chance preference for the free fit is e^-ln(n)/2 ~ 1 % per LED at most).
  EXPECT_GE(kept, 10);
  const LedRadianceSummary forced = CalibrateLedRadiance(Options(ExponentRule::kKeep), kCamera, kNoise, Photograph(leds, 1.0));
  for (const LedRadianceEstimate& e : forced.leds) EXPECT_FALSE(e.exponent_fitted);
}

TEST(LedRadiance, APlaneShadedAgainstTheModelMakesItsLedsUnusable) {
  const LedRadianceSummary summary =
      CalibrateLedRadiance(Options(), kCamera, kNoise, Photograph(Dome(1.0), 1.0, 0.8));
  EXPECT_EQ(summary.termination, core::Termination::kFailure);
  EXPECT_EQ(summary.usable, 0);
  EXPECT_NE(summary.message.find("departs from the model"), std::string::npos) << summary.message;
}

TEST(LedRadiance, BadInputIsRefusedSayingWhat) {
  std::vector<LedPlaneFrame> frames = Photograph(Dome(1.0), 1.0);
  EXPECT_EQ(CalibrateLedRadiance(Options(), kCamera, SensorNoise{}, frames).termination,
            core::Termination::kInvalidInput);
  LedRadianceOptions no_albedo = Options();
  no_albedo.albedo = 0.0;
  EXPECT_EQ(CalibrateLedRadiance(no_albedo, kCamera, kNoise, frames).termination, core::Termination::kInvalidOptions);
  frames[4].position_mm.z() = -1.0;
  const LedRadianceSummary below = CalibrateLedRadiance(Options(), kCamera, kNoise, frames);
  EXPECT_EQ(below.termination, core::Termination::kInvalidInput);
  EXPECT_NE(below.message.find("frame 4"), std::string::npos) << below.message;
}

}  // namespace
}  // namespace photorig::solvers::lighting
