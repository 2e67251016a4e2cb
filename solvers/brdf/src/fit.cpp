#include "photorig/solvers/brdf/fit.h"

#include "lobes.h"
#include "photorig/solvers/autodiff/dual.h"
#include "photorig/solvers/core/number_text.h"

#include <Eigen/QR>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <type_traits>

namespace photorig::solvers::brdf {
namespace {

// Per sample: the geometry, the measurement and the per-channel weight of its
// residual: sqrt(BrdfSample::weight), divided by sigma for kWeighted.
struct Prepared {
  Geometry geometry;
  Eigen::Vector3d value;
  Eigen::Vector3d weight;
};

// The residuals of one sample. `kd` holds rho_d per channel; `lobe` (absent
// for Lambertian) holds the specular parameter per channel and log(shape);
// `extra` (Cook-Torrance, GGX) the one parameter the channels
// share beyond the shape: Cook-Torrance's F0, GGX's scale.
class SampleResidual {
 public:
  SampleResidual(Model model, const Prepared& sample, FitLoss loss) : model_(model), s_(sample), loss_(loss) {}

  template <typename T>
  bool operator()(const T* kd, const T* lobe, const T* extra, T* residual) const {
    using std::exp;
    const T factor = internal::LobeFactor(model_, T(exp(lobe[3])), *extra, s_.geometry);
    for (int c = 0; c < 3; ++c)
      Finish(c, kd[c] / M_PI + internal::ChannelLobe(model_, lobe[c], factor, s_.geometry), residual);
    return true;
  }
  template <typename T>
  bool operator()(const T* kd, const T* lobe, T* residual) const {
    const T no_extra(0.0);
    return (*this)(kd, lobe, &no_extra, residual);
  }
  template <typename T>
  bool operator()(const T* kd, T* residual) const {
    for (int c = 0; c < 3; ++c) Finish(c, kd[c] / M_PI, residual);
    return true;
  }

 protected:
  template <typename T>
  void Finish(int c, const T& f, T* residual) const {
    using std::log;
    if (loss_ == FitLoss::kWeighted) {
      residual[c] = (f - s_.value[c]) * s_.weight[c];
    } else {
      const double ci = s_.geometry.cos_i;
      residual[c] = (log(1.0 + f * ci) - std::log(1.0 + s_.value[c] * ci)) * s_.weight[c];
    }
  }

  Model model_;
  Prepared s_;
  FitLoss loss_;
};

// two_blinn_phong: `lobe` and `lobe2` each hold k_s per channel and log(e).
class TwoLobeResidual : public SampleResidual {
 public:
  using SampleResidual::SampleResidual;

  template <typename T>
  bool operator()(const T* kd, const T* lobe, const T* lobe2, T* residual) const {
    using std::exp;
    const T first = internal::BlinnPhongFactor(T(exp(lobe[3])), s_.geometry);
    const T second = internal::BlinnPhongFactor(T(exp(lobe2[3])), s_.geometry);
    for (int c = 0; c < 3; ++c) Finish(c, kd[c] / M_PI + lobe[c] * first + lobe2[c] * second, residual);
    return true;
  }
};

// The shape values the starting grid tries, and the bounds of the fit (as log shape).
struct ShapeRange {
  double min, max;
  int steps;
};
// 41 grid steps: a factor of 1.16 in roughness, 1.36 = 1.16^2 in exponent
// (the same step in lobe width).
ShapeRange RangeOf(Model model) {
  return model == Model::kBlinnPhong || model == Model::kTwoBlinnPhong ? ShapeRange{kMinExponent, kMaxExponent, 41}
                                                                      : ShapeRange{kMinRoughness, kMaxRoughness, 41};
}

// What the shape is called in messages.
const char* ShapeName(Model model) {
  switch (model) {
    case Model::kBlinnPhong:
    case Model::kTwoBlinnPhong: return "exponent";
    case Model::kCookTorrance: return "Beckmann m";
    default: return "roughness";
  }
}

// That parameter is not linear in the lobe: the starting grid tries these.
std::vector<double> StartingExtras(Model model) {
  if (model == Model::kCookTorrance) return {0.05, 0.2, 0.4, 0.6, 0.8, 0.95};
  if (model == Model::kGgx) return {0.05, 0.1, 0.2, 0.35, 0.6, 1.0};  // 1: Schlick's lobe alone
  return {0.0};
}

// Weighted non-negative least squares of one channel's value against
// f = kd / pi + sum_j ks_j * basis_j + offset (lobes affine in their specular
// parameters): every subset of the terms is solved and the best one with no
// negative coefficient kept (at most three terms). `coefficients` gets kd,
// then each ks_j. Returns the weighted squared error.
double FitLinearChannel(const std::vector<Prepared>& prepared, const std::vector<const std::vector<double>*>& bases,
                        const std::vector<double>& offset, int c, double* coefficients) {
  // At most three terms: fixed-capacity matrices, no allocation in the grid search.
  using Small = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 3, 3>;
  using SmallVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 3, 1>;
  const int m = 1 + static_cast<int>(bases.size());
  Small a = Small::Zero(m, m);
  SmallVector b = SmallVector::Zero(m);
  double yy = 0.0, x[3];
  for (std::size_t k = 0; k < prepared.size(); ++k) {
    const double w2 = prepared[k].weight[c] * prepared[k].weight[c];
    x[0] = 1.0 / M_PI;
    for (int j = 1; j < m; ++j) x[j] = (*bases[j - 1])[k];
    const double y = prepared[k].value[c] - offset[k];
    for (int i = 0; i < m; ++i) {
      for (int j = 0; j <= i; ++j) a(i, j) += w2 * x[i] * x[j];
      b[i] += w2 * y * x[i];
    }
    yy += w2 * y * y;
  }
  a = a.selfadjointView<Eigen::Lower>();
  double best = yy;  // every coefficient zero
  SmallVector best_x = SmallVector::Zero(m);
  for (int subset = 1; subset < (1 << m); ++subset) {
    int terms[3], t = 0;
    for (int j = 0; j < m; ++j)
      if (subset & (1 << j)) terms[t++] = j;
    Small as(t, t);
    SmallVector bs(t);
    for (int i = 0; i < t; ++i) {
      bs[i] = b[terms[i]];
      for (int j = 0; j < t; ++j) as(i, j) = a(terms[i], terms[j]);
    }
    const Eigen::LDLT<Small> ldlt(as);
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().array() > 0.0).all()) continue;
    const SmallVector xs = ldlt.solve(bs);
    if ((xs.array() < 0.0).any() || !xs.allFinite()) continue;
    const double error = yy - xs.dot(bs);  // at the subset's optimum: y'y - x'b
    if (error < best) {
      best = error;
      best_x.setZero();
      for (int i = 0; i < t; ++i) best_x[terms[i]] = xs[i];
    }
  }
  for (int j = 0; j < m; ++j) coefficients[j] = best_x[j];
  return std::max(best, 0.0);
}

