#include "low_frequency_fit.h"

#include "lane_math.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>

namespace photorig::solvers::ps::internal {
namespace {

// The Levenberg-Marquardt search stops after this many iterations, or once
// a step moves the normal by less than kConvergedStepRad or by less than
// kConvergedStepSigma of its own standard error (the information the fit
// reports, LowFrequencySolution::normal_information): further steps would
// move it by a small fraction of what the noise already does.
constexpr int kMaxIterations = 40;
constexpr double kConvergedStepRad = 1e-5;
constexpr double kConvergedStepSigma = 0.01;

// The Cholesky factor L L^T of G restricted to `support` (a bit mask of the
// four unknowns; G symmetric, upper triangle used). False where that system
// is singular: a pivot that keeps no more than 1e-12 of its diagonal is a
// dependent column (e.g. no sample near the mirror direction, where n.h and
// (n.h)^2 coincide).
struct SupportFactor {
  int index[4];  // the support's unknowns, ascending
  int n = 0;
  double L[4][4] = {};

  bool Factor(const double (&G)[4][4], int support) {
    n = 0;
    for (int j = 0; j < 4; ++j)
      if (support >> j & 1) index[n++] = j;
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j <= i; ++j) {
        double sum = G[std::min(index[i], index[j])][std::max(index[i], index[j])];
        for (int k = 0; k < j; ++k) sum -= L[i][k] * L[j][k];
        if (i == j) {
          const double diagonal = G[index[i]][index[i]];
          if (!(diagonal > 0.0) || !(sum > 1e-12 * diagonal)) return false;
          L[i][i] = std::sqrt(sum);
        } else {
          L[i][j] = sum / L[j][j];
        }
      }
    }
    return true;
  }
  // y = L^-1 (the support's entries of v).
  void ForwardSubstitute(const double* v, double* y) const {
    for (int i = 0; i < n; ++i) {
      double sum = v[index[i]];
      for (int k = 0; k < i; ++k) sum -= L[i][k] * y[k];
      y[i] = sum / L[i][i];
    }
  }
};

// The least-squares solution of G a = g on `support` (SupportFactor's), into
// a (0 off the support); false where the support's system is singular.
bool SolveOnSupport(const double (&G)[4][4], const double (&g)[4], int support, std::array<double, 4>* a) {
  SupportFactor f;
  if (!f.Factor(G, support)) return false;
  double x[4];
  f.ForwardSubstitute(g, x);
  for (int i = f.n - 1; i >= 0; --i) {
    double sum = x[i];
    for (int k = i + 1; k < f.n; ++k) sum -= f.L[k][i] * x[k];
    x[i] = sum / f.L[i][i];
  }
  a->fill(0.0);
  for (int i = 0; i < f.n; ++i) (*a)[f.index[i]] = x[i];
  return true;
}

// G's upper triangle from NormalEquationSums' first ten sums (the rest of G 0).
void GramOf(const std::array<double, 14>& sums, double (&G)[4][4]) {
  for (int row = 0, entry = 0; row < 4; ++row)
    for (int col = 0; col < 4; ++col) G[row][col] = col >= row ? sums[entry++] : 0.0;
}

// Whether a (the least-squares solution on its support) is the non-negative
// least-squares solution: every a on the support positive, and the gradient
// G a - g non-negative off it (the Karush-Kuhn-Tucker conditions of a convex problem).
bool IsNonNegativeOptimum(const double (&G)[4][4], const double (&g)[4], int support, const std::array<double, 4>& a) {
  for (int j = 0; j < 4; ++j) {
    if (support >> j & 1) {
      if (!(a[j] > 0.0)) return false;
      continue;
    }
    double gradient = -g[j];
    for (int k = 0; k < 4; ++k) gradient += G[std::min(j, k)][std::max(j, k)] * a[k];
    if (gradient < -1e-12 * (std::abs(g[j]) + G[j][j])) return false;
  }
  return true;
}

