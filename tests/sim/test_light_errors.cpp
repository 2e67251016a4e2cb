#include "photorig/sim/light_errors.h"

#include <gtest/gtest.h>

#include <cmath>

namespace photorig::sim {
namespace {

// 96 lights spread over a hemisphere, each of irradiance 1 + k / 100.
std::vector<Light> Dome() {
  std::vector<Light> lights;
  for (int k = 0; k < 96; ++k) {
    const double elevation = (20.0 + 60.0 * (k % 6) / 5.0) * M_PI / 180.0, azimuth = 2.0 * M_PI * k / 96.0;
    lights.emplace_back(Eigen::Vector3d(std::cos(elevation) * std::cos(azimuth), std::cos(elevation) * std::sin(azimuth),
                                        std::sin(elevation)),
                        1.0 + k / 100.0);
  }
  return lights;
}

TEST(PerturbLights, ErrorsHaveTheRequestedRmsOverManySeeds) {
  const std::vector<Light> stated = Dome();
  double angle2 = 0.0, relative2 = 0.0, relative = 0.0;
  int count = 0;
  for (std::uint64_t seed = 1; seed <= 100; ++seed) {
    std::vector<Light> lights = stated;
    PerturbLights({2.0, 5.0}, seed, &lights);
    for (std::size_t k = 0; k < lights.size(); ++k) {
      EXPECT_NEAR(lights[k].direction.norm(), 1.0, 1e-12);
      const double angle_deg =
          std::acos(std::clamp(lights[k].direction.dot(stated[k].direction), -1.0, 1.0)) * 180.0 / M_PI;
      angle2 += angle_deg * angle_deg;
      const double error = lights[k].irradiance / stated[k].irradiance - 1.0;
      relative += error;
      relative2 += error * error;
      ++count;
    }
  }
  // 9600 draws: the sample RMS is within about 1 % of the truth (its relative
  // standard error is 1 / sqrt(2 n) for the angle's two components, 1 /
  // sqrt(2 n) for the intensity).
  EXPECT_NEAR(std::sqrt(angle2 / count), 2.0, 0.04);
  EXPECT_NEAR(std::sqrt(relative2 / count), 0.05, 0.001);
  EXPECT_NEAR(relative / count, 0.0, 0.0015);  // unbiased: the stated figure is the mean
}

TEST(PerturbLights, IsDeterministicAndEachErrorKeepsItsOwnDraws) {
  std::vector<Light> both = Dome(), directions_only = Dome(), intensities_only = Dome(), again = Dome();
  PerturbLights({1.5, 4.0}, 7, &both);
  PerturbLights({1.5, 4.0}, 7, &again);
  PerturbLights({1.5, 0.0}, 7, &directions_only);
  PerturbLights({0.0, 4.0}, 7, &intensities_only);
  const std::vector<Light> stated = Dome();
  for (std::size_t k = 0; k < both.size(); ++k) {
    EXPECT_EQ(both[k].direction, again[k].direction);
    EXPECT_EQ(both[k].irradiance, again[k].irradiance);
    EXPECT_EQ(both[k].direction, directions_only[k].direction);
    EXPECT_EQ(both[k].irradiance, intensities_only[k].irradiance);
    EXPECT_EQ(directions_only[k].irradiance, stated[k].irradiance);
    EXPECT_EQ(intensities_only[k].direction, stated[k].direction);
  }
  std::vector<Light> other_seed = Dome();
  PerturbLights({1.5, 4.0}, 8, &other_seed);
  EXPECT_NE(other_seed[0].irradiance, both[0].irradiance);
}

TEST(PerturbLights, ANearLedSwingsAboutTheOriginStillAimedAtIt) {
  std::vector<Light> lights(1);
  lights[0].position_mm = Eigen::Vector3d(0.0, 100.0, 200.0);
  lights[0].direction = lights[0].position_mm->normalized();
  lights[0].axis = -lights[0].direction;
  PerturbLights({3.0, 0.0}, 11, &lights);
  EXPECT_NEAR(lights[0].position_mm->norm(), std::sqrt(100.0 * 100.0 + 200.0 * 200.0), 1e-9);
  EXPECT_LT((lights[0].position_mm->normalized() - lights[0].direction).norm(), 1e-12);
  EXPECT_LT((lights[0].axis + lights[0].direction).norm(), 1e-12);
}

}  // namespace
}  // namespace photorig::sim