// The starting point: the best shape on a geometric grid (and F0 on a coarse
// one; for two lobes, the best pair of shapes at least 2.5x apart on a
// coarser grid), each with its channels' linear parameters solved exactly.
void StartingPoint(Model model, const std::vector<Prepared>& prepared, double kd[3], double lobe[4], double extra[4]) {
  const std::size_t n = prepared.size();
  std::vector<double> offset(n, 0.0);
  if (model == Model::kLambertian) {
    for (int c = 0; c < 3; ++c) FitLinearChannel(prepared, {}, offset, c, &kd[c]);
    return;
  }
  const ShapeRange range = RangeOf(model);
  auto shape_at = [&](int step) { return range.min * std::pow(range.max / range.min, step / (range.steps - 1.0)); };
  double best = std::numeric_limits<double>::infinity();
  if (HasSecondLobe(model)) {
    // Every other grid shape, each lobe's basis computed once.
    std::vector<std::vector<double>> basis;
    std::vector<double> shapes;
    for (int step = 0; step < range.steps; step += 2) {
      shapes.push_back(shape_at(step));
      basis.emplace_back(n);
      for (std::size_t k = 0; k < n; ++k)
        basis.back()[k] = internal::BlinnPhongLobe(1.0, shapes.back(), prepared[k].geometry);
    }
    for (std::size_t narrow = 0; narrow < shapes.size(); ++narrow)
      for (std::size_t broad = 0; broad + 2 <= narrow; ++broad) {
        double error = 0.0, trial[3][3];
        for (int c = 0; c < 3; ++c) error += FitLinearChannel(prepared, {&basis[narrow], &basis[broad]}, offset, c, trial[c]);
        if (error < best) {
          best = error;
          for (int c = 0; c < 3; ++c) {
            kd[c] = trial[c][0];
            lobe[c] = trial[c][1];
            extra[c] = trial[c][2];
          }
          lobe[3] = std::log(shapes[narrow]);
          extra[3] = std::log(shapes[broad]);
        }
      }
    return;
  }
  std::vector<double> basis(n);
  for (int step = 0; step < range.steps; ++step) {
    const double shape = shape_at(step);
    for (double shared : StartingExtras(model)) {
      for (std::size_t k = 0; k < n; ++k) {
        const Geometry& g = prepared[k].geometry;
        const double factor = internal::LobeFactor(model, shape, shared, g);
        offset[k] = internal::ChannelLobe(model, 0.0, factor, g);
        basis[k] = internal::ChannelLobe(model, 1.0, factor, g) - offset[k];
      }
      double error = 0.0, trial[3][2];
      for (int c = 0; c < 3; ++c) error += FitLinearChannel(prepared, {&basis}, offset, c, trial[c]);
      if (error < best) {
        best = error;
        for (int c = 0; c < 3; ++c) {
          kd[c] = trial[c][0];
          lobe[c] = model == Model::kGgx ? std::min(trial[c][1], 1.0) : trial[c][1];
        }
        lobe[3] = std::log(shape);
        extra[0] = shared;
      }
    }
  }
}

// Squared residual of one sample under `params`, mean over the channels, in
// the units of `loss`, times the sample's weight.
double SquaredResidual(const ModelParams& params, const BrdfSample& s, FitLoss loss) {
  const Eigen::Vector3d f = Evaluate(params, s.wi, s.wo);
  double sum = 0.0;
  for (int c = 0; c < 3; ++c) {
    const double r = loss == FitLoss::kWeighted
                         ? (f[c] - s.value[c]) / s.sigma[c]
                         : std::log(1.0 + f[c] * s.wi.z()) - std::log(1.0 + s.value[c] * s.wi.z());
    sum += r * r;
  }
  return s.weight * sum / 3.0;
}

// The least squares' parameter blocks at `p` (log shapes), inside the bounds
// FitModel sets.
void StartAt(const ModelParams& p, double kd[3], double lobe[4], double extra[4]) {
  const ShapeRange range = RangeOf(p.model);
  const double log_min = std::log(range.min), log_max = std::log(range.max);
  for (int c = 0; c < 3; ++c) {
    kd[c] = std::max(p.diffuse[c], 0.0);
    lobe[c] = std::max(p.specular[c], 0.0);
    if (p.model == Model::kGgx) lobe[c] = std::min(lobe[c], 1.0);
  }
  if (p.model == Model::kLambertian) return;
  lobe[3] = std::clamp(std::log(std::max(p.shape, range.min)), log_min, log_max);
  if (p.model == Model::kCookTorrance) extra[0] = std::clamp(p.fresnel_f0, 0.0, 1.0);
  if (p.model == Model::kGgx) extra[0] = std::max(p.specular_scale, 0.0);
  if (HasSecondLobe(p.model)) {
    for (int c = 0; c < 3; ++c) extra[c] = std::max(p.specular2[c], 0.0);
    extra[3] = std::clamp(std::log(std::max(p.shape2, range.min)), log_min, log_max);
  }
}

// Mean of a - b over the samples and its standard error.
std::pair<double, double> MeanDifference(const std::vector<double>& a, const std::vector<double>& b) {
  const double n = static_cast<double>(a.size());
  double sum = 0.0, sum2 = 0.0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    const double d = a[k] - b[k];
    sum += d;
    sum2 += d * d;
  }
  const double mean = sum / n, variance = std::max(0.0, sum2 / n - mean * mean) * n / std::max(1.0, n - 1.0);
  return {mean, std::sqrt(variance / n)};
}

std::string Number(double v) { return core::NumberText(v, 4); }

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
  if (!(min_log_residual_variance >= 0.0)) {
    *why = "min_log_residual_variance must be non-negative";
    return false;
  }
  if (start) {
    const ModelParams& p = *start;
    const bool finite = p.diffuse.allFinite() && p.specular.allFinite() && std::isfinite(p.shape) &&
                        std::isfinite(p.fresnel_f0) && p.specular2.allFinite() && std::isfinite(p.shape2);
    if (!finite) {
      *why = "start has a non-finite parameter";
      return false;
    }
  }
  return true;
}

