// Ordered-subsets SART, optionally with total-variation steps after each
// pass (ASD-POCS) (reconstruct.h).
#include "iteration.h"
#include "photorig/solvers/tomography/reconstruct.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <numeric>
#include <utility>
#include <vector>

namespace photorig::solvers::tomography::internal {
namespace {

// SART checks its exact residual once the residual its views met comes within
// this factor of the discrepancy target (the two differ by a few percent).
constexpr double kExactResidualMargin = 1.25;
// Stands in for a zero column sum, whose back projection is zero too.
constexpr float kTinyWeight = 1e-30f;

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

class Sart final : public Iteration {
 public:
  explicit Sart(const IterationInputs& in) : in_(in), inv_rows_(Reciprocals(in.row_sums)) {
    const Projector& whole = *in.whole;
    state_.order = SpreadViewOrder(whole.geometry());
    state_.scratch.assign(static_cast<std::size_t>(2 * in.system.voxels()), 0.0f);
    state_.span.assign(static_cast<std::size_t>(in.system.views()), {std::numeric_limits<std::int32_t>::max(), -1});
    for (int view = 0; view < in.system.views(); ++view)
      whole.VisitViewRows(view, [&](std::int64_t ray, const std::int32_t* voxel, const float*, std::int32_t n) {
        if (in.mask[ray] == 0.0f) return;
        auto& [first, last] = state_.span[static_cast<std::size_t>(view)];
        for (std::int32_t k = 0; k < n; ++k) {
          first = std::min(first, voxel[k]);
          last = std::max(last, voxel[k]);
        }
      });
  }

  StepResult Step(Eigen::VectorXf* x, Eigen::VectorXf* r) override {
    if (in_.tv_strength > 0.0) before_ = *x;
    const double met_squared =
        SartPass(*in_.whole, in_.b, in_.mask, inv_rows_, in_.lambda, in_.non_negative, &state_, x);
    const double met = std::sqrt(in_.system.SumOverRays(met_squared));
    if (in_.tv_strength > 0.0)
      TotalVariationSteps(in_.whole->grid(), in_.options.tv_steps, in_.tv_strength * (*x - before_).norm(),
                          in_.non_negative, x);
    // The exact residual costs a forward projection, about a third of the
    // pass: taken only where the stopping rule could act on it. Elsewhere
    // the residual each view met in the pass stands for it (it trails the
    // exact one by the pass's own progress, a few percent once the first
    // passes are done).
    if (in_.options.stop_rule == StopRule::kDiscrepancy && met <= kExactResidualMargin * in_.discrepancy_target) {
      in_.system.Forward(*x, in_.wx);
      MaskedResidual(in_.b, *in_.wx, in_.mask, r);
      return {};
    }
    return {false, met};
  }

 private:
  IterationInputs in_;
  Eigen::VectorXf inv_rows_;
  SartState state_;
  Eigen::VectorXf before_;  // with TV: the volume before the pass
};

}  // namespace

std::unique_ptr<Iteration> MakeSart(const IterationInputs& in) { return std::make_unique<Sart>(in); }

}  // namespace photorig::solvers::tomography::internal
