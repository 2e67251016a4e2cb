#include "photorig/solvers/tomography/reconstruct.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <random>
#include <sstream>

namespace photorig::tomography {

std::optional<Method> ParseMethod(std::string_view name) {
  if (name == "art") return Method::kArt;
  if (name == "sirt") return Method::kSirt;
  if (name == "cgls") return Method::kCgls;
  if (name == "sart") return Method::kSart;
  return std::nullopt;
}

const char* MethodName(Method method) {
  switch (method) {
    case Method::kArt: return "art";
    case Method::kSirt: return "sirt";
    case Method::kCgls: return "cgls";
    case Method::kSart: return "sart";
  }
  return "?";
}

const char* StopReasonName(StopReason reason) {
  switch (reason) {
    case StopReason::kNone: return "none";
    case StopReason::kDiscrepancy: return "discrepancy";
    case StopReason::kMaxIterations: return "max-iterations";
    case StopReason::kStagnation: return "stagnation";
    case StopReason::kLimitCycle: return "limit-cycle";
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
  if (method == Method::kSart && relaxation >= 2.0) return fail("SART converges only for relaxation in (0, 2)");
  if (total_variation && method != Method::kSart) return fail("total_variation is implemented for SART only");
  if (!(tv_strength >= 0) || !std::isfinite(tv_strength)) return fail("tv_strength must be finite and >= 0");
  if (tv_steps < 1) return fail("tv_steps must be >= 1");
  if (!(discrepancy_factor > 0) || !std::isfinite(discrepancy_factor)) return fail("discrepancy_factor must be > 0");
  if (!(noise_sigma >= 0) || !std::isfinite(noise_sigma)) return fail("noise_sigma must be finite and >= 0");
  if (!(min_rays_per_voxel >= 0) || !std::isfinite(min_rays_per_voxel)) return fail("min_rays_per_voxel must be >= 0");
  if (!(stagnation_tolerance >= 0) || !std::isfinite(stagnation_tolerance))
    return fail("stagnation_tolerance must be finite and >= 0");
  return true;
}

namespace {

// SART's default relaxation (see ReconstructOptions::relaxation).
constexpr double kSartRelaxation = 0.25;
// SART checks its exact residual once the residual its views met comes within
// this factor of the discrepancy target (the two differ by a few percent).
constexpr double kExactResidualMargin = 1.25;
// Stands in for a zero column sum, whose back projection is zero too.
constexpr float kTinyWeight = 1e-30f;

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

// What ordered-subsets SART keeps between passes: the views' order, the
// span of voxels each view reaches (its update touches only those), and a
// scratch volume of (back projection, column sum) pairs, interleaved so that
// a ray's scatter touches one cache line per voxel, zero between views.
struct SartState {
  std::vector<int> order;
  std::vector<std::pair<std::int32_t, std::int32_t>> span;  // per view: first and last voxel reached
  std::vector<float> scratch;                                // 2 per voxel
};

// One ordered-subsets SART pass, a subset being a view: each view's rays
// simultaneously, sigma += lambda C_v W_v^T R_v (b_v - W_v sigma), then
// sigma >= 0, with R the inverse row sums and C_v the inverse column sums
// over the view's valid rays (summed as the rows are visited). Returns the
// squared residual each view's rays had as the pass reached them.
double SartPass(const Projector& projector, const Eigen::VectorXf& b, const Eigen::VectorXf& mask,
                const Eigen::VectorXf& inv_rows, double lambda, bool non_negative, SartState* state,
                Eigen::VectorXf* x) {
  double residual_squared = 0.0;
  float* xs = x->data();
  float* gc = state->scratch.data();
  const auto relaxation = static_cast<float>(lambda);
  for (int view : state->order) {
    const auto [first, last] = state->span[static_cast<std::size_t>(view)];
    if (last < first) continue;
    projector.VisitViewRows(view, [&](std::int64_t ray, const std::int32_t* voxel, const float* w, std::int32_t n) {
      if (mask[ray] == 0.0f) return;
      float dot = 0.0f;
      for (std::int32_t k = 0; k < n; ++k) dot += w[k] * xs[voxel[k]];
      residual_squared += static_cast<double>(b[ray] - dot) * (b[ray] - dot);
      const float residual = (b[ray] - dot) * inv_rows[ray];
      for (std::int32_t k = 0; k < n; ++k) {
        float* pair = gc + 2 * static_cast<std::int64_t>(voxel[k]);
        pair[0] += w[k] * residual;
        pair[1] += w[k];
      }
    });
    // Branch-free, so that it vectorises: where the view adds no weight, the
    // back projection is 0 too and the voxel keeps its value.
    for (std::int64_t j = first; j <= last; ++j) {
      const float v = xs[j] + relaxation * gc[2 * j] / std::max(gc[2 * j + 1], kTinyWeight);
      xs[j] = non_negative ? std::max(v, 0.0f) : v;
    }
    std::fill(gc + 2 * static_cast<std::int64_t>(first), gc + 2 * (static_cast<std::int64_t>(last) + 1), 0.0f);
  }
  return residual_squared;
}

// Views in a spread-out order: sorted by angle (modulo the half turn that
// repeats a parallel view), then visited in bit-reversed order, so that
// consecutive subsets see the sample from far-apart directions (Herman &
// Meyer 1993); neighbouring views nearly repeat each other's correction.
std::vector<int> SpreadViewOrder(const Geometry& geometry) {
  const int views = geometry.views();
  const double period = geometry.beam == Beam::kParallel ? std::numbers::pi : 2.0 * std::numbers::pi;
  std::vector<int> by_angle(static_cast<std::size_t>(views));
  std::iota(by_angle.begin(), by_angle.end(), 0);
  auto wrapped = [&](int v) {
    const double a = std::fmod(geometry.angles_rad[static_cast<std::size_t>(v)], period);
    return a < 0.0 ? a + period : a;
  };
  std::stable_sort(by_angle.begin(), by_angle.end(), [&](int a, int b) { return wrapped(a) < wrapped(b); });
  int bits = 0;
  while ((1 << bits) < views) ++bits;
  std::vector<int> order;
  order.reserve(by_angle.size());
  for (int i = 0; i < (1 << bits); ++i) {
    int reversed = 0;
    for (int k = 0; k < bits; ++k)
      if (i & (1 << k)) reversed |= 1 << (bits - 1 - k);
    if (reversed < views) order.push_back(by_angle[static_cast<std::size_t>(reversed)]);
  }
  return order;
}

// The gradient of the volume's isotropic total variation, sum over voxels of
// sqrt(|forward differences|^2 + eps^2) (eps keeps it differentiable where
// the volume is flat). A one-slice grid has no z differences. Row by row
// without branches inside a row, so that the loops vectorise.
void TotalVariationGradient(const VolumeGrid& grid, const Eigen::VectorXf& volume, float eps,
                            Eigen::VectorXf* gradient) {
  const std::int64_t n = volume.size(), nx = grid.nx, sy = grid.nx, sz = static_cast<std::int64_t>(grid.nx) * grid.ny;
  // Each forward difference divided by its voxel's gradient magnitude.
  Eigen::VectorXf px(n), py(n), pz(n);
  const float* x = volume.data();
  for (int k = 0; k < grid.nz; ++k)
    for (int j = 0; j < grid.ny; ++j) {
      const std::int64_t row = grid.Index(0, j, k);
      float* ax = px.data() + row;
      float* ay = py.data() + row;
      float* az = pz.data() + row;
      const float* xr = x + row;
      for (std::int64_t i = 0; i + 1 < nx; ++i) ax[i] = xr[i + 1] - xr[i];
      ax[nx - 1] = 0.0f;
      if (j + 1 < grid.ny)
        for (std::int64_t i = 0; i < nx; ++i) ay[i] = xr[i + sy] - xr[i];
      else
        std::fill(ay, ay + nx, 0.0f);
      if (k + 1 < grid.nz)
        for (std::int64_t i = 0; i < nx; ++i) az[i] = xr[i + sz] - xr[i];
      else
        std::fill(az, az + nx, 0.0f);
      for (std::int64_t i = 0; i < nx; ++i) {
        const float inv = 1.0f / std::sqrt(ax[i] * ax[i] + ay[i] * ay[i] + az[i] * az[i] + eps * eps);
        ax[i] *= inv;
        ay[i] *= inv;
        az[i] *= inv;
      }
    }
  gradient->resize(n);
  for (int k = 0; k < grid.nz; ++k)
    for (int j = 0; j < grid.ny; ++j) {
      const std::int64_t row = grid.Index(0, j, k);
      const float* ax = px.data() + row;
      const float* ay = py.data() + row;
      const float* az = pz.data() + row;
      float* g = gradient->data() + row;
      for (std::int64_t i = 0; i < nx; ++i) g[i] = -(ax[i] + ay[i] + az[i]);
      for (std::int64_t i = 1; i < nx; ++i) g[i] += ax[i - 1];
      if (j > 0)
        for (std::int64_t i = 0; i < nx; ++i) g[i] += ay[i - sy];
      if (k > 0)
        for (std::int64_t i = 0; i < nx; ++i) g[i] += az[i - sz];
    }
}

// ASD-POCS's TV phase: `steps` normalised steepest-descent steps of total
// length `length` (in the volume's units, 1/mm).
void TotalVariationSteps(const VolumeGrid& grid, int steps, double length, bool non_negative, Eigen::VectorXf* x) {
  if (!(length > 0.0)) return;
  // eps: a thousandth of the volume's range, far below any edge worth keeping.
  const float eps = std::max(1e-3f * x->maxCoeff(), 1e-12f);
  Eigen::VectorXf gradient;
  for (int step = 0; step < steps; ++step) {
    TotalVariationGradient(grid, *x, eps, &gradient);
    const double norm = std::sqrt(SquaredNorm(gradient));
    if (!(norm > 0.0)) break;
    *x -= static_cast<float>(length / steps / norm) * gradient;
  }
  if (non_negative) ClampNonNegative(x);
}

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
  if ((options.method == Method::kArt || options.method == Method::kSart) && !whole)
    return end(solvers::Termination::kInvalidOptions,
               std::string(options.method == Method::kArt ? "ART visits one ray" : "SART visits one view") +
                   " at a time and needs every row of W in one process; use SIRT or CGLS");
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
  const double lambda = options.relaxation > 0.0             ? options.relaxation
                        : options.method == Method::kArt  ? 0.25
                        : options.method == Method::kSart ? kSartRelaxation
                                                          : 1.9;
  summary.relaxation = options.method == Method::kCgls ? 0.0 : lambda;
  summary.tv_strength = options.total_variation ? options.tv_strength : 0.0;
  const bool non_negative = options.non_negative && options.method != Method::kCgls;
  if (non_negative) ClampNonNegative(&x);

  Eigen::VectorXf wx, r, g;
  projector.Forward(x, &wx);
  MaskedResidual(b, wx, mask, &r);
  summary.residual_history.push_back(std::sqrt(ray_sum(SquaredNorm(r))));
  timer.SetupDone(&summary);

  // Method state.
  Eigen::VectorXf inv_rows, inv_columns;  // SIRT
  SartState sart;
  Eigen::VectorXf before;                 // SART with TV: the volume before the pass
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
  } else if (options.method == Method::kSart) {
    inv_rows = row_sums.unaryExpr([](float v) { return v > 0.0f ? 1.0f / v : 0.0f; });
    sart.order = SpreadViewOrder(whole->geometry());
    sart.scratch.assign(static_cast<std::size_t>(2 * voxels), 0.0f);
    sart.span.assign(static_cast<std::size_t>(projector.views()), {std::numeric_limits<std::int32_t>::max(), -1});
    for (int view = 0; view < projector.views(); ++view)
      whole->VisitViewRows(view, [&](std::int64_t ray, const std::int32_t* voxel, const float*, std::int32_t n) {
        if (mask[ray] == 0.0f) return;
        auto& [first, last] = sart.span[static_cast<std::size_t>(view)];
        for (std::int32_t k = 0; k < n; ++k) {
          first = std::min(first, voxel[k]);
          last = std::max(last, voxel[k]);
        }
      });
  } else {
    // Views in a shuffled order: consecutive updates from nearby angles are
    // nearly parallel hyperplanes and make slow progress.
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), std::mt19937(27));
  }

  solvers::ProgressThrottle throttle(options.progress, MethodName(options.method), options.max_iterations);
  summary.stop_reason = StopReason::kMaxIterations;
  // A fixed relaxation keeps ART's and SART's updates from shrinking to zero.
  const bool row_action = options.method == Method::kArt || options.method == Method::kSart;
  // SART with TV approaches a balance between the data step and the TV step
  // tied to it, whose residual stays above the noise level by what TV holds
  // back, so the discrepancy rule may never act while each pass fits more
  // noise. A pass that lowers the residual by less than the noise's own
  // scatter in it (||noise|| has a standard deviation of
  // sqrt(sum var(b) / (2 rays))) makes a change the data cannot resolve:
  // three in a row are the balance, converged (kStagnation), and trusted if
  // the residual is within 1.5 x the noise level like any stalled iteration.
  const double resolvable_drop =
      summary.tv_strength > 0.0 && have_noise && options.stop_rule == StopRule::kDiscrepancy &&
              options.stagnation_tolerance > 0.0
          ? std::sqrt(noise_sum / (2.0 * static_cast<double>(summary.rays_used)))
          : 0.0;
  int flat_steps = 0;
  // SART's residual as the pass met it, when that stands for the exact one
  // (below); negative when r holds the exact residual.
  double residual_met = -1.0;
  for (int iteration = 1; iteration <= options.max_iterations; ++iteration) {
    residual_met = -1.0;
    if (options.method == Method::kArt) {
      ArtSweep(*whole, b, mask, order, lambda, non_negative, &x);
      projector.Forward(x, &wx);
      MaskedResidual(b, wx, mask, &r);
    } else if (options.method == Method::kSart) {
      if (summary.tv_strength > 0.0) before = x;
      const double met = std::sqrt(ray_sum(SartPass(*whole, b, mask, inv_rows, lambda, non_negative, &sart, &x)));
      if (summary.tv_strength > 0.0)
        TotalVariationSteps(whole->grid(), options.tv_steps, summary.tv_strength * (x - before).norm(), non_negative,
                            &x);
      // The exact residual costs a forward projection, about a third of the
      // pass: taken only where the stopping rule could act on it. Elsewhere
      // the residual each view met in the pass stands for it (it trails the
      // exact one by the pass's own progress, a few percent once the first
      // passes are done).
      if (options.stop_rule == StopRule::kDiscrepancy && met <= kExactResidualMargin * summary.discrepancy_target) {
        projector.Forward(x, &wx);
        MaskedResidual(b, wx, mask, &r);
      } else {
        residual_met = met;
      }
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
    const double residual = residual_met >= 0.0 ? residual_met : std::sqrt(ray_sum(SquaredNorm(r)));
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
    const double flat_drop = std::max(options.stagnation_tolerance * previous, resolvable_drop);
    flat_steps = previous - residual < flat_drop ? flat_steps + 1 : 0;
    if (options.stagnation_tolerance > 0.0 && flat_steps >= 3) {
      summary.stop_reason = row_action && resolvable_drop == 0.0 ? StopReason::kLimitCycle : StopReason::kStagnation;
      break;
    }
  }
  if (summary.stop_reason == StopReason::kMaxIterations)
    throttle.Finish();
  else
    throttle.StoppedAt(summary.iterations, StopPhrase(summary.stop_reason));
  for (std::int64_t j = 0; j < voxels; ++j)
    if (column_sums[j] <= 0.0f) x[j] = 0.0f;
  if (residual_met >= 0.0) {  // the last entry was SART's estimate: the result's own residual instead
    projector.Forward(x, &wx);
    MaskedResidual(b, wx, mask, &r);
    summary.residual_history.back() = std::sqrt(ray_sum(SquaredNorm(r)));
  }

  const double final_residual = summary.residual_history.back();
  const bool stalled = summary.stop_reason == StopReason::kStagnation || summary.stop_reason == StopReason::kLimitCycle;
  summary.inconsistent = have_noise && stalled && final_residual > 1.5 * std::sqrt(noise_sum);
  std::string notes;
  if (summary.underdetermined)
    notes += "; underdetermined (" + std::to_string(summary.rays_used) + " rays for " +
             std::to_string(summary.voxels_reached) + " voxels): the stopping rule and non-negativity carry it";
  if (summary.voxels_unreached > 0)
    notes += "; " + std::to_string(summary.voxels_unreached) + " voxels no valid ray reaches, left at 0";
  timer.Finish(&summary);
  if (summary.stop_reason == StopReason::kLimitCycle && !(have_noise && final_residual <= summary.discrepancy_target)) {
    // Where the cycle settles depends on the relaxation and the order, not on the data.
    summary.termination = solvers::Termination::kFailure;
    summary.message = std::string(MethodName(options.method)) + " ended in a limit cycle: the residual stopped at " +
                      (have_noise ? Format(final_residual / std::sqrt(noise_sum)) + " times the noise level"
                                  : Format(final_residual) + " with no noise level to judge it by") +
                      " after " + std::to_string(summary.iterations) +
                      " passes; the volume is not usable: lower the relaxation or use SIRT" +
                      (summary.inconsistent ? "; the data may be inconsistent: check the centre of rotation, the "
                                              "flats and the geometry"
                                            : "") +
                      notes;
  } else if (summary.inconsistent) {
    summary.termination = solvers::Termination::kNoConvergence;
    summary.message = "inconsistent data: the residual stalls at " + Format(final_residual / std::sqrt(noise_sum)) +
                      " times the noise level; check the centre of rotation, the flats and the geometry" + notes;
  } else if (summary.stop_reason == StopReason::kMaxIterations && options.stop_rule == StopRule::kDiscrepancy) {
    summary.termination = solvers::Termination::kNoConvergence;
    summary.message = "the residual " + Format(final_residual) + " is still above the noise level " +
                      Format(summary.discrepancy_target) + " after " + std::to_string(summary.iterations) +
                      " iterations; raise " + options.iteration_limit_name + notes;
  } else {
    summary.termination = solvers::Termination::kSuccess;
    if (resolvable_drop > 0.0 && summary.stop_reason == StopReason::kStagnation)
      notes = "; total variation holds the residual at " + Format(final_residual / std::sqrt(noise_sum)) +
              " times the noise level: stopped at its balance, where a pass lowers it by less than the noise "
              "resolves (" + Format(resolvable_drop) + ")" + notes;
    summary.message = notes.empty() ? std::string() : notes.substr(2);
  }
  return summary;
}

}  // namespace photorig::tomography