// Non-negative least squares on four unknowns from the normal equations
// G a = g and yy = the sum of squared targets, returning the sum of squared
// residuals. The solution is the unconstrained one on its own support, so
// it is the best non-negative one over the fifteen supports; *support
// (the last solution's, as a bit mask) is tried first and kept if it passes
// the optimality conditions, which from one Levenberg-Marquardt step to the
// next it almost always does.
double NonNegativeLeastSquares(const double (&G)[4][4], const double (&g)[4], double yy, int* support,
                               std::array<double, 4>* a) {
  auto misfit = [&](const std::array<double, 4>& x) {
    // At the least-squares solution on a support, the misfit is yy - g . a.
    return std::max(yy - (g[0] * x[0] + g[1] * x[1] + g[2] * x[2] + g[3] * x[3]), 0.0);
  };
  if (*support > 0 && SolveOnSupport(G, g, *support, a) && IsNonNegativeOptimum(G, g, *support, *a)) return misfit(*a);
  // Then the supports one unknown away (a step of the search adds or drops
  // one far more often than more): the conditions are sufficient, so one
  // that passes is the optimum the search over all fifteen would find.
  if (*support > 0) {
    for (int j = 0; j < 4; ++j) {
      const int next = *support ^ (1 << j);
      if (next > 0 && SolveOnSupport(G, g, next, a) && IsNonNegativeOptimum(G, g, next, *a)) {
        *support = next;
        return misfit(*a);
      }
    }
  }
  // Then every support, fewest unknowns first (a pixel's reflectance uses
  // few of the four), the first that passes the conditions being the optimum.
  static constexpr int kSupportsBySize[15] = {1, 2, 4, 8, 3, 5, 6, 9, 10, 12, 7, 11, 13, 14, 15};
  for (const int s : kSupportsBySize) {
    if (SolveOnSupport(G, g, s, a) && IsNonNegativeOptimum(G, g, s, *a)) {
      *support = s;
      return misfit(*a);
    }
  }
  // Rounding can fail the conditions everywhere near a dependent column:
  // the best of the supports whose solution is non-negative.
  double best = yy;  // the empty support
  int best_support = 0;
  std::array<double, 4> best_a{}, x;
  for (int s = 1; s < 16; ++s) {
    if (!SolveOnSupport(G, g, s, &x) || !std::all_of(x.begin(), x.end(), [](double v) { return v >= 0.0; })) continue;
    const double m = misfit(x);
    if (m < best) best = m, best_support = s, best_a = x;
  }
  *support = best_support;
  *a = best_a;
  return best;
}

// The sample loops below run kSampleLanes samples per pass with each sum
// held per lane (`omp simd` over the lanes, the arrays padded to whole
// passes with samples that add nothing): an `omp simd reduction` over the
// samples with this many sums was compiled with every sum in memory and the
// samples gathered one by one, 3.5 times slower (about 9 ns a sample).
constexpr int kSampleLanes = kLowFrequencySampleLanes;

// body(k, j) for every sample k of the padded arrays, kSampleLanes at a
// time, j = k's lane in its pass.
template <typename Body>
PHOTORIG_LANE_INLINE void ForEachSample(int padded_count, const Body& body) {
  for (int first = 0; first < padded_count; first += kSampleLanes) {
#pragma omp simd
    for (int j = 0; j < kSampleLanes; ++j) body(first + j, j);
  }
}

PHOTORIG_LANE_INLINE double Square(double x) { return x * x; }

// Adds lane j's sums into one total per row.
template <int kRows>
void ReduceLanes(const double (&lanes)[kRows][kSampleLanes], double* out) {
  for (int i = 0; i < kRows; ++i) {
    double total = 0.0;
    for (int j = 0; j < kSampleLanes; ++j) total += lanes[i][j];
    out[i] = total;
  }
}

