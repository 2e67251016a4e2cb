#include "photorig/solvers/brdf/fit.h"

#include "lobes.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace photorig::solvers::brdf {
namespace {

// Per sample: the geometry, the measurement and the per-channel weight of its
// residual (1 / sigma for kWeighted, 1 for kLog).
struct Prepared {
  Geometry geometry;
  Eigen::Vector3d value;
  Eigen::Vector3d weight;
};

// The residuals of one sample. `kd` holds rho_d per channel; `lobe` (absent
// for Lambertian) holds the specular parameter per channel and log(shape);
// `f0` (Cook-Torrance only) its Fresnel F0.
class SampleResidual {
 public:
  SampleResidual(Model model, const Prepared& sample, FitLoss loss) : model_(model), s_(sample), loss_(loss) {}

  template <typename T>
  bool operator()(const T* kd, const T* lobe, const T* f0, T* residual) const {
    using std::exp;
    const T shape = exp(lobe[3]);
    for (int c = 0; c < 3; ++c)
      Finish(c, kd[c] / M_PI + internal::Lobe(model_, lobe[c], shape, *f0, s_.geometry), residual);
    return true;
  }
  template <typename T>
  bool operator()(const T* kd, const T* lobe, T* residual) const {
    const T no_f0(0.0);
    return (*this)(kd, lobe, &no_f0, residual);
  }
  template <typename T>
  bool operator()(const T* kd, T* residual) const {
    for (int c = 0; c < 3; ++c) Finish(c, kd[c] / M_PI, residual);
    return true;
  }

 private:
  template <typename T>
  void Finish(int c, const T& f, T* residual) const {
    using std::log;
    if (loss_ == FitLoss::kWeighted) {
      residual[c] = (f - s_.value[c]) * s_.weight[c];
    } else {
      const double ci = s_.geometry.cos_i;
      residual[c] = log(1.0 + f * ci) - std::log(1.0 + s_.value[c] * ci);
    }
  }

