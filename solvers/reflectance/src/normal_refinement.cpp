// Joint refinement of normals and reflectance (normal_refinement.h): per-pixel
// Levenberg-Marquardt on the normal with the material's lobe fixed and the
// albedos eliminated, alternated with FitReflectance.
#include "photorig/solvers/reflectance/normal_refinement.h"
#include "photorig/solvers/reflectance/relighting.h"

#include "samples.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace photorig::solvers::reflectance {
namespace {

constexpr double kDegPerRad = 180.0 / M_PI;

// One pixel's usable samples and what its material says of them.
struct PixelProblem {
  int channels = 1;
  std::vector<Eigen::Vector3d> light;  // directions (camera frame)
  std::vector<double> value;           // [sample][channel]
  std::vector<double> irradiance;      // [sample][channel]
  std::vector<double> weight;          // [sample][channel]: 1 / variance
  Eigen::Vector3d view;
  internal::Lobe lobe;
  Eigen::Vector3d specular = Eigen::Vector3d::Zero();
  Eigen::Vector3d t0, b0, n0;  // the starting normal and its tangent plane

  int samples() const { return static_cast<int>(light.size()); }

  Eigen::Vector3d Normal(const Eigen::Vector2d& x) const { return (n0 + x[0] * t0 + x[1] * b0).normalized(); }