bool SelectionOptions::IsValid(std::string* why) const {
  if (!fit.IsValid(why)) return false;
  if (fit.start) {
    *why = "fit.start is for one model's fit: give each candidate's in starts";
    return false;
  }
  if (!starts.empty() && starts.size() != candidates.size()) {
    *why = "starts must be empty or give one (possibly absent) start per candidate";
    return false;
  }
  for (std::size_t c = 0; c < starts.size(); ++c)
    if (starts[c] && starts[c]->model != candidates[c]) {
      *why = std::string("starts[") + std::to_string(c) + "] is a " + ModelName(starts[c]->model) + " point for a " +
             ModelName(candidates[c]) + " candidate";
      return false;
    }
  if (candidates.empty()) {
    *why = "no candidate models";
    return false;
  }
  if (!(min_bic_improvement >= 0.0) || !(peak_theta_h_deg >= 0.0) || !(min_held_out_gain_weighted >= 0.0) ||
      !(min_held_out_gain_log >= 0.0)) {
    *why = "min_bic_improvement, min_held_out_gain_weighted, min_held_out_gain_log and peak_theta_h_deg must be "
           "non-negative";
    return false;
  }
  if (held_out_folds < 0 || held_out_folds == 1) {
    *why = "held_out_folds must be 0 (none) or at least 2";
    return false;
  }
  for (int f : folds)
    if (f < 0 || f >= held_out_folds) {
      *why = "every entry of folds must lie in [0, held_out_folds)";
      return false;
    }
  return true;
}

namespace {

// Checks every sample for `options.loss` and prepares it; false (with
// `summary` ended kInvalidInput naming the sample) at the first bad one.
bool PrepareSamples(const std::vector<BrdfSample>& samples, const FitOptions& options, std::vector<Prepared>* prepared,
                    FitSummary* summary) {
  prepared->clear();
  prepared->reserve(samples.size());
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const BrdfSample& s = samples[k];
    auto refuse = [&](const std::string& why) {
      summary->End(core::Termination::kInvalidInput, "sample " + std::to_string(k) + ": " + why);
      return false;
    };
    if (!s.wi.allFinite() || !s.wo.allFinite() || std::abs(s.wi.norm() - 1.0) > 1e-6 ||
        std::abs(s.wo.norm() - 1.0) > 1e-6)
      return refuse("directions must be finite unit vectors");
    if (s.wi.z() <= 0.0 || s.wo.z() <= 0.0) return refuse("a direction is below the horizon (no BRDF value there)");
    if (!s.value.allFinite() || !s.sigma.allFinite() || (s.sigma.array() < 0.0).any())
      return refuse("value and sigma must be finite, sigma non-negative");
    if (options.loss == FitLoss::kWeighted && (s.sigma.array() <= 0.0).any())
      return refuse("the weighted loss needs sigma > 0 in every channel (use the log loss without deviations)");
    if (options.loss == FitLoss::kLog && (s.value.array() * s.wi.z() <= -1.0).any())
      return refuse("value too negative for the log loss");
    if (!(s.weight > 0.0 && std::isfinite(s.weight))) return refuse("weight must be positive and finite");
    Prepared p{GeometryOf(s.wi, s.wo), s.value, Eigen::Vector3d::Constant(std::sqrt(s.weight))};
    if (options.loss == FitLoss::kWeighted) p.weight = p.weight.cwiseQuotient(s.sigma);
    prepared->push_back(p);
  }
  return true;
}

// The Levenberg-Marquardt problem of one model on some prepared samples, its
// parameter blocks and the account of the solve. `extra`: Cook-Torrance's
// F0 or GGX's scale (extra[0]), or the second lobe (as `lobe`).
struct LeastSquares {
  double kd[3] = {0, 0, 0}, lobe[4] = {0, 0, 0, 0}, extra[4] = {0, 0, 0, 0};
  bool usable = false;     // the solution is finite
  bool converged = false;  // a tolerance, not the iteration limit, ended the solve
  double cost = 0.0;       // sum of squared residuals at the solution
  int iterations = 0;      // steps tried, counting the start as one (as Ceres counts)

  ModelParams Params(Model model) const {
    ModelParams p;
    p.model = model;
    p.diffuse = Eigen::Vector3d(kd[0], kd[1], kd[2]);
    if (model != Model::kLambertian) {
      p.specular = Eigen::Vector3d(lobe[0], lobe[1], lobe[2]);
      p.shape = std::exp(lobe[3]);
      if (model == Model::kCookTorrance) p.fresnel_f0 = extra[0];
      if (model == Model::kGgx) p.specular_scale = extra[0];
    }
    if (HasSecondLobe(model)) {
      p.specular2 = Eigen::Vector3d(extra[0], extra[1], extra[2]);
      p.shape2 = std::exp(extra[3]);
    }
    return p;
  }
  // The blocks as one vector x = (kd, lobe, extra), the solver's layout.
  void Pack(double x[11]) const {
    std::copy(kd, kd + 3, x);
    std::copy(lobe, lobe + 4, x + 3);
    std::copy(extra, extra + 4, x + 7);
  }
};

// f(std::integral_constant<int, P>()) with P = ParameterCount(model): the
// solver's and the Jacobian's fixed sizes.
template <typename F>
void WithParameterCount(Model model, const F& f) {
  switch (ParameterCount(model)) {
    case 3: f(std::integral_constant<int, 3>()); break;
    case 7: f(std::integral_constant<int, 7>()); break;
    case 8: f(std::integral_constant<int, 8>()); break;
    default: f(std::integral_constant<int, 11>()); break;
  }
}

// The bounds of the least squares' parameters, laid out as (kd, lobe,
// extra): weights, GGX's scale and F0 non-negative, GGX's per-channel F0 and
// Cook-Torrance's F0 at most 1, log shapes within RangeOf.
template <int P>
void Bounds(Model model, Eigen::Matrix<double, P, 1>* lower, Eigen::Matrix<double, P, 1>* upper) {
  lower->setZero();
  upper->setConstant(std::numeric_limits<double>::infinity());
  if constexpr (P >= 7) {
    const ShapeRange range = RangeOf(model);
    if (model == Model::kGgx) upper->template segment<3>(3).setOnes();
    (*lower)[6] = std::log(range.min);
    (*upper)[6] = std::log(range.max);
  }
  if constexpr (P == 8)
    if (model == Model::kCookTorrance) (*upper)[7] = 1.0;
  if constexpr (P == 11) {
    (*lower)[10] = (*lower)[6];
    (*upper)[10] = (*upper)[6];
  }
}

// One sample's residuals at x = (kd, lobe, extra), P = ParameterCount(model).
template <int P, typename T>
void Residuals(Model model, const Prepared& p, FitLoss loss, const T* x, T* r) {
  if constexpr (P == 3) {
    SampleResidual(model, p, loss)(x, r);
  } else if constexpr (P == 7) {
    SampleResidual(model, p, loss)(x, x + 3, r);
  } else if constexpr (P == 8) {
    SampleResidual(model, p, loss)(x, x + 3, x + 7, r);
  } else {
    TwoLobeResidual(model, p, loss)(x, x + 3, x + 7, r);
  }
}

