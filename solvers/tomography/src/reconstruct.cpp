#include "photorig/solvers/tomography/reconstruct.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <sstream>

namespace photorig::tomography {

std::optional<Method> ParseMethod(std::string_view name) {
  if (name == "art") return Method::kArt;
  if (name == "sirt") return Method::kSirt;
  if (name == "cgls") return Method::kCgls;
  return std::nullopt;
}

const char* MethodName(Method method) {
  switch (method) {
    case Method::kArt: return "art";
    case Method::kSirt: return "sirt";
    case Method::kCgls: return "cgls";
  }
  return "?";
}

const char* StopReasonName(StopReason reason) {
  switch (reason) {
    case StopReason::kNone: return "none";
    case StopReason::kDiscrepancy: return "discrepancy";
    case StopReason::kMaxIterations: return "max-iterations";
    case StopReason::kStagnation: return "stagnation";
  }
  return "?";
}

bool ReconstructOptions::IsValid(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why) *why = message;
    return false;
  };
  if (max_iterations < 1) return fail("max_iterations must be >= 1");
  if (!(relaxation >= 0) || !std::isfinite(relaxation)) return fail("relaxation must be finite and >= 0 (0: the method's default)");
  if (method == Method::kSirt && relaxation >= 2.0) return fail("SIRT converges only for relaxation in (0, 2)");
  if (method == Method::kArt && relaxation >= 2.0) return fail("ART converges only for relaxation in (0, 2)");
  if (!(discrepancy_factor > 0) || !std::isfinite(discrepancy_factor)) return fail("discrepancy_factor must be > 0");
  if (!(noise_sigma >= 0) || !std::isfinite(noise_sigma)) return fail("noise_sigma must be finite and >= 0");
  if (!(min_rays_per_voxel >= 0) || !std::isfinite(min_rays_per_voxel)) return fail("min_rays_per_voxel must be >= 0");
  if (!(stagnation_tolerance >= 0) || !std::isfinite(stagnation_tolerance))
    return fail("stagnation_tolerance must be finite and >= 0");
  return true;
}

namespace {

double SquaredNorm(const Eigen::VectorXf& v) {
  double sum = 0.0;
  const std::int64_t n = v.size();
#pragma omp parallel for reduction(+ : sum) schedule(static) if (n > 100000)
  for (std::int64_t i = 0; i < n; ++i) sum += static_cast<double>(v[i]) * v[i];
  return sum;
}

// r = mask (b - y): the residual over the valid rays.
void MaskedResidual(const Eigen::VectorXf& b, const Eigen::VectorXf& y, const Eigen::VectorXf& mask, Eigen::VectorXf* r) {
  *r = mask.cwiseProduct(b - y);
}

void ClampNonNegative(Eigen::VectorXf* x) { *x = x->cwiseMax(0.0f); }

// One Kaczmarz sweep: every valid ray once, views in `order`.
void ArtSweep(const Projector& projector, const Eigen::VectorXf& b, const Eigen::VectorXf& mask,
              const std::vector<int>& order, double lambda, bool non_negative, Eigen::VectorXf* x) {
  const std::int64_t per_view = projector.geometry().pixels_per_view();
  std::vector<RayWeight> weights;
  float* xs = x->data();
  for (int view : order)
    for (std::int64_t p = 0; p < per_view; ++p) {
      const std::int64_t ray = view * per_view + p;
      if (mask[ray] == 0.0f) continue;
      projector.Row(ray, &weights);
      double dot = 0.0, norm2 = 0.0;
      for (const RayWeight& w : weights) {
        dot += static_cast<double>(w.weight_mm) * xs[w.voxel];
        norm2 += static_cast<double>(w.weight_mm) * w.weight_mm;
      }
      if (norm2 <= 0.0) continue;
      const auto c = static_cast<float>(lambda * (b[ray] - dot) / norm2);
      for (const RayWeight& w : weights) {
        float& v = xs[w.voxel];
        v += c * w.weight_mm;
        if (non_negative && v < 0.0f) v = 0.0f;
      }
    }
}

std::string Format(double value) {
  std::ostringstream out;
  out.precision(3);
  out << value;
  return out.str();
}

}  // namespace