  // Weighted residuals at normal n with each channel's albedo at its
  // weighted least-squares value (clamped at 0); returns the squared norm.
  double Residuals(const Eigen::Vector3d& n, Eigen::VectorXd* r, Eigen::Vector3d* rho = nullptr) const {
    const int K = samples(), C = channels;
    const Eigen::Vector3d wo = internal::ToLocal(n, view);
    std::vector<double> u(static_cast<std::size_t>(K) * C), g(u.size());
    for (int k = 0; k < K; ++k) {
      const Eigen::Vector3d wi = internal::ToLocal(n, light[k]);
      const double cosine = std::max(wi.z(), 0.0);
      double a0 = 0.0, a1 = 0.0;
      if (cosine > 0.0) internal::LobeBasis(lobe, brdf::GeometryOf(wi, wo), &a0, &a1);
      for (int c = 0; c < C; ++c) {
        const std::size_t i = static_cast<std::size_t>(k) * C + c;
        const double e = irradiance[i] * cosine;
        u[i] = e / M_PI;
        g[i] = e * (a0 + specular[c] * (a1 - a0));
      }
    }
    r->resize(static_cast<Eigen::Index>(K) * C);
    Eigen::Vector3d albedo = Eigen::Vector3d::Zero();
    for (int c = 0; c < C; ++c) {
      double uu = 0.0, uy = 0.0;
      for (int k = 0; k < K; ++k) {
        const std::size_t i = static_cast<std::size_t>(k) * C + c;
        uu += weight[i] * u[i] * u[i];
        uy += weight[i] * u[i] * (value[i] - g[i]);
      }
      albedo[c] = uu > 0.0 ? std::max(uy / uu, 0.0) : 0.0;
      for (int k = 0; k < K; ++k) {
        const std::size_t i = static_cast<std::size_t>(k) * C + c;
        (*r)[static_cast<Eigen::Index>(i)] = std::sqrt(weight[i]) * (value[i] - u[i] * albedo[c] - g[i]);
      }
    }
    if (rho) *rho = albedo;
    return r->squaredNorm();
  }
};

// Pixel i's problem from starting normal n0 under its material: its samples
// under the lights not kept for judging that face n0 by min_cosine or more
// and are unclipped, not yet weighted.
PixelProblem ProblemAt(const ReflectanceStack& stack, const internal::PixelLights& lights, int i,
                       const Eigen::Vector3d& n0, const MaterialFit& material, const std::vector<std::uint8_t>& judging,
                       double min_cosine) {
  const int C = stack.channels();
  PixelProblem problem;
  problem.channels = C;
  problem.view = lights.View(i);
  problem.n0 = n0;
  internal::FrameOf(problem.n0, &problem.t0, &problem.b0);
  problem.lobe = {material.model, material.shape};
  problem.specular = material.specular;
  for (int j = 0; j < stack.light_count(); ++j) {
    Eigen::Vector3d towards;
    const double gain = lights.At(i, j, &towards);
    if (judging[j] || !(gain > 0.0) || problem.n0.dot(towards) < min_cosine) continue;
    const float* px = stack.images[j].ptr<float>() + static_cast<std::size_t>(i) * C;
    bool usable = true;
    for (int c = 0; c < C; ++c) usable = usable && std::isfinite(px[c]) && px[c] < stack.saturation_level;
    if (!usable) continue;
    problem.light.push_back(towards);
    const Eigen::Vector3d e = gain * stack.Intensity(j);
    for (int c = 0; c < C; ++c) {
      problem.value.push_back(px[c]);
      problem.irradiance.push_back(e[c]);
    }
  }
  return problem;
}

// Weights from the noise model at the signal predicted with the starting normal.
void WeightByNoise(const SensorNoise& noise, PixelProblem* problem) {
  problem->weight.assign(problem->value.size(), 1.0);
  Eigen::VectorXd r;
  Eigen::Vector3d rho;
  problem->Residuals(problem->n0, &r, &rho);
  for (std::size_t s = 0; s < problem->value.size(); ++s) {
    const int c = static_cast<int>(s % problem->channels);
    const double predicted = problem->value[s] - r[static_cast<Eigen::Index>(s)];
    problem->weight[s] = 1.0 / std::max(noise.Variance(c, predicted), 1e-12);
  }
}

// Levenberg-Marquardt over the two tangent-plane offsets, forward-difference
// Jacobian (3 residual evaluations an iteration; central differences took 5
// for no gain in the result at this step). Returns the final normal;
// *improved says whether the cost fell.
Eigen::Vector3d Minimise(const PixelProblem& problem, bool* improved) {
  Eigen::Vector2d x = Eigen::Vector2d::Zero();
  Eigen::VectorXd r, r_plus, trial;
  const double start_cost = problem.Residuals(problem.Normal(x), &r);
  double cost = start_cost, lambda = 1e-3;
  constexpr double kStep = 1e-6;  // radians
  for (int iteration = 0; iteration < 30; ++iteration) {
    Eigen::MatrixXd jacobian(r.size(), 2);
    for (int a = 0; a < 2; ++a) {
      Eigen::Vector2d dx = Eigen::Vector2d::Zero();
      dx[a] = kStep;
      problem.Residuals(problem.Normal(x + dx), &r_plus);
      jacobian.col(a) = (r_plus - r) / kStep;
    }
    const Eigen::Matrix2d jtj = jacobian.transpose() * jacobian;
    const Eigen::Vector2d gradient = jacobian.transpose() * r;
    bool accepted = false;
    while (lambda < 1e10) {
      Eigen::Matrix2d damped = jtj;
      damped.diagonal() += lambda * jtj.diagonal().cwiseMax(1e-12);
      const Eigen::Vector2d step = damped.ldlt().solve(-gradient);
      const double trial_cost = problem.Residuals(problem.Normal(x + step), &trial);
      if (trial_cost < cost) {
        const double gain = cost - trial_cost;
        x += step;
        r = trial;
        cost = trial_cost;
        lambda = std::max(lambda / 3.0, 1e-9);
        accepted = true;
        if (step.norm() < 1e-8 || gain < 1e-10 * cost) iteration = 30;
        break;
      }
      lambda *= 4.0;
    }
    if (!accepted) break;
  }
  *improved = cost < start_cost;
  return problem.Normal(x);
}

double Quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const auto it = v.begin() + static_cast<std::ptrdiff_t>(q * (v.size() - 1));
  std::nth_element(v.begin(), it, v.end());
  return *it;
}

}  // namespace