// Levenberg-Marquardt on the normal equations, the step projected onto the
// bounds, with Ceres' trust-region rules and tolerances (initial radius 1e4,
// D = diag(J^T J) clamped to [1e-6, 1e32], a step kept when it achieves
// 1e-3 of its predicted decrease; converged when the cost changes by less
// than 1e-6 of itself, the projected gradient's largest component is below
// 1e-10, or the step is below 1e-8 of |x|). Each iteration is one pass over
// the samples with Dual<P> (forward mode, every derivative at once) building
// J^T J and J^T r, no Jacobian stored: 3.4x faster than Ceres' DENSE_QR on
// the same problem (docs/performance.md).
template <int P>
void SolveProjectedLm(Model model, const std::vector<Prepared>& fitted, const FitOptions& options, double* x_out,
                      LeastSquares* ls) {
  using Vector = Eigen::Matrix<double, P, 1>;
  using Matrix = Eigen::Matrix<double, P, P>;
  using Dual = autodiff::Dual<P>;
  Vector lower, upper;
  Bounds<P>(model, &lower, &upper);
  auto cost_of = [&](const Vector& x) {
    double cost = 0.0, r[3];
    for (const Prepared& p : fitted) {
      Residuals<P>(model, p, options.loss, x.data(), r);
      cost += r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
    }
    return cost;
  };
  auto normal_equations = [&](const Vector& x, Matrix* jtj, Vector* jtr) {
    jtj->setZero();
    jtr->setZero();
    Dual xd[P], r[3];
    for (int k = 0; k < P; ++k) xd[k] = Dual(x[k], k);
    for (const Prepared& p : fitted) {
      Residuals<P>(model, p, options.loss, xd, r);
      for (int c = 0; c < 3; ++c) {
        jtj->template selfadjointView<Eigen::Lower>().rankUpdate(r[c].tangent);
        *jtr += r[c].value * r[c].tangent;
      }
    }
    *jtj = jtj->template selfadjointView<Eigen::Lower>();
  };
  Vector x = Eigen::Map<const Vector>(x_out).cwiseMax(lower).cwiseMin(upper);
  double cost = cost_of(x);
  Matrix jtj;
  Vector jtr;
  normal_equations(x, &jtj, &jtr);
  double radius = 1e4, decrease_factor = 2.0;
  ls->iterations = 1;
  ls->converged = false;
  while (ls->iterations <= options.max_iterations && std::isfinite(cost)) {
    if (((x - jtr).cwiseMax(lower).cwiseMin(upper) - x).cwiseAbs().maxCoeff() <= 1e-10) {
      ls->converged = true;
      break;
    }
    ++ls->iterations;
    Matrix damped = jtj;
    damped.diagonal() += jtj.diagonal().cwiseMax(1e-6).cwiseMin(1e32) / radius;
    // A parameter on a bound that the gradient pushes out of stays there this
    // step: solving for it too and projecting afterwards would leave the
    // others a step that counted on it moving.
    Vector rhs = jtr;
    for (int k = 0; k < P; ++k)
      if ((x[k] <= lower[k] && jtr[k] > 0.0) || (x[k] >= upper[k] && jtr[k] < 0.0)) {
        damped.row(k).setZero();
        damped.col(k).setZero();
        damped(k, k) = 1.0;
        rhs[k] = 0.0;
      }
    const Vector trial = (x - damped.ldlt().solve(rhs)).cwiseMax(lower).cwiseMin(upper);
    const Vector step = trial - x;
    if (step.norm() <= 1e-8 * (x.norm() + 1e-8)) {
      ls->converged = true;
      break;
    }
    const double trial_cost = cost_of(trial);
    // The linear model's decrease of the sum of squares along the step taken.
    const double predicted = -(2.0 * jtr.dot(step) + step.dot(jtj * step));
    const double change = cost - trial_cost;
    const bool small = std::abs(change) <= 1e-6 * cost;
    if (std::isfinite(trial_cost) && predicted > 0.0 && change / predicted > 1e-3) {
      const double rho = change / predicted;
      x = trial;
      cost = trial_cost;
      radius = std::min(radius / std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3)), 1e16);
      decrease_factor = 2.0;
      if (small) {
        ls->converged = true;
        break;
      }
      normal_equations(x, &jtj, &jtr);
    } else {
      if (small && std::isfinite(trial_cost)) {
        ls->converged = true;
        break;
      }
      radius /= decrease_factor;
      decrease_factor *= 2.0;
      if (radius < 1e-32) break;
    }
  }
  ls->usable = std::isfinite(cost) && x.allFinite();
  ls->cost = cost;
  Eigen::Map<Vector>{x_out} = x;
}

// The samples the least squares see among those at `indices`: all of them, or
// an evenly spaced subsample of max_fit_samples (a table's grid order makes
// that stratified over theta_h, theta_d and phi_d).
std::vector<Prepared> FittedSubset(const std::vector<Prepared>& prepared, const std::vector<std::size_t>& indices,
                                   std::size_t max_fit_samples) {
  const std::size_t n = indices.size();
  const std::size_t m = max_fit_samples > 0 && n > max_fit_samples ? max_fit_samples : n;
  std::vector<Prepared> fitted;
  fitted.reserve(m);
  for (std::size_t j = 0; j < m; ++j) fitted.push_back(prepared[indices[m == n ? j : j * n / m]]);
  return fitted;
}

// The starting grid sees at most this many of the least squares' samples,
// evenly spaced. It only picks the basin, 41 shapes 1.16x apart with each
// channel's linear weights solved exactly, which the least squares then
// refine on every sample. The grid's cost is linear in its samples; at 5,000
// each grid point's error is still the mean of 15,000 residuals.
constexpr std::size_t kGridSamples = 5000;

// Solves for `model` on `fitted`, from options.start or the starting grid.
void SolveLeastSquares(Model model, const std::vector<Prepared>& fitted, const FitOptions& options, LeastSquares* ls) {
  if (options.start) {
    StartAt(*options.start, ls->kd, ls->lobe, ls->extra);
  } else {
    std::vector<std::size_t> every(fitted.size());
    std::iota(every.begin(), every.end(), std::size_t{0});
    StartingPoint(model, FittedSubset(fitted, every, kGridSamples), ls->kd, ls->lobe, ls->extra);
  }
  double x[11];
  ls->Pack(x);
  WithParameterCount(model, [&](auto p) { SolveProjectedLm<p()>(model, fitted, options, x, ls); });
  const int p = ParameterCount(model);
  std::copy(x, x + 3, ls->kd);
  if (p > 3) std::copy(x + 3, x + 7, ls->lobe);
  if (p > 7) std::copy(x + 7, x + p, ls->extra);
}

// The residuals r and their Jacobian J (3 rows per sample, the columns
// x = (kd, lobe, extra)) at `ls`'s solution: what the covariance and the F0
// score test evaluate. Forward mode, as the solver's normal equations.
struct Linearisation {
  Eigen::VectorXd residuals;
  Eigen::MatrixXd jacobian;
};