// The normal equations of a at normal n: the upper triangle of G (10
// sums, row by row) and g (4), columns max(0, n.l) (1, c, c^2, d) with c =
// max(0, n.h).
PHOTORIG_PS_MULTIVERSION
void NormalEquationSums(const LowFrequencySamples& s, const double* n, double* out) {
  const double nx = n[0], ny = n[1], nz = n[2];
  const double *lx = s.lx, *ly = s.ly, *lz = s.lz, *hx = s.hx, *hy = s.hy, *hz = s.hz, *d = s.d, *b = s.b;
  alignas(64) double acc[14][kSampleLanes] = {};
  ForEachSample(s.padded_count, [&](int k, int j) {
    const double c0 = std::max(0.0, nx * lx[k] + ny * ly[k] + nz * lz[k]);
    const double c = std::max(0.0, nx * hx[k] + ny * hy[k] + nz * hz[k]);
    const double c1 = c0 * c, c2 = c1 * c, c3 = c0 * d[k];
    acc[0][j] += c0 * c0, acc[1][j] += c0 * c1, acc[2][j] += c0 * c2, acc[3][j] += c0 * c3;
    acc[4][j] += c1 * c1, acc[5][j] += c1 * c2, acc[6][j] += c1 * c3;
    acc[7][j] += c2 * c2, acc[8][j] += c2 * c3, acc[9][j] += c3 * c3;
    acc[10][j] += c0 * b[k], acc[11][j] += c1 * b[k], acc[12][j] += c2 * b[k], acc[13][j] += c3 * b[k];
  });
  ReduceLanes(acc, out);
}

// The misfit's derivatives along the tangent directions t1, t2 at n, a
// held (the clamps' derivatives are 0 where they bind): with v_j the
// residuals' derivative along t_j, out = v1.v1, v1.v2, v2.v2, v1.r, v2.r,
// then the four columns' products with v1 and with v2 (for the projection
// of variable projection's Jacobian).
PHOTORIG_PS_MULTIVERSION
void TangentSums(const LowFrequencySamples& s, const double* n, const double* t1, const double* t2, const double* a,
                 double* out) {
  const double nx = n[0], ny = n[1], nz = n[2];
  const double a0 = a[0], a1 = a[1], a2 = a[2], a3 = a[3];
  const double t1x = t1[0], t1y = t1[1], t1z = t1[2], t2x = t2[0], t2y = t2[1], t2z = t2[2];
  const double *lx = s.lx, *ly = s.ly, *lz = s.lz, *hx = s.hx, *hy = s.hy, *hz = s.hz, *d = s.d, *b = s.b;
  alignas(64) double acc[13][kSampleLanes] = {};
  ForEachSample(s.padded_count, [&](int k, int j) {
    const double dot_l = nx * lx[k] + ny * ly[k] + nz * lz[k];
    const double dot_h = nx * hx[k] + ny * hy[k] + nz * hz[k];
    const double nl = std::max(0.0, dot_l), c = std::max(0.0, dot_h);
    const double shape = a0 + c * (a1 + a2 * c) + a3 * d[k];
    const double residual = nl * shape - b[k];
    const double dl = dot_l > 0.0 ? shape : 0.0;
    const double dh = dot_h > 0.0 ? nl * (a1 + 2.0 * a2 * c) : 0.0;
    const double d1 = dl * (t1x * lx[k] + t1y * ly[k] + t1z * lz[k]) + dh * (t1x * hx[k] + t1y * hy[k] + t1z * hz[k]);
    const double d2 = dl * (t2x * lx[k] + t2y * ly[k] + t2z * lz[k]) + dh * (t2x * hx[k] + t2y * hy[k] + t2z * hz[k]);
    const double c1 = nl * c, c2 = c1 * c, c3 = nl * d[k];
    acc[0][j] += d1 * d1, acc[1][j] += d1 * d2, acc[2][j] += d2 * d2;
    acc[3][j] += d1 * residual, acc[4][j] += d2 * residual;
    acc[5][j] += nl * d1, acc[6][j] += c1 * d1, acc[7][j] += c2 * d1, acc[8][j] += c3 * d1;
    acc[9][j] += nl * d2, acc[10][j] += c1 * d2, acc[11][j] += c2 * d2, acc[12][j] += c3 * d2;
  });
  ReduceLanes(acc, out);
}