bool NormalRefinementOptions::IsValid(std::string* why) const {
  if (rounds < 1) return core::Refuse(why, "rounds must be >= 1");
  if (!(max_change_deg > 0.0 && max_change_deg <= 90.0)) return core::Refuse(why, "max_change_deg must be in (0, 90]");
  if (!(converged_deg >= 0.0)) return core::Refuse(why, "converged_deg must be >= 0");
  if (keep_better && held_out_lights < 0) return core::Refuse(why, "held_out_lights must be >= 0 (0 = every light)");
  return fit.IsValid(why);
}

NormalRefinementSummary RefineNormalsAndReflectance(const NormalRefinementOptions& options,
                                                    const ReflectanceStack& stack, const cv::Mat& normals,
                                                    const cv::Mat& mask, cv::Mat* refined_normals,
                                                    ReflectanceMaps* maps) {
  std::string why;
  if (!options.IsValid(&why)) {
    NormalRefinementSummary summary;
    summary.End(core::Termination::kInvalidOptions, why);
    return summary;
  }
  ReflectanceMaps first;
  const ReflectanceSummary fitted = FitReflectance(options.fit, stack, normals, mask, &first);
  if (!fitted.IsSolutionUsable()) {
    NormalRefinementSummary summary;
    summary.End(fitted.termination, fitted.message);
    summary.reflectance = fitted;
    return summary;
  }
  return RefineNormalsAndReflectance(options, stack, normals, mask, first, fitted, refined_normals, maps);
}