Linearisation Linearise(Model model, const std::vector<Prepared>& fitted, FitLoss loss, const LeastSquares& ls) {
  double x[11];
  ls.Pack(x);
  Linearisation at;
  WithParameterCount(model, [&](auto count) {
    constexpr int P = count();
    using Dual = autodiff::Dual<P>;
    Dual xd[P], r[3];
    for (int k = 0; k < P; ++k) xd[k] = Dual(x[k], k);
    at.residuals.resize(3 * static_cast<Eigen::Index>(fitted.size()));
    at.jacobian.resize(at.residuals.size(), P);
    for (std::size_t s = 0; s < fitted.size(); ++s) {
      Residuals<P>(model, fitted[s], loss, xd, r);
      for (int c = 0; c < 3; ++c) {
        const Eigen::Index row = 3 * static_cast<Eigen::Index>(s) + c;
        at.residuals[row] = r[c].value;
        at.jacobian.row(row) = r[c].tangent.transpose();
      }
    }
  });
  return at;
}

// (J^T J)^-1 = V diag(1 / s^2) V^T from the singular values s and right
// singular vectors V of J, taken from the R of J = QR (P x P) rather than
// from J^T J, whose condition number is J's squared. Empty, as Ceres'
// DENSE_SVD with its default min_reciprocal_condition_number (1e-14 on s^2),
// when a singular value is below 1e-7 of the largest: a rank-deficient
// Jacobian gets no invented variance.
std::optional<Eigen::MatrixXd> InverseNormalMatrix(const Eigen::MatrixXd& jacobian) {
  if (!jacobian.allFinite()) return std::nullopt;
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(jacobian);
  const Eigen::MatrixXd r = qr.matrixQR().topRows(jacobian.cols()).triangularView<Eigen::Upper>();
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(r, Eigen::ComputeFullV);
  const Eigen::VectorXd& s = svd.singularValues();
  if (!(s.minCoeff() >= std::sqrt(1e-14) * s.maxCoeff())) return std::nullopt;
  return svd.matrixV() * s.cwiseAbs2().cwiseInverse().asDiagonal() * svd.matrixV().transpose();
}

// One held-out fold of `all` (the fit to every sample): sample k is left out
// when fold_of[k] is `fold`, the fold's fit starts from `all`'s parameters and
// sees at most fit_samples of its samples, and the left-out samples' squared
// residuals go into *errors. False when the fold's fit fails. Needs only the
// fold's parameters, so it computes no covariance and no cost over its
// training set.
bool HeldOutFold(const FitSummary& all, const std::vector<BrdfSample>& samples, const std::vector<Prepared>& prepared,
                 const FitOptions& options, const std::vector<int>& fold_of, int fold, std::size_t fit_samples,
                 std::vector<double>* errors) {
  FitOptions fold_options = options;
  fold_options.start = all.params;
  std::vector<std::size_t> train, held_out;
  train.reserve(samples.size());
  for (std::size_t k = 0; k < samples.size(); ++k) (fold_of[k] == fold ? held_out : train).push_back(k);
  if (held_out.empty()) return true;
  if (train.empty()) return false;
  LeastSquares ls;
  SolveLeastSquares(all.params.model, FittedSubset(prepared, train, fit_samples), fold_options, &ls);
  if (!ls.usable) return false;
  const ModelParams params = ls.Params(all.params.model);
  for (std::size_t k : held_out) (*errors)[k] = SquaredResidual(params, samples[k], options.loss);
  return true;
}

// Indices, in the least squares' parameter vector (kd, lobe, extra), of the
// F0s bounded above by 1: Cook-Torrance's one, GGX's per channel.
std::vector<int> FresnelIndices(Model model) {
  if (model == Model::kCookTorrance) return {7};
  if (model == Model::kGgx) return {3, 4, 5};
  return {};
}

// Whether the loss still falls beyond F0 = 1 at the solution, more than the
// data's noise explains: the score (Lagrange multiplier) test, statistic
// g_i^2 (J^T J)^-1_ii / s^2 with g = J^T r (chi-square with one degree of
// freedom when the bound does not bind; s^2 = 1 for the weighted loss, the
// residual variance for the log loss, at least min_log_residual_variance),
// beyond 4 (two standard deviations)
// with g_i < 0. F0 = 1 itself is a lobe without a Fresnel rise (a table
// made with it does not press); pressing means the data want F0 > 1.
// Returns each F0 index's statistic, 0 where it does not press.
std::vector<double> FresnelScores(Model model, const LeastSquares& ls, const Linearisation& at, const FitOptions& options) {
  const std::vector<int> indices = FresnelIndices(model);
  std::vector<double> scores(indices.size(), 0.0);
  const double* values[] = {&ls.lobe[0], &ls.lobe[1], &ls.lobe[2]};
  bool any = false;
  for (std::size_t j = 0; j < indices.size(); ++j)
    any |= (model == Model::kCookTorrance ? ls.extra[0] : *values[j]) >= 1.0 - 1e-6;
  if (!any) return scores;
  const Eigen::VectorXd gradient = at.jacobian.transpose() * at.residuals;
  const Eigen::MatrixXd jtj = at.jacobian.transpose() * at.jacobian;
  const Eigen::MatrixXd inverse = jtj.completeOrthogonalDecomposition().pseudoInverse();
  const double m = static_cast<double>(at.residuals.size()), parameters = static_cast<double>(at.jacobian.cols());
  const double s2 = options.loss == FitLoss::kWeighted
                        ? 1.0
                        : std::max(at.residuals.squaredNorm() / std::max(1.0, m - parameters),
                                   options.min_log_residual_variance);
  for (std::size_t j = 0; j < indices.size(); ++j) {
    const double value = model == Model::kCookTorrance ? ls.extra[0] : *values[j];
    const int i = indices[j];
    if (value < 1.0 - 1e-6 || !(gradient[i] < 0.0) || !(s2 > 0.0)) continue;
    scores[j] = gradient[i] * gradient[i] * inverse(i, i) / s2;
  }
  return scores;
}

