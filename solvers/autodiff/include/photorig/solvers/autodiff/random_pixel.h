// Random, physically plausible Blinn-Phong pixels: the shared workload of the tests, the
// benchmark and the speed-accuracy chart. Deterministic for a given generator state.
#pragma once

#include <array>
#include <cmath>
#include <numbers>
#include <random>

#include <Eigen/Core>

#include "photorig/solvers/autodiff/blinn_phong.h"

namespace photorig::solvers::autodiff {

struct RandomPixel {
  BlinnPhongPixel pixel;
  // Where to evaluate: the parameters that rendered the observations, perturbed, with the
  // normal left unnormalised (|m| in [0.5, 1.5]) as a fitter's iterate would be.
  std::array<double, BlinnPhongPixel::kNumParameters> parameters;
};

// The camera looks down -z (w_o = +z). Lights lie 15 to 80 degrees above the horizon, the normal
// within 60 degrees of the view; rho_d in [0.2, 0.8], rho_s in [0.1, 0.6], e in [2, 60].
inline RandomPixel MakeRandomPixel(int num_lights, std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const auto direction = [&](double min_elevation_rad, double max_elevation_rad) {
    const double elevation =
        min_elevation_rad + (max_elevation_rad - min_elevation_rad) * unit(rng);
    const double azimuth = 2.0 * std::numbers::pi * unit(rng);
    return Eigen::Vector3d(std::cos(elevation) * std::cos(azimuth),
                           std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
  };
  constexpr double kDegree = std::numbers::pi / 180.0;

  Eigen::Matrix<double, Eigen::Dynamic, 3> light_directions(num_lights, 3);
  Eigen::VectorXd light_intensities(num_lights);
  for (int i = 0; i < num_lights; ++i) {
    light_directions.row(i) = direction(15.0 * kDegree, 80.0 * kDegree).transpose();
    light_intensities[i] = 0.5 + 1.5 * unit(rng);
  }
  const Eigen::Vector3d normal = direction(30.0 * kDegree, 90.0 * kDegree);
  const std::array<double, BlinnPhongPixel::kNumParameters> truth = {normal.x(),
                                                                     normal.y(),
                                                                     normal.z(),
                                                                     0.2 + 0.6 * unit(rng),
                                                                     0.1 + 0.5 * unit(rng),
                                                                     2.0 + 58.0 * unit(rng)};

  const Eigen::Vector3d view(0.0, 0.0, 1.0);
  const BlinnPhongPixel renderer(light_directions, light_intensities, view,
                                 Eigen::VectorXd::Zero(num_lights));
  Eigen::VectorXd observed(num_lights);
  renderer.Predict(truth.data(), observed.data());

  std::array<double, BlinnPhongPixel::kNumParameters> parameters = truth;
  const double scale = 0.5 + unit(rng);
  for (int k = 0; k < 3; ++k) {
    parameters[k] = scale * (truth[k] + 0.1 * (unit(rng) - 0.5));
  }
  parameters[BlinnPhongPixel::kDiffuseAlbedo] *= 0.8 + 0.4 * unit(rng);
  parameters[BlinnPhongPixel::kSpecularAlbedo] *= 0.8 + 0.4 * unit(rng);
  parameters[BlinnPhongPixel::kExponent] *= 0.8 + 0.4 * unit(rng);
  return {BlinnPhongPixel(light_directions, light_intensities, view, observed), parameters};
}

}  // namespace photorig::solvers::autodiff