  Model model_;
  Prepared s_;
  FitLoss loss_;
};

// The shape values the starting grid tries, and the bounds of the fit (as log shape).
struct ShapeRange {
  double min, max;
  int steps;
};
ShapeRange RangeOf(Model model) {
  return model == Model::kBlinnPhong ? ShapeRange{1.0, 1.0e4, 41} : ShapeRange{0.005, 1.0, 41};
}

// Cook-Torrance's F0 is not linear in the lobe: the starting grid tries these.
std::vector<double> StartingF0s(Model model) {
  return model == Model::kCookTorrance ? std::vector<double>{0.05, 0.2, 0.4, 0.6, 0.8, 0.95}
                                       : std::vector<double>{0.0};
}

// Weighted least squares of one channel's value against
// f = kd / pi + ks * basis + offset with kd, ks >= 0 (a lobe affine in its
// specular parameter). Returns the weighted squared error.
double FitLinearChannel(const std::vector<Prepared>& prepared, const std::vector<double>& basis,
                        const std::vector<double>& offset, int c, double* kd, double* ks) {
  double a00 = 0, a01 = 0, a11 = 0, b0 = 0, b1 = 0;
  for (std::size_t k = 0; k < prepared.size(); ++k) {
    const double w2 = prepared[k].weight[c] * prepared[k].weight[c];
    const double x0 = 1.0 / M_PI, x1 = basis[k], y = prepared[k].value[c] - offset[k];
    a00 += w2 * x0 * x0;
    a01 += w2 * x0 * x1;
    a11 += w2 * x1 * x1;
    b0 += w2 * x0 * y;
    b1 += w2 * x1 * y;
  }
  const double det = a00 * a11 - a01 * a01;
  *kd = det > 0 ? (a11 * b0 - a01 * b1) / det : 0.0;
  *ks = det > 0 ? (a00 * b1 - a01 * b0) / det : 0.0;
  // On a negative coefficient, the best fit with it at zero.
  if (*kd < 0.0 || *ks < 0.0) {
    const double kd_only = std::max(0.0, b0 / a00), ks_only = a11 > 0 ? std::max(0.0, b1 / a11) : 0.0;
    // Compare the two one-term fits by the error they remove.
    if (kd_only * b0 >= ks_only * b1) {
      *kd = kd_only;
      *ks = 0.0;
    } else {
      *kd = 0.0;
      *ks = ks_only;
    }
  }
  double error = 0.0;
  for (std::size_t k = 0; k < prepared.size(); ++k) {
    const double r =
        (*kd / M_PI + *ks * basis[k] + offset[k] - prepared[k].value[c]) * prepared[k].weight[c];
    error += r * r;
  }
  return error;
}

// The starting point: the best shape on a geometric grid (and F0 on a coarse
// one), each with its channels' linear parameters solved exactly.
void StartingPoint(Model model, const std::vector<Prepared>& prepared, double kd[3], double lobe[4], double* f0_start) {
  const std::size_t n = prepared.size();
  std::vector<double> basis(n, 0.0), offset(n, 0.0);
  if (model == Model::kLambertian) {
    for (int c = 0; c < 3; ++c) {
      double ks;
      FitLinearChannel(prepared, basis, offset, c, &kd[c], &ks);
    }
    return;
  }
  const ShapeRange range = RangeOf(model);
  double best = std::numeric_limits<double>::infinity();
  for (int step = 0; step < range.steps; ++step) {
    const double shape = range.min * std::pow(range.max / range.min, step / (range.steps - 1.0));
    for (double f0 : StartingF0s(model)) {
      for (std::size_t k = 0; k < n; ++k) {
        offset[k] = internal::Lobe(model, 0.0, shape, f0, prepared[k].geometry);
        basis[k] = internal::Lobe(model, 1.0, shape, f0, prepared[k].geometry) - offset[k];
      }
      double error = 0.0, trial_kd[3], trial_ks[3];
      for (int c = 0; c < 3; ++c) error += FitLinearChannel(prepared, basis, offset, c, &trial_kd[c], &trial_ks[c]);
      if (error < best) {
        best = error;
        for (int c = 0; c < 3; ++c) {
          kd[c] = trial_kd[c];
          lobe[c] = model == Model::kGgx ? std::min(trial_ks[c], 1.0) : trial_ks[c];
        }
        lobe[3] = std::log(shape);
        *f0_start = f0;
      }
    }
  }
}

// RMS residual of `samples` under `params`, in the units of `loss`.
double RmsResidual(const ModelParams& params, const std::vector<BrdfSample>& samples, FitLoss loss) {
  double sum = 0.0;
  for (const BrdfSample& s : samples) {
    const Eigen::Vector3d f = Evaluate(params, s.wi, s.wo);
    for (int c = 0; c < 3; ++c) {
      const double r = loss == FitLoss::kWeighted
                           ? (f[c] - s.value[c]) / s.sigma[c]
                           : std::log(1.0 + f[c] * s.wi.z()) - std::log(1.0 + s.value[c] * s.wi.z());
      sum += r * r;
    }
  }
  return std::sqrt(sum / (3.0 * static_cast<double>(samples.size())));
}

// k-fold held-out RMS residual of `model`; NaN when a fold's fit fails.
double HeldOutRms(Model model, const std::vector<BrdfSample>& samples, const FitOptions& options, int folds) {
  double sum = 0.0;
  std::size_t count = 0;
  for (int fold = 0; fold < folds; ++fold) {
    std::vector<BrdfSample> train, test;
    for (std::size_t k = 0; k < samples.size(); ++k) (static_cast<int>(k % folds) == fold ? test : train).push_back(samples[k]);
    if (test.empty()) continue;
    const FitSummary fit = FitModel(model, train, options);
    if (!fit.IsSolutionUsable()) return std::numeric_limits<double>::quiet_NaN();
    const double rms = RmsResidual(fit.params, test, options.loss);
    sum += rms * rms * static_cast<double>(test.size());
    count += test.size();
  }
  return count > 0 ? std::sqrt(sum / static_cast<double>(count)) : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

bool FitOptions::IsValid(std::string* why) const {
  if (max_iterations < 1) {
    *why = "max_iterations must be at least 1";
    return false;
  }
  if (!(max_relative_shape_sigma > 0.0)) {
    *why = "max_relative_shape_sigma must be positive";
    return false;
  }
  return true;
}

bool SelectionOptions::IsValid(std::string* why) const {
  if (!fit.IsValid(why)) return false;
  if (candidates.empty()) {
    *why = "no candidate models";
    return false;
  }
  if (!(min_bic_improvement >= 0.0) || !(peak_theta_h_deg >= 0.0)) {
    *why = "min_bic_improvement and peak_theta_h_deg must be non-negative";
    return false;
  }
  if (held_out_folds < 0 || held_out_folds == 1) {
    *why = "held_out_folds must be 0 (none) or at least 2";
    return false;
  }
  return true;
}

FitSummary FitModel(Model model, const std::vector<BrdfSample>& samples, const FitOptions& options) {
  SolveTimer timer;
  FitSummary summary;
  summary.params.model = model;
  summary.samples = samples.size();
  summary.residuals = 3 * samples.size();
  summary.parameters = ParameterCount(model);
  if (std::string why; !options.IsValid(&why)) {
    summary.End(Termination::kInvalidOptions, why);
    return summary;
  }
  std::vector<Prepared> prepared;
  prepared.reserve(samples.size());
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const BrdfSample& s = samples[k];
    const std::string which = "sample " + std::to_string(k) + ": ";
    if (!s.wi.allFinite() || !s.wo.allFinite() || std::abs(s.wi.norm() - 1.0) > 1e-6 ||
        std::abs(s.wo.norm() - 1.0) > 1e-6) {
      summary.End(Termination::kInvalidInput, which + "directions must be finite unit vectors");
      return summary;
    }
    if (s.wi.z() <= 0.0 || s.wo.z() <= 0.0) {
      summary.End(Termination::kInvalidInput, which + "a direction is below the horizon (no BRDF value there)");
      return summary;
    }
    if (!s.value.allFinite() || !s.sigma.allFinite() || (s.sigma.array() < 0.0).any()) {
      summary.End(Termination::kInvalidInput, which + "value and sigma must be finite, sigma non-negative");
      return summary;
    }
    if (options.loss == FitLoss::kWeighted && (s.sigma.array() <= 0.0).any()) {
      summary.End(Termination::kInvalidInput,
                  which + "the weighted loss needs sigma > 0 in every channel (use the log loss without deviations)");
      return summary;
    }
    if (options.loss == FitLoss::kLog && (s.value.array() * s.wi.z() <= -1.0).any()) {
      summary.End(Termination::kInvalidInput, which + "value too negative for the log loss");
      return summary;
    }
    Prepared p{GeometryOf(s.wi, s.wo), s.value, Eigen::Vector3d::Ones()};
    if (options.loss == FitLoss::kWeighted) p.weight = s.sigma.cwiseInverse();
    prepared.push_back(p);
  }
  if (summary.residuals <= static_cast<std::size_t>(summary.parameters)) {
    summary.End(Termination::kFailure, std::to_string(samples.size()) + " samples (" +
                                           std::to_string(summary.residuals) + " values) cannot fit the " +
                                           std::to_string(summary.parameters) + " parameters of " + ModelName(model));
    if (model != Model::kLambertian) summary.lobe_identifiable = false;
    return summary;
  }

  double kd[3] = {0, 0, 0}, lobe[4] = {0, 0, 0, 0}, f0 = 0.0;
  StartingPoint(model, prepared, kd, lobe, &f0);
  ceres::Problem problem;
  for (const Prepared& p : prepared) {
    if (model == Model::kLambertian) {
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<SampleResidual, 3, 3>(new SampleResidual(model, p, options.loss)), nullptr,
          kd);
    } else if (model == Model::kCookTorrance) {
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<SampleResidual, 3, 3, 4, 1>(new SampleResidual(model, p, options.loss)),
          nullptr, kd, lobe, &f0);
    } else {
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<SampleResidual, 3, 3, 4>(new SampleResidual(model, p, options.loss)),
          nullptr, kd, lobe);
    }
  }
  for (int c = 0; c < 3; ++c) problem.SetParameterLowerBound(kd, c, 0.0);
  if (model != Model::kLambertian) {
    const ShapeRange range = RangeOf(model);
    for (int c = 0; c < 3; ++c) problem.SetParameterLowerBound(lobe, c, 0.0);
    if (model == Model::kGgx)
      for (int c = 0; c < 3; ++c) problem.SetParameterUpperBound(lobe, c, 1.0);
    problem.SetParameterLowerBound(lobe, 3, std::log(range.min));
    problem.SetParameterUpperBound(lobe, 3, std::log(range.max));
    if (model == Model::kCookTorrance) {
      problem.SetParameterLowerBound(&f0, 0, 0.0);
      problem.SetParameterUpperBound(&f0, 0, 1.0);
    }
  }
  timer.SetupDone(&summary);

  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::DENSE_QR;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.num_threads = 1;
  ceres::Solver::Summary ceres_summary;
  ceres::Solve(solver_options, &problem, &ceres_summary);
  summary.iterations = static_cast<int>(ceres_summary.iterations.size());
  if (!ceres_summary.IsSolutionUsable()) {
    summary.End(Termination::kFailure, "the fit failed: " + ceres_summary.message);
    timer.Finish(&summary);
    return summary;
  }
  summary.termination =
      ceres_summary.termination_type == ceres::CONVERGENCE ? Termination::kSuccess : Termination::kNoConvergence;
  summary.cost = 2.0 * ceres_summary.final_cost;  // Ceres reports half the sum of squares
  const double n = static_cast<double>(summary.residuals), k = summary.parameters;
  summary.bic = options.loss == FitLoss::kWeighted ? summary.cost + k * std::log(n)
                                                   : n * std::log(std::max(summary.cost, 1e-300) / n) + k * std::log(n);
  summary.params.diffuse = Eigen::Vector3d(kd[0], kd[1], kd[2]);
  if (model != Model::kLambertian) {
    summary.params.specular = Eigen::Vector3d(lobe[0], lobe[1], lobe[2]);
    summary.params.shape = std::exp(lobe[3]);
    if (model == Model::kCookTorrance) summary.params.fresnel_f0 = f0;
  }

  // Uncertainties: the inverse of J^T J at the solution (DENSE_SVD refuses a
  // rank-deficient Jacobian instead of inventing a variance for it).
  ceres::Covariance::Options covariance_options;
  covariance_options.algorithm_type = ceres::DENSE_SVD;
  ceres::Covariance covariance(covariance_options);
  std::vector<const double*> blocks = {kd};
  if (model != Model::kLambertian) blocks.push_back(lobe);
  if (model == Model::kCookTorrance) blocks.push_back(&f0);
  std::vector<std::pair<const double*, const double*>> pairs;
  for (const double* a : blocks)
    for (const double* b : blocks) pairs.emplace_back(a, b);
  const int p = summary.parameters;
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> cov(p, p);
  if (covariance.Compute(pairs, &problem) && covariance.GetCovarianceMatrix(blocks, cov.data())) {
    // The log loss carries no absolute scale: use the residual variance.
    if (options.loss == FitLoss::kLog) cov *= summary.cost / std::max(1.0, n - k);
    summary.covariance_available = cov.allFinite();
  }
  if (summary.covariance_available) {
    const Eigen::VectorXd sd = cov.diagonal().cwiseMax(0.0).cwiseSqrt();
    summary.diffuse_sigma = sd.head<3>();
    if (model != Model::kLambertian) {
      summary.specular_sigma = sd.segment<3>(3);
      summary.shape_sigma = summary.params.shape * sd[6];  // d shape = shape * d log(shape)
      if (model == Model::kCookTorrance) summary.fresnel_f0_sigma = sd[7];
    }
  }
  if (model != Model::kLambertian) {
    summary.lobe_identifiable =
        summary.covariance_available && summary.shape_sigma <= options.max_relative_shape_sigma * summary.params.shape;
    if (!summary.lobe_identifiable)
      summary.message = std::string("the ") + ModelName(model) +
                        " lobe's shape is not identifiable from these samples (relative sd " +
                        (summary.covariance_available ? std::to_string(summary.shape_sigma / summary.params.shape)
                                                      : std::string("unknown: singular covariance")) +
                        "); sample nearer the specular peak";
  }
  timer.Finish(&summary);
  return summary;
}