// Sets `at_bound`, `normal_albedo` and `implausible` of a fit at `ls`'s
// solution; a shape at a bound also makes the lobe not identifiable.
void CheckBoundsAndPlausibility(Model model, const LeastSquares& ls, const Linearisation& at, const FitOptions& options,
                                FitSummary* summary) {
  const ModelParams& p = summary->params;
  std::string& at_bound = summary->at_bound;
  auto add = [](std::string* list, const std::string& what) { *list += (list->empty() ? "" : ", ") + what; };
  if (model != Model::kLambertian) {
    const ShapeRange range = RangeOf(model);
    std::vector<double> shapes = {p.shape};
    if (HasSecondLobe(model)) shapes.push_back(p.shape2);
    for (std::size_t j = 0; j < shapes.size(); ++j) {
      // Ceres projects a parameter that wants out onto its bound; 0.1 % covers one that stops just short.
      const bool low = std::abs(std::log(shapes[j] / range.min)) < 1e-3;
      const bool high = std::abs(std::log(shapes[j] / range.max)) < 1e-3;
      if (!low && !high) continue;
      const std::string which = std::string(j == 0 ? "" : "second lobe's ") + ShapeName(model) + " " +
                                Number(shapes[j]) + " at its " + (low ? "lower" : "upper") + " bound";
      add(&at_bound, which);
      summary->lobe_identifiable = false;
      summary->message = std::string("the ") + ModelName(model) + " " + which + " (" + Number(low ? range.min : range.max) +
                         "): the data want a lobe " + (low ? "broader" : "narrower") +
                         " than the range, its width is not identifiable";
    }
  }
  std::string implausible;
  const std::vector<double> scores = FresnelScores(model, ls, at, options);
  for (std::size_t j = 0; j < scores.size(); ++j) {
    if (!(scores[j] > 4.0)) continue;
    const std::string channel = model == Model::kGgx ? std::string(" (") + "RGB"[j] + ")" : "";
    add(&at_bound, "F0" + channel + " pressed against its bound 1 (score " + Number(scores[j]) + ")");
    add(&implausible, "F0" + channel + " pressed against 1: the data want a Fresnel reflectance above 1");
  }
  // Each term on its own reflects at most everything: rho_d <= 1, and the
  // lobes' albedo at normal incidence (where these lobes reflect most) <= 1.
  // Their sum is not held to 1: these additive models do not attenuate the
  // diffuse term by the light the lobe reflects, as a layered surface does,
  // so rho_d here is the diffuse albedo beneath the coat (docs/brdf.md).
  // 1e-3: the quadrature's accuracy.
  ModelParams lobes = p;
  lobes.diffuse.setZero();
  const Eigen::Vector3d lobe_albedo = model == Model::kLambertian ? Eigen::Vector3d::Zero() : NormalAlbedo(lobes);
  summary->normal_albedo = p.diffuse + lobe_albedo;
  auto over_one = [&](const char* what, const Eigen::Vector3d& v) {
    if ((v.array() > 1.0 + 1e-3).any())
      add(&implausible, std::string(what) + " (" + Number(v[0]) + ", " + Number(v[1]) + ", " + Number(v[2]) + ") over 1");
  };
  over_one("diffuse albedo rho_d", p.diffuse);
  over_one("the lobe's albedo at normal incidence", lobe_albedo);
  summary->implausible = implausible;
}

// A fit's summary before the fit: the model and the counts.
FitSummary FitOf(Model model, std::size_t samples) {
  FitSummary summary;
  summary.params.model = model;
  summary.samples = samples;
  summary.residuals = 3 * samples;
  summary.parameters = ParameterCount(model);
  return summary;
}

// FitModel on prepared samples.
FitSummary FitPrepared(Model model, const std::vector<Prepared>& prepared, const FitOptions& options) {
  core::SolveTimer timer;
  FitSummary summary = FitOf(model, prepared.size());
  if (summary.residuals <= static_cast<std::size_t>(summary.parameters)) {
    summary.End(core::Termination::kFailure, std::to_string(prepared.size()) + " samples (" +
                                           std::to_string(summary.residuals) + " values) cannot fit the " +
                                           std::to_string(summary.parameters) + " parameters of " + ModelName(model));
    if (model != Model::kLambertian) summary.lobe_identifiable = false;
    return summary;
  }
  std::vector<std::size_t> every(prepared.size());
  for (std::size_t k = 0; k < every.size(); ++k) every[k] = k;
  const std::vector<Prepared> fitted = FittedSubset(prepared, every, options.max_fit_samples);
  summary.fitted_samples = fitted.size();
  timer.SetupDone(&summary);

  LeastSquares ls;
  SolveLeastSquares(model, fitted, options, &ls);
  summary.iterations = ls.iterations;
  if (!ls.usable) {
    summary.End(core::Termination::kFailure, "the fit failed: the cost is not finite at the start");
    timer.Finish(&summary);
    return summary;
  }
  summary.termination =
      ls.converged ? core::Termination::kSuccess : core::Termination::kNoConvergence;
  summary.cost = ls.cost;
  const double* kd = ls.kd;
  const double* lobe = ls.lobe;
  const double* extra = ls.extra;
  if (fitted.size() < prepared.size()) {
    // The cost of every sample at the subsample's solution.
    summary.cost = 0.0;
    double r[3];
    for (const Prepared& p : prepared) {
      if (HasSecondLobe(model)) {
        TwoLobeResidual(model, p, options.loss)(kd, lobe, extra, r);
      } else if (model == Model::kLambertian) {
        SampleResidual(model, p, options.loss)(kd, r);
      } else {
        SampleResidual(model, p, options.loss)(kd, lobe, extra, r);
      }
      summary.cost += r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
    }
  }
  const double n = static_cast<double>(summary.residuals), k = summary.parameters;
  summary.bic = options.loss == FitLoss::kWeighted ? summary.cost + k * std::log(n)
                                                   : n * std::log(std::max(summary.cost, 1e-300) / n) + k * std::log(n);
  summary.params = ls.Params(model);
  const Linearisation at_solution = Linearise(model, fitted, options.loss, ls);

  // Uncertainties: the inverse of J^T J at the solution (none for a
  // rank-deficient Jacobian rather than an invented variance).
  std::optional<Eigen::MatrixXd> cov = InverseNormalMatrix(at_solution.jacobian);
  if (cov) {
    // A subsample's J^T J is about fitted/all of the whole set's.
    *cov *= static_cast<double>(fitted.size()) / static_cast<double>(prepared.size());
    // The log loss carries no absolute scale: use the residual variance.
    if (options.loss == FitLoss::kLog) *cov *= summary.cost / std::max(1.0, n - k);
    summary.covariance_available = cov->allFinite();
  }
  if (summary.covariance_available) {
    const Eigen::VectorXd sd = cov->diagonal().cwiseMax(0.0).cwiseSqrt();
    summary.diffuse_sigma = sd.head<3>();
    if (model != Model::kLambertian) {
      summary.specular_sigma = sd.segment<3>(3);
      summary.shape_sigma = summary.params.shape * sd[6];  // d shape = shape * d log(shape)
      if (model == Model::kCookTorrance) summary.fresnel_f0_sigma = sd[7];
      if (model == Model::kGgx) summary.specular_scale_sigma = sd[7];
    }
    if (HasSecondLobe(model)) {
      summary.specular2_sigma = sd.segment<3>(7);
      summary.shape2_sigma = summary.params.shape2 * sd[10];
    }
  }
  // The lobes are reported narrower first (the fit's labels are arbitrary).
  if (HasSecondLobe(model) && summary.params.shape2 > summary.params.shape) {
    std::swap(summary.params.specular, summary.params.specular2);
    std::swap(summary.params.shape, summary.params.shape2);
    std::swap(summary.specular_sigma, summary.specular2_sigma);
    std::swap(summary.shape_sigma, summary.shape2_sigma);
  }
  if (model != Model::kLambertian) {
    const double limit = options.max_relative_shape_sigma;
    const bool first = summary.covariance_available && summary.shape_sigma <= limit * summary.params.shape;
    const bool second = !HasSecondLobe(model) ||
                        (summary.covariance_available && summary.shape2_sigma <= limit * summary.params.shape2);
    summary.lobe_identifiable = first && second;
    auto relative = [&](double sigma, double shape) {
      return summary.covariance_available ? Number(sigma / shape) : std::string("unknown: singular covariance");
    };
    if (!first)
      summary.message = std::string("the ") + ModelName(model) +
                        " lobe's shape is not identifiable from these samples (relative sd " +
                        relative(summary.shape_sigma, summary.params.shape) + "); sample nearer the specular peak";
    else if (!second)
      summary.message = std::string("the ") + ModelName(model) +
                        " second lobe is not pinned down by these samples (relative sd of its exponent " +
                        relative(summary.shape2_sigma, summary.params.shape2) +
                        "): the samples support one lobe, or two too alike to separate";
  }
  CheckBoundsAndPlausibility(model, ls, at_solution, options, &summary);
  timer.Finish(&summary);
  return summary;
}

}  // namespace