ReconstructionSummary Reconstruct(const SystemMatrix& projector, const Absorbance& measurements,
                                  const ReconstructOptions& options, Eigen::VectorXf* sigma) {
  solvers::SolveTimer timer;
  ReconstructionSummary summary;
  summary.method = options.method;
  auto end = [&](solvers::Termination how, std::string why) {
    summary.End(how, std::move(why));
    timer.Finish(&summary);
    return summary;
  };
  std::string why;
  if (!options.IsValid(&why)) return end(solvers::Termination::kInvalidOptions, why);
  if (!sigma) return end(solvers::Termination::kInvalidInput, "no output volume given");
  const auto* whole = dynamic_cast<const Projector*>(&projector);
  if (options.method == Method::kArt && !whole)
    return end(solvers::Termination::kInvalidOptions,
               "ART visits one ray at a time and needs every row of W in one process; use SIRT or CGLS");
  // Sums over rays cover the whole scan, whatever part of it this process holds.
  auto ray_sum = [&projector](double held_here) { return projector.SumOverRays(held_here); };
  const std::int64_t rays = projector.rays(), voxels = projector.voxels();
  if (measurements.b.size() != rays)
    return end(solvers::Termination::kInvalidInput,
               "b has " + std::to_string(measurements.b.size()) + " entries; the scan has " + std::to_string(rays) + " rays");
  if (!measurements.valid.empty() && static_cast<std::int64_t>(measurements.valid.size()) != rays)
    return end(solvers::Termination::kInvalidInput, "the validity flags do not match the rays");
  if (measurements.variance.size() != 0 && measurements.variance.size() != rays)
    return end(solvers::Termination::kInvalidInput, "the variances do not match the rays");

  Eigen::VectorXf mask(rays), b(rays);
  for (std::int64_t i = 0; i < rays; ++i) {
    const bool valid = measurements.valid.empty() || measurements.valid[static_cast<std::size_t>(i)] != 0;
    if (valid && !std::isfinite(measurements.b[i]))
      return end(solvers::Termination::kInvalidInput, "b holds a non-finite value on a ray marked valid");
    mask[i] = valid ? 1.0f : 0.0f;
    b[i] = valid ? measurements.b[i] : 0.0f;
    summary.rays_used += valid;
  }
  summary.rays_used = static_cast<std::int64_t>(ray_sum(static_cast<double>(summary.rays_used)));
  if (summary.rays_used == 0)
    return end(solvers::Termination::kFailure, "no valid ray: every pixel was flagged (see the absorbance summary)");

  // Row sums over all voxels, column sums over the valid rays.
  Eigen::VectorXf row_sums, column_sums;
  projector.Forward(Eigen::VectorXf::Ones(voxels), &row_sums);
  projector.Back(mask, &column_sums);
  // Counts over the whole volume, whatever part of it this process holds.
  std::int64_t reached_here = 0;
  for (std::int64_t j = 0; j < voxels; ++j) reached_here += column_sums[j] > 0.0f;
  summary.voxels_reached = static_cast<std::int64_t>(projector.SumOverVoxels(static_cast<double>(reached_here)));
  summary.voxels_unreached =
      static_cast<std::int64_t>(projector.SumOverVoxels(static_cast<double>(voxels))) - summary.voxels_reached;
  if (summary.voxels_reached == 0)
    return end(solvers::Termination::kFailure, "no valid ray crosses the volume: check the grid against the geometry");
  summary.underdetermined = summary.rays_used < summary.voxels_reached;
  const double rays_per_voxel = static_cast<double>(summary.rays_used) / static_cast<double>(summary.voxels_reached);
  if (rays_per_voxel < options.min_rays_per_voxel) {
    const int views = projector.views();
    const int needed = static_cast<int>(std::ceil(views * options.min_rays_per_voxel / rays_per_voxel));
    return end(solvers::Termination::kFailure,
               "too few views for the volume: " + std::to_string(summary.rays_used) + " valid rays for " +
                   std::to_string(summary.voxels_reached) + " voxels (" + Format(rays_per_voxel) +
                   " per voxel, below " + Format(options.min_rays_per_voxel) + "); take about " +
                   std::to_string(needed) + " views or coarsen the grid");
  }

  // The noise level the discrepancy rule stops at.
  double noise_sum = 0.0;
  if (measurements.variance.size() == rays) {
    for (std::int64_t i = 0; i < rays; ++i)
      if (mask[i] != 0.0f) noise_sum += measurements.variance[i];
  } else if (options.noise_sigma > 0.0) {
    noise_sum = static_cast<double>(summary.rays_used) * options.noise_sigma * options.noise_sigma;
  }
  if (measurements.variance.size() == rays) noise_sum = ray_sum(noise_sum);
  const bool have_noise = noise_sum > 0.0;
  summary.discrepancy_target = options.discrepancy_factor * std::sqrt(noise_sum);
  if (options.stop_rule == StopRule::kDiscrepancy && !have_noise)
    return end(solvers::Termination::kInvalidInput,
               "the discrepancy rule needs a noise estimate: two or more flats and darks, or noise_sigma; "
               "or stop after max_iterations");
  // |b|^2 of pure noise is chi-square with rays_used degrees of freedom: more
  // than three of its standard deviations above its mean is a signal.
  const double b_norm = std::sqrt(ray_sum(SquaredNorm(b)));
  const double noise_ceiling = noise_sum * (1.0 + 3.0 * std::sqrt(2.0 / static_cast<double>(summary.rays_used)));
  if (have_noise ? b_norm * b_norm <= noise_ceiling : b_norm == 0.0)
    return end(solvers::Termination::kFailure,
               "no signal: |b| = " + Format(b_norm) + " is within the noise (" + Format(std::sqrt(noise_sum)) +
                   "); the sample absorbs too little, or the flats do not match the frames");

  if (sigma->size() != voxels) sigma->setZero(voxels);
  Eigen::VectorXf& x = *sigma;
  const double lambda =
      options.relaxation > 0.0 ? options.relaxation : (options.method == Method::kArt ? 0.25 : 1.9);
  summary.relaxation = options.method == Method::kCgls ? 0.0 : lambda;
  const bool non_negative = options.non_negative && options.method != Method::kCgls;
  if (non_negative) ClampNonNegative(&x);

  Eigen::VectorXf wx, r, g;
  projector.Forward(x, &wx);
  MaskedResidual(b, wx, mask, &r);
  summary.residual_history.push_back(std::sqrt(ray_sum(SquaredNorm(r))));
  timer.SetupDone(&summary);

  // Method state.
  Eigen::VectorXf inv_rows, inv_columns;  // SIRT
  Eigen::VectorXf s, p, q;                // CGLS
  double gamma = 0.0, gamma_floor = 0.0;  // |W^T r|^2 now, and where float precision ends
  std::vector<int> order(static_cast<std::size_t>(projector.views()));  // ART
  if (options.method == Method::kSirt) {
    inv_rows = row_sums.unaryExpr([](float v) { return v > 0.0f ? 1.0f / v : 0.0f; });
    inv_columns = column_sums.unaryExpr([](float v) { return v > 0.0f ? 1.0f / v : 0.0f; });
  } else if (options.method == Method::kCgls) {
    projector.Back(r, &s);
    p = s;
    gamma = projector.SumOverVoxels(SquaredNorm(s));
    gamma_floor = gamma * 1e-12;
  } else {
    // Views in a shuffled order: consecutive updates from nearby angles are
    // nearly parallel hyperplanes and make slow progress.
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), std::mt19937(27));
  }

  solvers::ProgressThrottle throttle(options.progress, MethodName(options.method), options.max_iterations);
  summary.stop_reason = StopReason::kMaxIterations;
  int flat_steps = 0;
  for (int iteration = 1; iteration <= options.max_iterations; ++iteration) {
    if (options.method == Method::kArt) {
      ArtSweep(*whole, b, mask, order, lambda, non_negative, &x);
      projector.Forward(x, &wx);
      MaskedResidual(b, wx, mask, &r);
    } else if (options.method == Method::kSirt) {
      projector.Back(r.cwiseProduct(inv_rows), &g);
      x += static_cast<float>(lambda) * inv_columns.cwiseProduct(g);
      if (non_negative) ClampNonNegative(&x);
      projector.Forward(x, &wx);
      MaskedResidual(b, wx, mask, &r);
    } else {
      projector.Forward(p, &q);
      q = q.cwiseProduct(mask);
      const double delta = ray_sum(SquaredNorm(q));
      // At the least-squares point (|W^T r| down by 1e6, float precision) a
      // further step divides rounding noise by rounding noise.
      if (delta <= 0.0 || gamma <= gamma_floor) {
        summary.stop_reason = StopReason::kStagnation;
        break;
      }
      const auto alpha = static_cast<float>(gamma / delta);
      x += alpha * p;
      r -= alpha * q;
      projector.Back(r, &s);
      const double gamma_next = projector.SumOverVoxels(SquaredNorm(s));
      p = s + static_cast<float>(gamma_next / gamma) * p;
      gamma = gamma_next;
    }
    const double residual = std::sqrt(ray_sum(SquaredNorm(r)));
    const double previous = summary.residual_history.back();
    summary.residual_history.push_back(residual);
    summary.iterations = iteration;
    if (options.on_iteration) options.on_iteration(iteration, x);
    throttle.Update(iteration);
    if (options.stop_rule == StopRule::kDiscrepancy && residual <= summary.discrepancy_target) {
      summary.stop_reason = StopReason::kDiscrepancy;
      break;
    }
    // Three iterations in a row that barely lower the residual: it has stalled.
    flat_steps = previous - residual < options.stagnation_tolerance * previous ? flat_steps + 1 : 0;
    if (options.stagnation_tolerance > 0.0 && flat_steps >= 3) {
      summary.stop_reason = StopReason::kStagnation;
      break;
    }
  }
  throttle.Finish();
  for (std::int64_t j = 0; j < voxels; ++j)
    if (column_sums[j] <= 0.0f) x[j] = 0.0f;

  const double final_residual = summary.residual_history.back();
  summary.inconsistent =
      have_noise && summary.stop_reason == StopReason::kStagnation && final_residual > 1.5 * std::sqrt(noise_sum);
  std::string notes;
  if (summary.underdetermined)
    notes += "; underdetermined (" + std::to_string(summary.rays_used) + " rays for " +
             std::to_string(summary.voxels_reached) + " voxels): the stopping rule and non-negativity carry it";
  if (summary.voxels_unreached > 0)
    notes += "; " + std::to_string(summary.voxels_unreached) + " voxels no valid ray reaches, left at 0";
  timer.Finish(&summary);
  if (summary.inconsistent) {
    summary.termination = solvers::Termination::kNoConvergence;
    summary.message = "inconsistent data: the residual stalls at " + Format(final_residual / std::sqrt(noise_sum)) +
                      " times the noise level; check the centre of rotation, the flats and the geometry" + notes;
  } else if (summary.stop_reason == StopReason::kMaxIterations && options.stop_rule == StopRule::kDiscrepancy) {
    summary.termination = solvers::Termination::kNoConvergence;
    summary.message = "the residual " + Format(final_residual) + " is still above the noise level " +
                      Format(summary.discrepancy_target) + " after " + std::to_string(summary.iterations) +
                      " iterations; raise max_iterations" + notes;
  } else {
    summary.termination = solvers::Termination::kSuccess;
    summary.message = notes.empty() ? std::string() : notes.substr(2);
  }
  return summary;
}

}  // namespace photorig::tomography