// Chi-square of the fit (n, a): each residual over its sample's sigma.
PHOTORIG_PS_MULTIVERSION
double WeightedMisfit(const LowFrequencySamples& s, const double* n, const double* a) {
  const double nx = n[0], ny = n[1], nz = n[2];
  const double a0 = a[0], a1 = a[1], a2 = a[2], a3 = a[3];
  const double *lx = s.lx, *ly = s.ly, *lz = s.lz, *hx = s.hx, *hy = s.hy, *hz = s.hz, *d = s.d, *b = s.b;
  const double* inverse_sigma = s.inverse_sigma;
  alignas(64) double acc[1][kSampleLanes] = {};
  ForEachSample(s.padded_count, [&](int k, int j) {
    const double nl = std::max(0.0, nx * lx[k] + ny * ly[k] + nz * lz[k]);
    const double c = std::max(0.0, nx * hx[k] + ny * hy[k] + nz * hz[k]);
    acc[0][j] += Square(inverse_sigma[k] * (nl * (a0 + c * (a1 + a2 * c) + a3 * d[k]) - b[k]));
  });
  double chi2 = 0.0;
  ReduceLanes(acc, &chi2);
  return chi2;
}

// Two unit vectors that complete n (unit) to an orthonormal basis.
void Tangents(const Eigen::Vector3d& n, Eigen::Vector3d* t1, Eigen::Vector3d* t2) {
  const Eigen::Vector3d helper = std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  *t1 = n.cross(helper).normalized();
  *t2 = n.cross(*t1);
}

}  // namespace

void LowFrequencyProblem::Geometry(int k, Eigen::Vector3d* l, Eigen::Vector3d* h, double* cos_d) const {
  *l = Eigen::Vector3d(wx[k * stride], wy[k * stride], wz[k * stride]);
  if (halves) {
    *h = Eigen::Vector3d(halves->x[k], halves->y[k], halves->z[k]);
    *cos_d = halves->cos_d[k];
    return;
  }
  *h = (*l + view).normalized();
  *cos_d = l->dot(*h);
}

HalfVectorTable::HalfVectorTable(const LowFrequencyProblem& problem) {
  LowFrequencyProblem each = problem;
  each.halves = nullptr;
  for (int k = 0; k < problem.lights; ++k) {
    Eigen::Vector3d l, h;
    double d = 0.0;
    each.Geometry(k, &l, &h, &d);
    x.push_back(h.x()), y.push_back(h.y()), z.push_back(h.z()), cos_d.push_back(d);
  }
}

LowFrequencyFitter::Evaluation LowFrequencyFitter::Evaluate(const Eigen::Vector3d& normal, int support) const {
  Evaluation e;
  e.support = support;
  NormalEquationSums(Samples(), normal.data(), e.sums.data());
  const double* sums = e.sums.data();
  double G[4][4];
  GramOf(e.sums, G);
  const double g[4] = {sums[10], sums[11], sums[12], sums[13]};
  e.misfit = NonNegativeLeastSquares(G, g, b2_, &e.support, &e.a);
  return e;
}

double LowFrequencyFitter::Chi2(const Eigen::Vector3d& normal, const std::array<double, 4>& a) const {
  return WeightedMisfit(Samples(), normal.data(), a.data());
}