FitSummary FitModel(Model model, const std::vector<BrdfSample>& samples, const FitOptions& options) {
  core::SolveTimer timer;
  FitSummary summary = FitOf(model, samples.size());
  if (std::string why; !options.IsValid(&why)) {
    summary.End(core::Termination::kInvalidOptions, why);
    return summary;
  }
  if (options.start && options.start->model != model) {
    summary.End(core::Termination::kInvalidOptions, std::string("start is a ") + ModelName(options.start->model) +
                                                  " point, the fit is of " + ModelName(model));
    return summary;
  }
  std::vector<Prepared> prepared;
  if (!PrepareSamples(samples, options, &prepared, &summary)) return summary;
  const double preparation_ms = timer.ElapsedMs();
  FitSummary fit = FitPrepared(model, prepared, options);
  fit.setup_ms += preparation_ms;
  fit.total_ms += preparation_ms;
  return fit;
}

std::optional<std::size_t> ChooseModel(const std::vector<FitSummary>& fits, double min_bic_improvement,
                                       double min_held_out_gain, std::string* reason) {
  // A fit the iteration limit stopped is not at its optimum: its BIC and
  // held-out error do not speak for the model.
  auto trusted = [](const FitSummary& f) {
    return f.termination == core::Termination::kSuccess && f.lobe_identifiable && f.implausible.empty();
  };
  std::string unconverged, implausible;
  for (const FitSummary& f : fits) {
    if (f.termination == core::Termination::kNoConvergence)
      unconverged += std::string(unconverged.empty() ? "" : ", ") + ModelName(f.params.model) + " (" +
                     std::to_string(f.iterations) + " iterations)";
    if (f.IsSolutionUsable() && !f.implausible.empty())
      implausible += std::string(implausible.empty() ? "" : "; ") + ModelName(f.params.model) + " (" + f.implausible + ")";
  }
  if (!unconverged.empty()) unconverged = "; not considered, the fit did not converge: " + unconverged;
  if (!implausible.empty()) unconverged += "; not considered, implausible: " + implausible;
  std::optional<std::size_t> current;
  for (std::size_t i = 0; i < fits.size(); ++i)
    if (trusted(fits[i]) && (!current || fits[i].parameters < fits[*current].parameters ||
                             (fits[i].parameters == fits[*current].parameters && fits[i].bic < fits[*current].bic)))
      current = i;
  if (!current) {
    *reason = "no candidate is converged and identifiable" + unconverged;
    return std::nullopt;
  }
  const auto name = [&](std::size_t i) { return std::string(ModelName(fits[i].params.model)); };
  *reason = name(*current) + " has the fewest parameters";
  // Forward, one step at a time: the fewest parameters, then the lowest BIC.
  const auto better_move = [&](std::size_t i, const std::optional<std::size_t>& other) {
    return !other || fits[i].parameters < fits[*other].parameters ||
           (fits[i].parameters == fits[*other].parameters && fits[i].bic < fits[*other].bic);
  };
  // What kept a more complex model out, reported when nothing better is found.
  std::string refused;
  for (;;) {
    std::optional<std::size_t> next;
    std::string why;
    for (std::size_t i = 0; i < fits.size(); ++i) {
      const FitSummary &f = fits[i], &c = fits[*current];
      if (i == *current || !trusted(f) || f.parameters < c.parameters) continue;
      if (f.parameters == c.parameters) {
        if (!(f.bic < c.bic)) continue;
        if (better_move(i, next)) {
          next = i;
          why = name(i) + ": as many parameters as " + name(*current) + ", BIC lower by " + Number(c.bic - f.bic);
        }
        continue;
      }
      if (!(f.bic < c.bic - min_bic_improvement)) continue;
      std::string held_out;
      if (!f.held_out_errors.empty() && f.held_out_errors.size() == c.held_out_errors.size()) {
        const auto [gain, se] = MeanDifference(c.held_out_errors, f.held_out_errors);
        held_out = ", held-out mean squared error lower by " + Number(gain) + " (" + Number(gain / se) +
                   " standard errors)";
        if (!(gain > se)) {
          refused = "; " + name(i) + "'s BIC is lower by " + Number(c.bic - f.bic) +
                    " but its held-out error is not lower by more than one standard error (" +
                    Number(gain / se) + "): not chosen";
          continue;
        }
        if (!(gain > min_held_out_gain)) {
          refused = "; " + name(i) + "'s BIC is lower by " + Number(c.bic - f.bic) +
                    " but its held-out mean squared error is lower by only " + Number(gain) +
                    ", within what the data resolve (" + Number(min_held_out_gain) + "): not chosen";
          continue;
        }
      }
      if (better_move(i, next)) {
        next = i;
        why = name(i) + ": BIC lower than " + name(*current) + "'s by " + Number(c.bic - f.bic) + held_out;
      }
    }
    if (!next) break;
    current = next;
    *reason = why;
    refused.clear();
  }
  *reason += refused;
  if (refused.empty()) *reason += "; no other model improves on it";
  *reason += unconverged;
  return current;
}