NormalRefinementSummary RefineNormalsAndReflectance(const NormalRefinementOptions& options,
                                                    const ReflectanceStack& stack, const cv::Mat& normals,
                                                    const cv::Mat& mask, const ReflectanceMaps& first,
                                                    const ReflectanceSummary& first_summary, cv::Mat* refined_normals,
                                                    ReflectanceMaps* maps) {
  core::SolveTimer timer;
  NormalRefinementSummary summary;
  std::string why;
  if (!options.IsValid(&why)) {
    summary.End(core::Termination::kInvalidOptions, why);
    return summary;
  }
  if (!first_summary.IsSolutionUsable() || first.material.size() != normals.size() ||
      static_cast<int>(first.materials.size()) != first_summary.materials) {
    summary.End(core::Termination::kInvalidInput, "the first fit is not a usable fit of these normals");
    return summary;
  }
  ReflectanceMaps current = first;
  ReflectanceSummary fitted = first_summary;
  summary.reduced_chi_square_before = fitted.reduced_chi_square;
  timer.SetupDone(&summary);
  cv::Mat n = normals.clone();
  // The lights that judge the result are left out of the normal steps: normals
  // fitted to a light predict it well whether or not they are nearer the truth.
  std::vector<std::uint8_t> judging(stack.light_count(), 0);
  if (options.keep_better)
    for (int j : StratifiedLights(stack.light_directions, options.held_out_lights)) judging[j] = 1;
  const double max_change = options.max_change_deg / kDegPerRad;
  const internal::PixelLights lights(stack);
  for (int round = 0; round < options.rounds; ++round) {
    if (options.progress) options.progress({"normals", round, options.rounds, {}});
    std::vector<int> fitted_pixels;
    for (int i = 0; i < static_cast<int>(current.material.total()); ++i)
      if (current.material.data[i] != 255) fitted_pixels.push_back(i);
    const core::SolveTimer step_timer;
    cv::Mat next = n.clone();
    std::vector<double> change(fitted_pixels.size(), -1.0);  // radians; < 0: held
#pragma omp parallel for schedule(dynamic, 64)
    for (std::size_t f = 0; f < fitted_pixels.size(); ++f) {
      const int i = fitted_pixels[f];
      const cv::Vec3f& nv = n.at<cv::Vec3f>(i);
      PixelProblem problem = ProblemAt(stack, lights, i, Eigen::Vector3d(nv[0], nv[1], nv[2]).normalized(),
                                       current.materials[current.material.data[i]], judging, options.fit.min_cosine);
      if (problem.samples() < options.fit.min_samples) continue;
      WeightByNoise(fitted.noise, &problem);
      bool improved = false;
      const Eigen::Vector3d moved = Minimise(problem, &improved);
      const double angle = std::acos(std::clamp(moved.dot(problem.n0), -1.0, 1.0));
      if (!improved || angle > max_change) continue;
      next.at<cv::Vec3f>(i) = cv::Vec3f(static_cast<float>(moved.x()), static_cast<float>(moved.y()),
                                        static_cast<float>(moved.z()));
      change[f] = angle;
    }
    std::vector<double> moved_deg;
    int held = 0;
    for (double c : change) {
      if (c < 0.0) ++held; else moved_deg.push_back(c * kDegPerRad);
    }
    summary.normals_ms += step_timer.ElapsedMs();
    ReflectanceMaps refit;
    const ReflectanceSummary refitted = FitReflectance(options.fit, stack, next, mask, &refit);
    if (!refitted.IsSolutionUsable()) break;  // keep the last good normals and fit
    n = next;
    current = std::move(refit);
    fitted = refitted;
    ++summary.rounds;
    summary.pixels_refined = static_cast<int>(moved_deg.size());
    summary.pixels_held = held;
    summary.median_change_deg.push_back(Quantile(moved_deg, 0.5));
    summary.p95_change_deg.push_back(Quantile(moved_deg, 0.95));
    if (summary.median_change_deg.back() < options.converged_deg) break;
  }
  std::string verdict;
  if (options.keep_better && summary.rounds > 0) {
    const core::SolveTimer judge_timer;
    // Both fits judged on the same pixels: those each of them resolved.
    const int resolved = static_cast<int>(PixelFlag::kFitted);
    const cv::Mat both = (first.flags == resolved) & (current.flags == resolved);
    RelightingOptions judge;
    judge.fit = options.fit;
    judge.fit.progress = nullptr;
    judge.held_out_lights = options.held_out_lights;
    judge.methods = {Method::kPerMaterial};
    const RelightingSummary on_given = EvaluateHeldOutLights(judge, stack, normals, both, first, first_summary);
    const RelightingSummary on_refined = EvaluateHeldOutLights(judge, stack, n, both, current, fitted);
    const int per_material = static_cast<int>(Method::kPerMaterial);
    if (on_given.IsSolutionUsable() && on_refined.IsSolutionUsable()) {
      summary.held_out_rmse_given = on_given.mean_rmse[per_material];
      summary.held_out_rmse_refined = on_refined.mean_rmse[per_material];
      summary.kept_refined = summary.held_out_rmse_refined < summary.held_out_rmse_given;
      verdict = std::string("; kept the ") + (summary.kept_refined ? "refined" : "given") +
                " normals (held-out RMSE given " + std::to_string(summary.held_out_rmse_given) + ", refined " +
                std::to_string(summary.held_out_rmse_refined) + ")";
    } else {
      // Unjudged, the refinement cannot promise to be no worse: the given normals stay.
      summary.kept_refined = false;
      verdict = "; kept the given normals: the held-out check failed (" +
                (on_given.IsSolutionUsable() ? on_refined.message : on_given.message) + ")";
    }
    if (!summary.kept_refined) {
      n = normals.clone();
      current = first;
      fitted = first_summary;
    }
    summary.judge_ms = judge_timer.ElapsedMs();
  }
  summary.reduced_chi_square_after = fitted.reduced_chi_square;
  summary.reflectance = fitted;
  *refined_normals = n;
  *maps = std::move(current);
  summary.termination = summary.rounds == options.rounds || (!summary.median_change_deg.empty() &&
                                                             summary.median_change_deg.back() < options.converged_deg)
                            ? core::Termination::kSuccess
                            : core::Termination::kNoConvergence;
  summary.message = std::to_string(summary.rounds) + " round(s); reduced chi-square " +
                    std::to_string(summary.reduced_chi_square_before) + " -> " +
                    std::to_string(summary.reduced_chi_square_after) + verdict;
  timer.Finish(&summary);
  return summary;
}

}  // namespace photorig::solvers::reflectance