void LowFrequencyFitter::TangentSystem(const Eigen::Vector3d& normal, const Evaluation& at, const Eigen::Vector3d& t1,
                                       const Eigen::Vector3d& t2, Eigen::Matrix2d* jtj, Eigen::Vector2d* jtr) const {
  double sums[13];
  TangentSums(Samples(), normal.data(), t1.data(), t2.data(), at.a.data(), sums);
  *jtj << sums[0], sums[1], sums[1], sums[2];
  // At the least-squares a on its support the residual is orthogonal to the
  // support's columns, so J^T r needs no projection.
  *jtr << sums[3], sums[4];
  // Variable projection (Golub and Pereyra; Kaufman's form): the Jacobian of
  // the residual with a re-solved is v_j less its projection onto the
  // support's columns, so J^T J loses p_j^T G_S^-1 p_k. Without it the
  // search moves the normal and a in turns and crawls along the valley
  // where the n . h terms trade against the normal.
  if (at.support == 0) return;
  double G[4][4];
  GramOf(at.sums, G);
  SupportFactor f;
  if (!f.Factor(G, at.support)) return;
  // p_j^T G_S^-1 p_k = y_j . y_k with y_j = L^-1 p_j.
  double y1[4], y2[4];
  f.ForwardSubstitute(sums + 5, y1);
  f.ForwardSubstitute(sums + 9, y2);
  Eigen::Matrix2d projected = Eigen::Matrix2d::Zero();
  for (int i = 0; i < f.n; ++i) {
    projected(0, 0) += y1[i] * y1[i], projected(1, 1) += y2[i] * y2[i];
    projected(0, 1) += y1[i] * y2[i];
  }
  projected(1, 0) = projected(0, 1);
  *jtj -= projected;
  // Rounding can leave the difference a hair from positive semi-definite.
  jtj->diagonal() = jtj->diagonal().cwiseMax(0.0);
}

Eigen::Vector3d LowFrequencyFitter::Search(Eigen::Vector3d normal, const Eigen::Vector3d& view, Evaluation* at,
                                           int* iterations) const {
  // The start is the Lambertian case, so its support (a0 alone) is tried first.
  Evaluation current = Evaluate(normal, 1);
  double damping = -1.0;  // set from the first system's diagonal
  for (int iteration = 0; iteration < kMaxIterations; ++iteration) {
    *iterations = iteration + 1;
    Eigen::Vector3d t1, t2;
    Tangents(normal, &t1, &t2);
    Eigen::Matrix2d jtj;
    Eigen::Vector2d jtr;
    TangentSystem(normal, current, t1, t2, &jtj, &jtr);
    if (damping < 0.0) damping = 1e-3 * std::max(jtj.trace() / 2.0, 1e-300);
    const double variance = ResidualVariance(current.misfit);
    auto negligible = [&](const Eigen::Vector2d& step) {
      return step.norm() < kConvergedStepRad ||
             step.dot(jtj * step) < kConvergedStepSigma * kConvergedStepSigma * variance;
    };
    bool moved = false, converged = false;
    // Marquardt's damping: raised until a step lowers the misfit (or gives up).
    while (damping < 1e12 * std::max(jtj.trace(), 1e-300)) {
      Eigen::Matrix2d damped = jtj;
      damped.diagonal().array() += damping;
      const Eigen::Vector2d step = damped.ldlt().solve(-jtr);
      if (!step.allFinite()) break;
      // Damping only shrinks the step from here: one this short would end
      // the search if taken, so the normal is where it stays to that
      // precision, and evaluating it (and shorter ones after a rejection)
      // would not move it further.
      if (negligible(step)) break;
      const Eigen::Vector3d trial = (normal + step.x() * t1 + step.y() * t2).normalized();
      if (!(trial.dot(view) > 0.0)) {
        damping *= 10.0;
        continue;
      }
      const Evaluation next = Evaluate(trial, current.support);
      if (next.misfit < current.misfit) {
        converged = negligible(step) || current.misfit - next.misfit <= 1e-10 * current.misfit;
        normal = trial, current = next, moved = true;
        damping = std::max(damping * 0.3, 1e-300);
        break;
      }
      damping *= 10.0;
    }
    if (!moved || converged) break;
  }
  *at = current;
  return normal;
}