SelectionSummary SelectModel(const std::vector<BrdfSample>& samples, const SelectionOptions& options) {
  SolveTimer timer;
  SelectionSummary summary;
  if (std::string why; !options.IsValid(&why)) {
    summary.End(Termination::kInvalidOptions, why);
    return summary;
  }
  if (samples.empty()) {
    summary.End(Termination::kInvalidInput, "no samples");
    return summary;
  }
  double min_theta_h = M_PI;
  for (const BrdfSample& s : samples)
    if (s.wi.allFinite() && s.wo.allFinite() && (s.wi + s.wo).norm() > 0.0)
      min_theta_h = std::min(min_theta_h, std::acos(std::clamp((s.wi + s.wo).normalized().z(), -1.0, 1.0)));
  summary.min_theta_h_deg = min_theta_h * 180.0 / M_PI;
  summary.peak_sampled = summary.min_theta_h_deg < options.peak_theta_h_deg;
  timer.SetupDone(&summary);

  ProgressThrottle progress(options.progress, "fit", static_cast<std::int64_t>(options.candidates.size()));
  for (Model model : options.candidates) {
    summary.candidates.push_back(FitModel(model, samples, options.fit));
    const FitSummary& fit = summary.candidates.back();
    // Input and options are the same for every candidate: the first refusal is everyone's.
    if (fit.termination == Termination::kInvalidInput || fit.termination == Termination::kInvalidOptions) {
      summary.End(fit.termination, fit.message);
      return summary;
    }
    if (options.held_out_folds > 0 && fit.IsSolutionUsable())
      summary.candidates.back().held_out_rms = HeldOutRms(model, samples, options.fit, options.held_out_folds);
    progress.Update(static_cast<std::int64_t>(summary.candidates.size()));
  }
  progress.Finish();
  auto trusted = [](const FitSummary& f) { return f.IsSolutionUsable() && f.lobe_identifiable; };
  std::optional<std::size_t> best;
  for (std::size_t i = 0; i < summary.candidates.size(); ++i)
    if (trusted(summary.candidates[i]) && (!best || summary.candidates[i].bic < summary.candidates[*best].bic)) best = i;
  if (!best) {
    summary.End(Termination::kFailure, "no candidate model gives a usable, identifiable fit to " +
                                           std::to_string(samples.size()) + " samples");
    timer.Finish(&summary);
    return summary;
  }
  // The simplest trusted model within min_bic_improvement of the best.
  std::size_t chosen = *best;
  for (std::size_t i = 0; i < summary.candidates.size(); ++i) {
    const FitSummary& f = summary.candidates[i];
    if (!trusted(f) || f.bic > summary.candidates[*best].bic + options.min_bic_improvement) continue;
    const FitSummary& c = summary.candidates[chosen];
    if (f.parameters < c.parameters || (f.parameters == c.parameters && f.bic < c.bic)) chosen = i;
  }
  summary.chosen = summary.candidates[chosen].params.model;
  summary.chosen_index = chosen;
  for (const FitSummary& f : summary.candidates)
    if (f.IsSolutionUsable() && !f.lobe_identifiable &&
        f.bic < summary.candidates[chosen].bic - options.min_bic_improvement) {
      summary.End(Termination::kFailure, std::string("the samples show a lobe (") + ModelName(f.params.model) +
                                             " fits far better than " + ModelName(*summary.chosen) +
                                             ") but not its width; sample nearer the specular peak (closest theta_h " +
                                             std::to_string(summary.min_theta_h_deg) + " deg)");
      timer.Finish(&summary);
      return summary;
    }
  summary.termination = Termination::kSuccess;
  if (!summary.peak_sampled)
    summary.message = "no sample near the specular peak (closest theta_h " + std::to_string(summary.min_theta_h_deg) +
                      " deg): a lobe narrower than that cannot be ruled out";
  timer.Finish(&summary);
  return summary;
}

}  // namespace photorig::solvers::brdf
