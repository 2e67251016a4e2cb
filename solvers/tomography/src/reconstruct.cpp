#include "photorig/solvers/tomography/reconstruct.h"

#include "iteration.h"
#include "photorig/solvers/core/names.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <sstream>

namespace photorig::solvers::tomography {

namespace {

constexpr core::NameTable<StopReason, 5> kStopReasonNames = {{
    {StopReason::kNone, "none"}, {StopReason::kDiscrepancy, "discrepancy"}, {StopReason::kMaxIterations, "max-iterations"},
    {StopReason::kStagnation, "stagnation"}, {StopReason::kLimitCycle, "limit-cycle"},
}};

}  // namespace

const char* StopReasonName(StopReason reason) { return core::NameOf(kStopReasonNames, reason); }

bool ReconstructOptions::IsValid(std::string* why) const {
  if (max_iterations < 1) return core::Refuse(why, "max_iterations must be >= 1");
  if (!(relaxation >= 0) || !std::isfinite(relaxation)) return core::Refuse(why, "relaxation must be finite and >= 0 (0: the method's default)");
  if (method == Method::kSirt && relaxation >= 2.0) return core::Refuse(why, "SIRT converges only for relaxation in (0, 2)");
  if (method == Method::kArt && relaxation >= 2.0) return core::Refuse(why, "ART converges only for relaxation in (0, 2)");
  if (method == Method::kSart && relaxation >= 2.0) return core::Refuse(why, "SART converges only for relaxation in (0, 2)");
  if (total_variation && method != Method::kSart) return core::Refuse(why, "total_variation is implemented for SART only");
  if (!(tv_strength >= 0) || !std::isfinite(tv_strength)) return core::Refuse(why, "tv_strength must be finite and >= 0");
  if (tv_steps < 1) return core::Refuse(why, "tv_steps must be >= 1");
  if (!(discrepancy_factor > 0) || !std::isfinite(discrepancy_factor)) return core::Refuse(why, "discrepancy_factor must be > 0");
  if (!(noise_sigma >= 0) || !std::isfinite(noise_sigma)) return core::Refuse(why, "noise_sigma must be finite and >= 0");
  if (!(min_rays_per_voxel >= 0) || !std::isfinite(min_rays_per_voxel)) return core::Refuse(why, "min_rays_per_voxel must be >= 0");
  if (!(stagnation_tolerance >= 0) || !std::isfinite(stagnation_tolerance))
    return core::Refuse(why, "stagnation_tolerance must be finite and >= 0");
  return true;
}
namespace internal {

double SquaredNorm(const Eigen::VectorXf& v) {
  double sum = 0.0;
  const std::int64_t n = v.size();
#pragma omp parallel for reduction(+ : sum) schedule(static) if (n > 100000)
  for (std::int64_t i = 0; i < n; ++i) sum += static_cast<double>(v[i]) * v[i];
  return sum;
}

void MaskedResidual(const Eigen::VectorXf& b, const Eigen::VectorXf& y, const Eigen::VectorXf& mask, Eigen::VectorXf* r) {
  *r = mask.cwiseProduct(b - y);
}

void ClampNonNegative(Eigen::VectorXf* x) { *x = x->cwiseMax(0.0f); }

Eigen::VectorXf Reciprocals(const Eigen::VectorXf& sums) {
  return sums.unaryExpr([](float v) { return v > 0.0f ? 1.0f / v : 0.0f; });
}

}  // namespace internal

namespace {

using internal::SquaredNorm;

// SART's default relaxation (see ReconstructOptions::relaxation).
constexpr double kSartRelaxation = 0.25;

// How the progress report's last line says why the iterations stopped early.
const char* StopPhrase(StopReason reason) {
  switch (reason) {
    case StopReason::kDiscrepancy: return "residual at the noise level";
    case StopReason::kStagnation: return "converged";
    case StopReason::kLimitCycle: return "limit cycle";
    case StopReason::kNone:
    case StopReason::kMaxIterations: break;
  }
  return "stopped";
}

std::string Format(double value) {
  std::ostringstream out;
  out.precision(3);
  out << value;
  return out.str();
}


// The measurements on the valid rays (0 elsewhere) and the rays' mask.
struct ValidRays {
  Eigen::VectorXf b, mask;
};

// Fails, ending *summary, where the measurements do not match the system's
// rays or no ray is valid.
bool ReadValidRays(const SystemMatrix& system, const Absorbance& measurements, ValidRays* valid,
                   ReconstructionSummary* summary) {
  const std::int64_t rays = system.rays();
  auto fail = [summary](solvers::core::Termination how, std::string why) {
    summary->End(how, std::move(why));
    return false;
  };
  if (measurements.b.size() != rays)
    return fail(solvers::core::Termination::kInvalidInput, "b has " + std::to_string(measurements.b.size()) +
                                                          " entries; the scan has " + std::to_string(rays) + " rays");
  if (!measurements.valid.empty() && static_cast<std::int64_t>(measurements.valid.size()) != rays)
    return fail(solvers::core::Termination::kInvalidInput, "the validity flags do not match the rays");
  if (measurements.variance.size() != 0 && measurements.variance.size() != rays)
    return fail(solvers::core::Termination::kInvalidInput, "the variances do not match the rays");
  valid->mask.resize(rays);
  valid->b.resize(rays);
  for (std::int64_t i = 0; i < rays; ++i) {
    const bool is_valid = measurements.valid.empty() || measurements.valid[static_cast<std::size_t>(i)] != 0;
    if (is_valid && !std::isfinite(measurements.b[i]))
      return fail(solvers::core::Termination::kInvalidInput, "b holds a non-finite value on a ray marked valid");
    valid->mask[i] = is_valid ? 1.0f : 0.0f;
    valid->b[i] = is_valid ? measurements.b[i] : 0.0f;
    summary->rays_used += is_valid;
  }
  // Sums over rays cover the whole scan, whatever part of it this process holds.
  summary->rays_used = static_cast<std::int64_t>(system.SumOverRays(static_cast<double>(summary->rays_used)));
  if (summary->rays_used == 0)
    return fail(solvers::core::Termination::kFailure, "no valid ray: every pixel was flagged (see the absorbance summary)");
  return true;
}

// W's row sums over all voxels and column sums over the valid rays. Fails,
// ending *summary, where no valid ray crosses the volume or too few do for its voxels.
bool CheckCoverage(const SystemMatrix& system, const ReconstructOptions& options, const Eigen::VectorXf& mask,
                   Eigen::VectorXf* row_sums, Eigen::VectorXf* column_sums, ReconstructionSummary* summary) {
  const std::int64_t voxels = system.voxels();
  system.Forward(Eigen::VectorXf::Ones(voxels), row_sums);
  system.Back(mask, column_sums);
  // Counts over the whole volume, whatever part of it this process holds.
  std::int64_t reached_here = 0;
  for (std::int64_t j = 0; j < voxels; ++j) reached_here += (*column_sums)[j] > 0.0f;
  summary->voxels_reached = static_cast<std::int64_t>(system.SumOverVoxels(static_cast<double>(reached_here)));
  summary->voxels_unreached =
      static_cast<std::int64_t>(system.SumOverVoxels(static_cast<double>(voxels))) - summary->voxels_reached;
  if (summary->voxels_reached == 0) {
    summary->End(solvers::core::Termination::kFailure,
                 "no valid ray crosses the volume: check the grid against the geometry");
    return false;
  }
  summary->underdetermined = summary->rays_used < summary->voxels_reached;
  const double rays_per_voxel = static_cast<double>(summary->rays_used) / static_cast<double>(summary->voxels_reached);
  if (rays_per_voxel < options.min_rays_per_voxel) {
    const int views = system.views();
    const int needed = static_cast<int>(std::ceil(views * options.min_rays_per_voxel / rays_per_voxel));
    summary->End(solvers::core::Termination::kFailure,
                 "too few views for the volume: " + std::to_string(summary->rays_used) + " valid rays for " +
                     std::to_string(summary->voxels_reached) + " voxels (" + Format(rays_per_voxel) +
                     " per voxel, below " + Format(options.min_rays_per_voxel) + "); take about " +
                     std::to_string(needed) + " views or coarsen the grid");
    return false;
  }
  return true;
}

// *noise_sum: sum var(b) over the valid rays, the noise level the
// discrepancy rule stops at (0: none known). Fails, ending *summary, where
// the rule needs one and none is known, or where b lies within it.
bool MeasureNoise(const SystemMatrix& system, const Absorbance& measurements, const ReconstructOptions& options,
                  const ValidRays& valid, double* noise_sum, ReconstructionSummary* summary) {
  const std::int64_t rays = system.rays();
  *noise_sum = 0.0;
  if (measurements.variance.size() == rays) {
    for (std::int64_t i = 0; i < rays; ++i)
      if (valid.mask[i] != 0.0f) *noise_sum += measurements.variance[i];
  } else if (options.noise_sigma > 0.0) {
    *noise_sum = static_cast<double>(summary->rays_used) * options.noise_sigma * options.noise_sigma;
  }
  if (measurements.variance.size() == rays) *noise_sum = system.SumOverRays(*noise_sum);
  const bool have_noise = *noise_sum > 0.0;
  summary->discrepancy_target = options.discrepancy_factor * std::sqrt(*noise_sum);
  if (options.stop_rule == StopRule::kDiscrepancy && !have_noise) {
    summary->End(solvers::core::Termination::kInvalidInput,
                 "the discrepancy rule needs a noise estimate: two or more flats and darks, or noise_sigma; "
                 "or stop after max_iterations");
    return false;
  }
  // |b|^2 of pure noise is chi-square with rays_used degrees of freedom: more
  // than three of its standard deviations above its mean is a signal.
  const double b_norm = std::sqrt(system.SumOverRays(SquaredNorm(valid.b)));
  const double noise_ceiling = *noise_sum * (1.0 + 3.0 * std::sqrt(2.0 / static_cast<double>(summary->rays_used)));
  if (have_noise ? b_norm * b_norm <= noise_ceiling : b_norm == 0.0) {
    summary->End(solvers::core::Termination::kFailure,
                 "no signal: |b| = " + Format(b_norm) + " is within the noise (" + Format(std::sqrt(*noise_sum)) +
                     "); the sample absorbs too little, or the flats do not match the frames");
    return false;
  }
  return true;
}

std::unique_ptr<internal::Iteration> MakeMethod(const internal::IterationInputs& in, const Eigen::VectorXf& r) {
  if (in.options.method == Method::kSirt) return internal::MakeSirt(in);
  if (in.options.method == Method::kCgls) return internal::MakeCgls(in, r);
  if (in.options.method == Method::kSart) return internal::MakeSart(in);
  return internal::MakeArt(in);
}

// SART with TV approaches a balance between the data step and the TV step
// tied to it, whose residual stays above the noise level by what TV holds
// back, so the discrepancy rule may never act while each pass fits more
// noise. A pass that lowers the residual by less than the noise's own
// scatter in it (||noise|| has a standard deviation of
// sqrt(sum var(b) / (2 rays))) makes a change the data cannot resolve:
// three in a row are the balance, converged (kStagnation), and trusted if
// the residual is within 1.5 x the noise level like any stalled iteration.
// 0 where no such balance is sought.
double ResolvableDrop(const ReconstructOptions& options, const ReconstructionSummary& summary, double noise_sum) {
  const bool have_noise = noise_sum > 0.0;
  return summary.tv_strength > 0.0 && have_noise && options.stop_rule == StopRule::kDiscrepancy &&
                 options.stagnation_tolerance > 0.0
             ? std::sqrt(noise_sum / (2.0 * static_cast<double>(summary.rays_used)))
             : 0.0;
}

// The iterations, until a stopping rule or max_iterations ends them: the
// summary's residual_history, iterations and stop_reason. Returns whether
// the last residual recorded is the one SART met during its pass rather
// than the exact one.
bool Iterate(const ReconstructOptions& options, const SystemMatrix& system, double resolvable_drop,
             internal::Iteration* method, Eigen::VectorXf* x, Eigen::VectorXf* r, ReconstructionSummary* summary) {
  solvers::core::ProgressThrottle throttle(options.progress, MethodName(options.method), options.max_iterations);
  summary->stop_reason = StopReason::kMaxIterations;
  // A fixed relaxation keeps ART's and SART's updates from shrinking to zero.
  const bool row_action = options.method == Method::kArt || options.method == Method::kSart;
  int flat_steps = 0;
  double residual_met = -1.0;
  for (int iteration = 1; iteration <= options.max_iterations; ++iteration) {
    const internal::StepResult step = method->Step(x, r);
    residual_met = step.residual_met;
    if (step.converged) {
      summary->stop_reason = StopReason::kStagnation;
      break;
    }
    const double residual = residual_met >= 0.0 ? residual_met : std::sqrt(system.SumOverRays(SquaredNorm(*r)));
    const double previous = summary->residual_history.back();
    summary->residual_history.push_back(residual);
    summary->iterations = iteration;
    if (options.on_iteration) options.on_iteration(iteration, *x);
    throttle.Update(iteration);
    if (options.stop_rule == StopRule::kDiscrepancy && residual <= summary->discrepancy_target) {
      summary->stop_reason = StopReason::kDiscrepancy;
      break;
    }
    // Three iterations in a row that barely lower the residual: it has stalled.
    const double flat_drop = std::max(options.stagnation_tolerance * previous, resolvable_drop);
    flat_steps = previous - residual < flat_drop ? flat_steps + 1 : 0;
    if (options.stagnation_tolerance > 0.0 && flat_steps >= 3) {
      summary->stop_reason = row_action && resolvable_drop == 0.0 ? StopReason::kLimitCycle : StopReason::kStagnation;
      break;
    }
  }
  if (summary->stop_reason == StopReason::kMaxIterations)
    throttle.Finish();
  else
    throttle.StoppedAt(summary->iterations, StopPhrase(summary->stop_reason));
  return residual_met >= 0.0;
}

// The termination and its message from how the iterations ended: success,
// or why the volume is not to be trusted.
void Conclude(const ReconstructOptions& options, double noise_sum, double resolvable_drop,
              ReconstructionSummary* summary) {
  const bool have_noise = noise_sum > 0.0;
  const double final_residual = summary->residual_history.back();
  const bool stalled =
      summary->stop_reason == StopReason::kStagnation || summary->stop_reason == StopReason::kLimitCycle;
  summary->inconsistent = have_noise && stalled && final_residual > 1.5 * std::sqrt(noise_sum);
  std::string notes;
  if (summary->underdetermined)
    notes += "; underdetermined (" + std::to_string(summary->rays_used) + " rays for " +
             std::to_string(summary->voxels_reached) + " voxels): the stopping rule and non-negativity carry it";
  if (summary->voxels_unreached > 0)
    notes += "; " + std::to_string(summary->voxels_unreached) + " voxels no valid ray reaches, left at 0";
  if (summary->stop_reason == StopReason::kLimitCycle &&
      !(have_noise && final_residual <= summary->discrepancy_target)) {
    // Where the cycle settles depends on the relaxation and the order, not on the data.
    summary->termination = solvers::core::Termination::kFailure;
    summary->message = std::string(MethodName(options.method)) + " ended in a limit cycle: the residual stopped at " +
                       (have_noise ? Format(final_residual / std::sqrt(noise_sum)) + " times the noise level"
                                   : Format(final_residual) + " with no noise level to judge it by") +
                       " after " + std::to_string(summary->iterations) +
                       " passes; the volume is not usable: lower the relaxation or use SIRT" +
                       (summary->inconsistent ? "; the data may be inconsistent: check the centre of rotation, the "
                                               "flats and the geometry"
                                             : "") +
                       notes;
  } else if (summary->inconsistent) {
    summary->termination = solvers::core::Termination::kNoConvergence;
    summary->message = "inconsistent data: the residual stalls at " + Format(final_residual / std::sqrt(noise_sum)) +
                       " times the noise level; check the centre of rotation, the flats and the geometry" + notes;
  } else if (summary->stop_reason == StopReason::kMaxIterations && options.stop_rule == StopRule::kDiscrepancy) {
    summary->termination = solvers::core::Termination::kNoConvergence;
    summary->message = "the residual " + Format(final_residual) + " is still above the noise level " +
                       Format(summary->discrepancy_target) + " after " + std::to_string(summary->iterations) +
                       " iterations; raise " + options.iteration_limit_name + notes;
  } else {
    summary->termination = solvers::core::Termination::kSuccess;
    if (resolvable_drop > 0.0 && summary->stop_reason == StopReason::kStagnation)
      notes = "; total variation holds the residual at " + Format(final_residual / std::sqrt(noise_sum)) +
              " times the noise level: stopped at its balance, where a pass lowers it by less than the noise "
              "resolves (" + Format(resolvable_drop) + ")" + notes;
    summary->message = notes.empty() ? std::string() : notes.substr(2);
  }
}

}  // namespace

ReconstructionSummary Reconstruct(const SystemMatrix& projector, const Absorbance& measurements,
                                  const ReconstructOptions& options, Eigen::VectorXf* sigma) {
  solvers::core::SolveTimer timer;
  ReconstructionSummary summary;
  summary.method = options.method;
  std::string why;
  if (!options.IsValid(&why)) return timer.End(&summary, solvers::core::Termination::kInvalidOptions, why);
  if (!sigma) return timer.End(&summary, solvers::core::Termination::kInvalidInput, "no output volume given");
  const auto* whole = dynamic_cast<const Projector*>(&projector);
  if ((options.method == Method::kArt || options.method == Method::kSart) && !whole)
    return timer.End(&summary, solvers::core::Termination::kInvalidOptions,
                               std::string(options.method == Method::kArt ? "ART visits one ray" : "SART visits one view") +
                                   " at a time and needs every row of W in one process; use SIRT or CGLS");
  ValidRays valid;
  Eigen::VectorXf row_sums, column_sums;
  double noise_sum = 0.0;
  if (!ReadValidRays(projector, measurements, &valid, &summary) ||
      !CheckCoverage(projector, options, valid.mask, &row_sums, &column_sums, &summary) ||
      !MeasureNoise(projector, measurements, options, valid, &noise_sum, &summary)) {
    timer.Finish(&summary);
    return summary;
  }

  const std::int64_t voxels = projector.voxels();
  if (sigma->size() != voxels) sigma->setZero(voxels);
  Eigen::VectorXf& x = *sigma;
  const double lambda = options.relaxation > 0.0             ? options.relaxation
                        : options.method == Method::kArt  ? 0.25
                        : options.method == Method::kSart ? kSartRelaxation
                                                          : 1.9;
  summary.relaxation = options.method == Method::kCgls ? 0.0 : lambda;
  summary.tv_strength = options.total_variation ? options.tv_strength : 0.0;
  const bool non_negative = options.non_negative && options.method != Method::kCgls;
  if (non_negative) internal::ClampNonNegative(&x);

  Eigen::VectorXf wx, r;
  projector.Forward(x, &wx);
  internal::MaskedResidual(valid.b, wx, valid.mask, &r);
  summary.residual_history.push_back(std::sqrt(projector.SumOverRays(SquaredNorm(r))));
  timer.SetupDone(&summary);

  const internal::IterationInputs inputs{projector, whole,       valid.b, valid.mask, row_sums, column_sums,
                                         lambda,    non_negative, options, summary.discrepancy_target,
                                         summary.tv_strength, &wx};
  const std::unique_ptr<internal::Iteration> method = MakeMethod(inputs, r);
  const double resolvable_drop = ResolvableDrop(options, summary, noise_sum);
  const bool residual_met = Iterate(options, projector, resolvable_drop, method.get(), &x, &r, &summary);
  for (std::int64_t j = 0; j < voxels; ++j)
    if (column_sums[j] <= 0.0f) x[j] = 0.0f;
  if (residual_met) {  // the last entry was SART's estimate: the result's own residual instead
    projector.Forward(x, &wx);
    internal::MaskedResidual(valid.b, wx, valid.mask, &r);
    summary.residual_history.back() = std::sqrt(projector.SumOverRays(SquaredNorm(r)));
  }
  timer.Finish(&summary);
  Conclude(options, noise_sum, resolvable_drop, &summary);
  return summary;
}

}  // namespace photorig::solvers::tomography