LowFrequencySolution LowFrequencyFitter::Fit(const LowFrequencyProblem& problem) {
  LowFrequencySolution out;
  // The usable samples, the brightest spike_fraction of them left out.
  order_.clear();
  for (int k = 0; k < problem.lights; ++k)
    if (problem.inverse_sigma[k] > 0.0) order_.push_back(k);
  const int usable = static_cast<int>(order_.size());
  const int left_out = LeftOut(usable);
  if (left_out > 0) {
    std::nth_element(order_.begin(), order_.begin() + left_out, order_.end(),
                     [&](int i, int j) { return problem.observed[i] > problem.observed[j]; });
    order_.erase(order_.begin(), order_.begin() + left_out);
  }
  const int count = static_cast<int>(order_.size());
  left_out_ = left_out;
  view_ = problem.view;
  ResizeSamples(count);
  b2_ = 0.0;
  for (int i = 0; i < count; ++i) {
    const int k = order_[i];
    Eigen::Vector3d l, h;
    problem.Geometry(k, &l, &h, &d_[i]);
    lx_[i] = l.x(), ly_[i] = l.y(), lz_[i] = l.z();
    hx_[i] = h.x(), hy_[i] = h.y(), hz_[i] = h.z();
    b_[i] = problem.observed[k];
    inverse_sigma_[i] = problem.inverse_sigma[k];
    b2_ += b_[i] * b_[i];
  }
  return Solve();
}

LowFrequencySolution LowFrequencyFitter::FitSameSamples(std::span<const double> values) {
  b2_ = 0.0;
  for (int i = 0; i < count_; ++i) b_[i] = values[i], b2_ += values[i] * values[i];
  return Solve();
}

void LowFrequencyFitter::ResizeSamples(int count) {
  count_ = count;
  const int padded = (count + kSampleLanes - 1) / kSampleLanes * kSampleLanes;
  for (auto* v : {&lx_, &ly_, &lz_, &hx_, &hy_, &hz_, &d_, &b_, &inverse_sigma_}) {
    v->resize(padded);
    std::fill(v->begin() + count, v->end(), 0.0);
  }
}

double LowFrequencyFitter::ResidualVariance(double misfit) const {
  // Quasi-likelihood: where the model leaves more than the noise, its
  // residual variance (with the noise's alone, a pixel's misfit counts as
  // evidence against the kept lobe: on goblet's GGX pixels, whose lobes are
  // right, that sends 0.5 deg more error to the low-frequency fit).
  return std::max(misfit / (static_cast<double>(count_) - kLowFrequencyParameters), mean_noise_variance_);
}

LowFrequencySolution LowFrequencyFitter::Solve() {
  LowFrequencySolution out;
  const int count = count_;
  out.left_out = left_out_;
  out.used = count;
  if (count <= kLowFrequencyParameters) return out;
  // The start: the model's Lambertian case (a0 alone) fitted to the same samples.
  Eigen::Matrix3d lambertian_lhs = Eigen::Matrix3d::Zero();
  Eigen::Vector3d lambertian_rhs = Eigen::Vector3d::Zero();
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3d l(lx_[i], ly_[i], lz_[i]);
    lambertian_lhs += l * l.transpose();
    lambertian_rhs += l * b_[i];
  }
  const Eigen::Vector3d x = lambertian_lhs.ldlt().solve(lambertian_rhs);
  if (!x.allFinite() || !(x.dot(view_) > 0.0)) return out;
  mean_noise_variance_ = 0.0;
  for (int i = 0; i < count; ++i) mean_noise_variance_ += 1.0 / (inverse_sigma_[i] * inverse_sigma_[i]);
  mean_noise_variance_ /= count;
  Evaluation current;
  const Eigen::Vector3d normal = Search(x.normalized(), view_, &current, &out.iterations);
  out.normal = normal;
  out.a = current.a;
  out.chi2 = Chi2(normal, current.a);
  out.ok = normal.allFinite() && std::isfinite(out.chi2) && current.a[0] + current.a[1] + current.a[2] + current.a[3] > 0.0;
  if (!out.ok) return out;
  Eigen::Vector3d t1, t2;
  Tangents(normal, &t1, &t2);
  Eigen::Matrix2d jtj;
  Eigen::Vector2d jtr;
  TangentSystem(normal, current, t1, t2, &jtj, &jtr);
  out.tangents.col(0) = t1, out.tangents.col(1) = t2;
  out.normal_information = jtj / ResidualVariance(current.misfit);
  return out;
}

}  // namespace photorig::solvers::ps::internal
