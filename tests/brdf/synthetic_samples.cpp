#include "synthetic_samples.h"

#include "photorig/solvers/brdf/half_diff.h"

#include <cmath>
#include <random>

namespace photorig::solvers::brdf::testing {

std::vector<BrdfSample> SyntheticSamples(const ModelParams& truth, const SyntheticSpec& spec) {
  std::mt19937 rng(spec.seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 1.0);
  constexpr double kDeg = M_PI / 180.0;
  std::vector<BrdfSample> samples;
  while (static_cast<int>(samples.size()) < spec.count) {
    const HalfDiff a{(spec.theta_h_min_deg + (spec.theta_h_max_deg - spec.theta_h_min_deg) * unit(rng)) * kDeg,
                     spec.theta_d_max_deg * unit(rng) * kDeg, 2.0 * M_PI * unit(rng)};
    const DirectionPair dirs = FromHalfDiff(a, 2.0 * M_PI * unit(rng));
    if (dirs.wi.z() < 0.05 || dirs.wo.z() < 0.05) continue;
    BrdfSample s;
    s.wi = dirs.wi;
    s.wo = dirs.wo;
    const Eigen::Vector3d f = Evaluate(truth, s.wi, s.wo);
    for (int c = 0; c < 3; ++c) {
      s.sigma[c] = spec.relative_sigma * f[c] + spec.absolute_sigma;
      s.value[c] = f[c] + s.sigma[c] * gauss(rng);
    }
    samples.push_back(s);
  }
  return samples;
}

double RelativeError(const ModelParams& fit, const ModelParams& truth, const std::vector<BrdfSample>& held_out) {
  double diff = 0.0, norm = 0.0;
  for (const BrdfSample& s : held_out) {
    const Eigen::Vector3d t = Evaluate(truth, s.wi, s.wo) * s.wi.z(), f = Evaluate(fit, s.wi, s.wo) * s.wi.z();
    diff += (f - t).squaredNorm();
    norm += t.squaredNorm();
  }
  return std::sqrt(diff / norm);
}

}  // namespace photorig::solvers::brdf::testing