SelectionSummary SelectModel(const std::vector<BrdfSample>& samples, const SelectionOptions& options) {
  core::SolveTimer timer;
  SelectionSummary summary;
  if (std::string why; !options.IsValid(&why)) {
    summary.End(core::Termination::kInvalidOptions, why);
    return summary;
  }
  if (samples.empty()) {
    summary.End(core::Termination::kInvalidInput, "no samples");
    return summary;
  }
  // A channel without one positive value saw no reflection: every model
  // would fit it with zero albedo and call that a success.
  for (int c = 0; c < 3; ++c)
    if (std::none_of(samples.begin(), samples.end(), [c](const BrdfSample& s) { return s.value[c] > 0.0; })) {
      summary.End(core::Termination::kInvalidInput,
                  std::string("no sample has a positive ") + "RGB"[c] +
                      " value: the measurement saw no light reflected (check the exposure, the lights and the dark "
                      "frames)");
      return summary;
    }
  if (!options.folds.empty() && options.folds.size() != samples.size()) {
    summary.End(core::Termination::kInvalidOptions, "folds gives " + std::to_string(options.folds.size()) +
                                                      " samples' folds for " + std::to_string(samples.size()) +
                                                      " samples");
    return summary;
  }
  double min_theta_h = M_PI;
  for (const BrdfSample& s : samples)
    if (s.wi.allFinite() && s.wo.allFinite() && (s.wi + s.wo).norm() > 0.0)
      min_theta_h = std::min(min_theta_h, std::acos(std::clamp((s.wi + s.wo).normalized().z(), -1.0, 1.0)));
  summary.min_theta_h_deg = min_theta_h * 180.0 / M_PI;
  summary.peak_sampled = summary.min_theta_h_deg < options.peak_theta_h_deg;

  // The samples are checked and prepared once for every candidate and fold.
  std::vector<Prepared> prepared;
  {
    FitSummary refused;
    if (!PrepareSamples(samples, options.fit, &prepared, &refused)) {
      summary.End(refused.termination, refused.message);
      return summary;
    }
  }
  timer.SetupDone(&summary);

  // The candidates' fits, then their folds, each as one parallel loop: a
  // whole table's fits take from 0.1 to 1 s each, so a loop per candidate
  // would leave a core idle. Progress is reported from this thread, after
  // each loop (stage "fit": the candidates, then "held-out": the folds).
  const int candidates = static_cast<int>(options.candidates.size());
  summary.candidates.resize(options.candidates.size());
#pragma omp parallel for schedule(dynamic)
  for (int c = 0; c < candidates; ++c) {
    FitOptions fit = options.fit;
    if (!options.starts.empty()) fit.start = options.starts[c];
    summary.candidates[c] = FitPrepared(options.candidates[c], prepared, fit);
  }
  if (options.progress) options.progress({"fit", candidates, candidates, {}});
  const int folds = options.held_out_folds;
  if (folds > 0) {
    const std::size_t fit_samples = options.fold_fit_samples > 0 ? options.fold_fit_samples : options.fit.max_fit_samples;
    std::vector<int> fold_of = options.folds;
    if (fold_of.empty())
      for (std::size_t k = 0; k < samples.size(); ++k) fold_of.push_back(static_cast<int>(k % folds));
    std::vector<std::vector<double>> errors(options.candidates.size());
    std::vector<char> failed(static_cast<std::size_t>(candidates) * folds, 0);  // per task
    for (int c = 0; c < candidates; ++c)
      if (summary.candidates[c].IsSolutionUsable()) errors[c].assign(samples.size(), 0.0);
#pragma omp parallel for schedule(dynamic)
    for (int task = 0; task < candidates * folds; ++task) {
      const int c = task / folds, fold = task % folds;
      if (errors[c].empty()) continue;
      if (!HeldOutFold(summary.candidates[c], samples, prepared, options.fit, fold_of, fold, fit_samples, &errors[c]))
        failed[task] = 1;
    }
    for (int c = 0; c < candidates; ++c) {
      const auto first = failed.begin() + static_cast<std::ptrdiff_t>(c) * folds;
      if (errors[c].empty() || std::find(first, first + folds, 1) != first + folds) continue;
      FitSummary& fit = summary.candidates[c];
      fit.held_out_errors = std::move(errors[c]);
      double sum = 0.0;
      for (double e : fit.held_out_errors) sum += e;
      fit.held_out_rms = std::sqrt(sum / static_cast<double>(fit.held_out_errors.size()));
    }
    if (options.progress) options.progress({"held-out", candidates * folds, candidates * folds, {}});
  }
  const double min_held_out_gain = options.fit.loss == FitLoss::kWeighted ? options.min_held_out_gain_weighted
                                                                           : options.min_held_out_gain_log;
  const std::optional<std::size_t> choice =
      ChooseModel(summary.candidates, options.min_bic_improvement, min_held_out_gain, &summary.reason);
  if (!choice) {
    summary.End(core::Termination::kFailure, "no candidate model gives a converged, identifiable fit to " +
                                           std::to_string(samples.size()) + " samples (" + summary.reason + ")");
    timer.Finish(&summary);
    return summary;
  }
  const std::size_t chosen = *choice;
  summary.chosen = summary.candidates[chosen].params.model;
  summary.chosen_index = chosen;
  // (A second lobe not pinned down is not this: the first is, and one-lobe
  // candidates stand for it.) "Far better" is what a step of ChooseModel
  // asks: the BIC margin and, with held-out errors, a held-out gain beyond
  // what the data resolve (on a noise-free table the log loss's BIC parts
  // fits by rounding).
  const FitSummary& chosen_fit = summary.candidates[chosen];
  auto far_better = [&](const FitSummary& f) {
    if (!(f.bic < chosen_fit.bic - options.min_bic_improvement)) return false;
    if (f.held_out_errors.empty() || f.held_out_errors.size() != chosen_fit.held_out_errors.size()) return true;
    return MeanDifference(chosen_fit.held_out_errors, f.held_out_errors).first > min_held_out_gain;
  };
  for (const FitSummary& f : summary.candidates)
    if (f.IsSolutionUsable() && !f.lobe_identifiable && !HasSecondLobe(f.params.model) && far_better(f)) {
      summary.End(core::Termination::kFailure,
                  std::string("the samples show a lobe (") + ModelName(f.params.model) + " fits far better than " +
                      ModelName(*summary.chosen) + ") but not its width; " +
                      (f.at_bound.empty() ? "sample nearer the specular peak (closest theta_h " +
                                                std::to_string(summary.min_theta_h_deg) + " deg)"
                                          : f.message));
      timer.Finish(&summary);
      return summary;
    }
  summary.termination = core::Termination::kSuccess;
  if (!summary.peak_sampled)
    summary.message = "no sample near the specular peak (closest theta_h " + std::to_string(summary.min_theta_h_deg) +
                      " deg): a lobe narrower than that cannot be ruled out";
  timer.Finish(&summary);
  return summary;
}

}  // namespace photorig::solvers::brdf
