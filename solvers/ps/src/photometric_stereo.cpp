#include "photorig/ps/photometric_stereo.h"

#include "kernels/blinn_phong_fit.h"
#include "lambertian_tiles.h"
#include "model_selection.h"
#include "noise_estimate.h"
#include "kernels/lambertian_recheck.h"
#include "kernels/irls_lambertian_fit.h"
#include "kernels/trimmed_lambertian_fit.h"

#include <Eigen/Dense>
#include <omp.h>

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <vector>

namespace photorig::ps {
namespace {

using Clock = std::chrono::steady_clock;
double MillisecondsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// The usable samples of one pixel in solver units: b_k = (I_k - D) / s_k with
// variance var_k = Var(I_k - D) / s_k^2.
struct PixelSamples {
  std::vector<double> b, variance;
  std::vector<Eigen::Vector3d> w;
  std::vector<int> light;
  std::vector<double> row_observed, row_inverse_sigma;  // every light's, while gathering
  int size() const { return static_cast<int>(b.size()); }
};

// One pixel's samples over every light: b = (I - D) / s, 1 / sigma with
// sigma^2 = Var(I - D) / s^2 (0 for a shadowed or clipped sample, whose b is
// 0), and chi-square of the Lambertian solution x on the usable samples.
// Plain arrays, so the loop vectorises; the raw values are read beforehand
// (GCC does not vectorise a load through a per-lane pointer, and a loop with
// one stays scalar throughout).
struct RowInputs {
  int lights;
  const float* const* planes;
  const float* dark;  // null: no dark frame
  double shadow_threshold, saturation_level;
  const double* scales;
  const double* inverse_scales;
  double read_variance, shot_gain;
  const double* directions;  // 3 per light
};

// `observed` holds the raw values I on entry, dark is D.
PHOTORIG_PS_MULTIVERSION
void ReadRow(const RowInputs& in, double dark, const double* x, double* observed, double* inverse_sigma, double* chi2,
             int* usable) {
  const double x0 = x[0], x1 = x[1], x2 = x[2];
  // Fields in locals and one reduction type: otherwise GCC 12 leaves the loop scalar.
  const double* scales = in.scales;
  const double* inverse_scales = in.inverse_scales;
  const double* directions = in.directions;
  const double shadow = in.shadow_threshold, saturation = in.saturation_level;
  const double read_variance = in.read_variance, gain = in.shot_gain;
  const double* values = observed;
  double sum = 0.0, count = 0.0;
#pragma omp simd reduction(+ : sum, count)
  for (int k = 0; k < in.lights; ++k) {
    const double value = values[k];
    const double signal = value - dark;
    const bool ok = (signal > shadow) & (value < saturation);
    // b = signal / s has sigma sqrt(var(I)) / s. The square root and division
    // were most of this loop's time in double; a weight needs no more than
    // float's 7 digits, and float's are several times faster.
    const double b = ok ? signal * inverse_scales[k] : 0.0;
    const float variance = static_cast<float>(read_variance + gain * std::max(signal, 0.0));
    const double inverse = ok ? double(static_cast<float>(scales[k]) / std::sqrt(variance)) : 0.0;
    observed[k] = b;
    inverse_sigma[k] = inverse;
    const double r = (b - directions[3 * k] * x0 - directions[3 * k + 1] * x1 - directions[3 * k + 2] * x2) * inverse;
    sum += r * r;
    count += ok ? 1.0 : 0.0;
  }
  *chi2 = sum;
  *usable = static_cast<int>(count);
}

// Marks the solved pixels of a tile whose Lambertian confidence is below
// threshold[usable samples] (they need a closer look); returns how many
// solved pixels pass.
PHOTORIG_PS_MULTIVERSION
std::size_t ScreenTile(const std::uint8_t* flags, const std::uint16_t* usable, const float* confidence, int count,
                       const float* threshold, std::uint8_t* needs_refit) {
  int passed = 0;
#pragma omp simd reduction(+ : passed)
  for (int i = 0; i < count; ++i) {
    const bool solved = flags[i] == static_cast<std::uint8_t>(PixelFlag::kSolved);
    const bool pass = confidence[i] >= threshold[usable[i]];
    needs_refit[i] = solved & !pass;
    passed += solved & pass;
  }
  return static_cast<std::size_t>(passed);
}

struct Fit {
  bool ok = false;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  double albedo = 0.0;
  double specular_albedo = 0.0, exponent = 0.0;
  double chi2 = 0.0;     // sum of squared residuals over variance, on the samples used
  int parameters = 3;
  int used = 0;          // samples with weight >= inlier threshold (all for least squares)
  int rejected = 0;
  PixelModel model = PixelModel::kLambertian;

  double Bic() const { return chi2 + parameters * std::log(std::max(used, 1)); }
  int Dof() const { return used - parameters; }
};

Fit LambertianFromX(const PixelSamples& s, const Eigen::Vector3d& x, const std::vector<double>* weight,
                    double inlier_weight) {
  Fit fit;
  const double length = x.norm();
  if (!(length > 0.0)) return fit;
  fit.ok = true;
  fit.normal = x / length;
  fit.albedo = M_PI * length;
  for (int k = 0; k < s.size(); ++k) {
    if (weight && (*weight)[k] < inlier_weight) {
      ++fit.rejected;
      continue;
    }
    const double r = s.b[k] - s.w[k].dot(x);
    fit.chi2 += r * r / s.variance[k];
    ++fit.used;
  }
  return fit;
}

// The Lambertian fit x of a pixel with its chi-square on `used` samples,
// `rejected` of its usable ones left out.
Fit LambertianFit(const Eigen::Vector3d& x, double chi2, int used, int rejected) {
  Fit fit;
  fit.ok = x.norm() > 0.0;
  fit.normal = x.normalized();
  fit.albedo = M_PI * x.norm();
  fit.chi2 = chi2;
  fit.used = used;
  fit.rejected = rejected;
  return fit;
}

// The `robust` fit of a pixel from its IRLS solution.
Fit RobustFit(const internal::RobustSolution& solution) {
  Fit fit;
  fit.model = PixelModel::kRobust;
  fit.ok = solution.ok;
  if (!fit.ok) return fit;
  fit.normal = solution.x.normalized();
  fit.albedo = M_PI * solution.x.norm();
  fit.chi2 = solution.chi2;
  fit.used = solution.used;
  fit.rejected = solution.rejected;
  return fit;
}

// FitLit's pass over every light's sample (a row as ReadRow writes it: b, and
// 1 / sigma, 0 where unusable): the normal equations of the usable samples
// the solution x lights (w . x > 0), chi-square of x on them, how many usable
// samples x leaves in attached shadow or, compared with the solution
// `previous`, moves across the terminator, and the largest squared
// standardised residual of x among the lit and among the unlit samples.
struct LitSums {
  double gxx = 0, gyy = 0, gzz = 0, gxy = 0, gxz = 0, gyz = 0, rx = 0, ry = 0, rz = 0;
  double chi2 = 0, used = 0, unlit = 0, moved = 0;
  double worst_lit = 0, worst_unlit = 0;
};

PHOTORIG_PS_MULTIVERSION
LitSums SumLitSamples(int lights, const double* wx, const double* wy, const double* wz, const double* observed,
                      const double* inverse_sigma, const double* x, const double* previous) {
  const double x0 = x[0], x1 = x[1], x2 = x[2], p0 = previous[0], p1 = previous[1], p2 = previous[2];
  double gxx = 0, gyy = 0, gzz = 0, gxy = 0, gxz = 0, gyz = 0, rx = 0, ry = 0, rz = 0;
  double chi2 = 0, used = 0, unlit = 0, moved = 0, worst_lit = 0, worst_unlit = 0;
#pragma omp simd reduction(+ : gxx, gyy, gzz, gxy, gxz, gyz, rx, ry, rz, chi2, used, unlit, moved) \
    reduction(max : worst_lit, worst_unlit)
  for (int k = 0; k < lights; ++k) {
    const double usable = inverse_sigma[k] != 0.0 ? 1.0 : 0.0;
    const double prediction = wx[k] * x0 + wy[k] * x1 + wz[k] * x2;
    const double lit = prediction > 0.0 ? usable : 0.0;
    const double was_lit = wx[k] * p0 + wy[k] * p1 + wz[k] * p2 > 0.0 ? usable : 0.0;
    const double u = inverse_sigma[k] * (observed[k] - prediction), u2 = u * u;  // 0 where unusable
    const double b = lit * observed[k];
    gxx += lit * wx[k] * wx[k], gyy += lit * wy[k] * wy[k], gzz += lit * wz[k] * wz[k];
    gxy += lit * wx[k] * wy[k], gxz += lit * wx[k] * wz[k], gyz += lit * wy[k] * wz[k];
    rx += b * wx[k], ry += b * wy[k], rz += b * wz[k];
    chi2 += lit * u2;
    used += lit;
    unlit += usable - lit;
    moved += lit != was_lit ? 1.0 : 0.0;
    worst_lit = std::max(worst_lit, lit * u2);
    worst_unlit = std::max(worst_unlit, (usable - lit) * u2);
  }
  return {gxx, gyy, gzz, gxy, gxz, gyz, rx, ry, rz, chi2, used, unlit, moved, worst_lit, worst_unlit};
}

// The Lambertian fit of a pixel on its usable samples that the fit itself
// lights. A sample of a light behind the surface's tangent plane (w . n <= 0)
// can only be dark: where one is usable, read noise lifted it over the shadow
// threshold, and least squares, which knows no max(0, w . n), pulls the
// normal towards it. Such samples are dropped and the rest refitted once; the
// refit stands if it lights exactly the samples it was fitted to. It is tried
// only where one of them is the fit's worst misfit: a glossy pixel's worst
// residuals are its highlight's, which dropping shadow samples would not
// mend (there the trimming stage decides). False also where the refit moves
// samples across the terminator or the remaining lights are worse
// conditioned than max_condition. RecheckLanes runs the same test in float
// lanes.
bool FitLit(int lights, const double* wx, const double* wy, const double* wz, const double* observed,
            const double* inverse_sigma, const Eigen::Vector3d& x, double max_condition, Fit* fit) {
  const LitSums before = SumLitSamples(lights, wx, wy, wz, observed, inverse_sigma, x.data(), x.data());
  if (before.unlit == 0.0 || before.worst_unlit < before.worst_lit || before.used < 4.0) return false;
  Eigen::Matrix3d g;
  g << before.gxx, before.gxy, before.gxz, before.gxy, before.gyy, before.gyz, before.gxz, before.gyz, before.gzz;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen;
  eigen.computeDirect(g, Eigen::EigenvaluesOnly);
  const Eigen::Vector3d lambda = eigen.eigenvalues();  // ascending; cond(A)^2 = cond(G)
  if (!(lambda(0) > 0.0) || !(lambda(2) <= max_condition * max_condition * lambda(0))) return false;
  const Eigen::Vector3d refit = g.ldlt().solve(Eigen::Vector3d(before.rx, before.ry, before.rz));
  const LitSums after = SumLitSamples(lights, wx, wy, wz, observed, inverse_sigma, refit.data(), x.data());
  if (after.moved != 0.0 || !(refit.norm() > 0.0)) return false;
  *fit = LambertianFit(refit, after.chi2, static_cast<int>(after.used), static_cast<int>(after.unlit));
  return true;
}

// A stack's samples, pixel by pixel.
class SampleReader {
 public:
  SampleReader(const PhotometricStack& stack, const LambertianOptions& thresholds)
      : stack_(stack), max_condition_(thresholds.max_condition_number) {
    for (int k = 0; k < stack.light_count(); ++k) {
      planes_.push_back(stack.images[k].ptr<float>());
      inverse_scales_.push_back(1.0 / stack.light_scales[k]);
      for (int i = 0; i < 3; ++i) {
        directions_.push_back(stack.light_directions[k][i]);
        direction_axes_[i].push_back(stack.light_directions[k][i]);
      }
    }
    inputs_ = {stack.light_count(), planes_.data(), stack.dark.empty() ? nullptr : stack.dark.ptr<float>(),
               thresholds.shadow_threshold, thresholds.saturation_level, stack.light_scales.data(),
               inverse_scales_.data(), stack.noise.read_sigma * stack.noise.read_sigma, stack.noise.shot_gain,
               directions_.data()};
  }

  int lights() const { return inputs_.lights; }

  // FitLit on a row of this stack's samples.
  bool FitLit(const double* observed, const double* inverse_sigma, const Eigen::Vector3d& x, Fit* fit) const {
    return photorig::ps::FitLit(lights(), direction_axes_[0].data(), direction_axes_[1].data(),
                                direction_axes_[2].data(), observed, inverse_sigma, x, max_condition_, fit);
  }

  // Every light's sample (see ReadRow); returns chi-square at x.
  double Row(int pixel, const Eigen::Vector3d& x, double* observed, double* inverse_sigma, int* usable) const {
    for (int k = 0; k < lights(); ++k) observed[k] = inputs_.planes[k][pixel];
    double chi2 = 0.0;
    ReadRow(inputs_, inputs_.dark ? inputs_.dark[pixel] : 0.0, x.data(), observed, inverse_sigma, &chi2, usable);
    return chi2;
  }
  // The same from a pixel's raw samples as TrimmedLambertianLanes::CopySamples
  // wrote them: every light's value, then the dark frame's.
  double RowFromSamples(const float* samples, const Eigen::Vector3d& x, double* observed, double* inverse_sigma,
                        int* usable) const {
    for (int k = 0; k < lights(); ++k) observed[k] = samples[k];
    double chi2 = 0.0;
    ReadRow(inputs_, samples[lights()], x.data(), observed, inverse_sigma, &chi2, usable);
    return chi2;
  }

  // The usable samples only.
  void Usable(int pixel, PixelSamples* out) const {
    int usable = 0;
    out->row_observed.resize(lights());
    out->row_inverse_sigma.resize(lights());
    const double* observed = out->row_observed.data();
    const double* inverse_sigma = out->row_inverse_sigma.data();
    Row(pixel, Eigen::Vector3d::Zero(), out->row_observed.data(), out->row_inverse_sigma.data(), &usable);
    const std::vector<Eigen::Vector3d>& light_directions = stack_.light_directions;
    out->b.clear();
    out->variance.clear();
    out->w.clear();
    out->light.clear();
    for (int k = 0; k < lights(); ++k) {
      if (inverse_sigma[k] == 0.0) continue;
      out->b.push_back(observed[k]);
      out->variance.push_back(1.0 / (inverse_sigma[k] * inverse_sigma[k]));
      out->w.push_back(light_directions[k]);
      out->light.push_back(k);
    }
  }

 private:
  const PhotometricStack& stack_;  // must outlive the reader
  std::vector<const float*> planes_;
  std::vector<double> directions_;  // the stack's, 3 per light
  std::array<std::vector<double>, 3> direction_axes_;  // the same, one array per axis
  double max_condition_;
  std::vector<double> inverse_scales_;  // 1 / s_k
  RowInputs inputs_;
};

// The samples of one pixel as plain arrays, for loops the compiler vectorises.
struct TrimScratch {
  std::vector<double> wx, wy, wz, b, inverse_variance, u2;
};

// Trimming, the cheap robust stage of kAuto: drop the samples TrimThreshold
// picks (the worst alone, or all gross outliers of a round together) and
// refit (rank-one downdates of the 3 x 3 normal equations), until the fit is
// adequate; a pixel that would have to drop more than `max_rejected` samples
// keeps its inadequate fit. Highlights are a few huge residuals, so this
// usually stops after one or two rounds at O(n) each, where IRLS needs ~10
// weighted passes. The per-pixel reference of TrimmedLambertianLanes.
template <typename Adequate>
Fit FitTrimmed(const PixelSamples& s, int max_rejected, double gross_u2, const Adequate& adequate, TrimScratch* t) {
  const int n = s.size();
  for (std::vector<double>* v : {&t->wx, &t->wy, &t->wz, &t->b, &t->inverse_variance, &t->u2}) v->resize(n);
  double* __restrict wx = t->wx.data();
  double* __restrict wy = t->wy.data();
  double* __restrict wz = t->wz.data();
  double* __restrict b = t->b.data();
  double* __restrict iv = t->inverse_variance.data();  // 0 once a sample is trimmed
  double* __restrict u2 = t->u2.data();
  for (int k = 0; k < n; ++k) {
    wx[k] = s.w[k].x(), wy[k] = s.w[k].y(), wz[k] = s.w[k].z();
    b[k] = s.b[k], iv[k] = 1.0 / s.variance[k];
  }
  double xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0, bx = 0, by = 0, bz = 0;
#pragma omp simd reduction(+ : xx, xy, xz, yy, yz, zz, bx, by, bz)
  for (int k = 0; k < n; ++k) {
    xx += iv[k] * wx[k] * wx[k], xy += iv[k] * wx[k] * wy[k], xz += iv[k] * wx[k] * wz[k];
    yy += iv[k] * wy[k] * wy[k], yz += iv[k] * wy[k] * wz[k], zz += iv[k] * wz[k] * wz[k];
    bx += iv[k] * b[k] * wx[k], by += iv[k] * b[k] * wy[k], bz += iv[k] * b[k] * wz[k];
  }
  for (int removed = 0;;) {
    Eigen::Matrix3d normal_matrix;
    normal_matrix << xx, xy, xz, xy, yy, yz, xz, yz, zz;
    // A singular system gives a non-finite x, which fails the check below.
    const Eigen::Vector3d x = normal_matrix.inverse() * Eigen::Vector3d(bx, by, bz);
    Fit fit;
    fit.model = PixelModel::kRobust;
    fit.ok = x.norm() > 0.0 && n - removed >= 3;
    if (!fit.ok) return fit;
    fit.normal = x.normalized();
    fit.albedo = M_PI * x.norm();
    double chi2 = 0.0, worst_u2 = 0.0;
#pragma omp simd reduction(+ : chi2) reduction(max : worst_u2)
    for (int k = 0; k < n; ++k) {
      const double r = b[k] - wx[k] * x.x() - wy[k] * x.y() - wz[k] * x.z();
      u2[k] = r * r * iv[k];
      chi2 += u2[k];
      worst_u2 = std::max(worst_u2, u2[k]);
    }
    fit.chi2 = chi2;
    fit.used = n - removed;
    fit.rejected = removed;
    if (adequate(fit)) return fit;
    // Trimmed samples have u2 = 0, below any threshold that drops something.
    const double threshold = internal::TrimThreshold(worst_u2, gross_u2);
    const int drop = static_cast<int>(std::count_if(u2, u2 + n, [threshold](double u) { return u >= threshold; }));
    if (!(threshold > 0.0) || removed + drop > max_rejected || fit.used - drop < 3) return fit;
    for (int k = 0; k < n; ++k) {
      if (!(u2[k] >= threshold)) continue;
      const double c = iv[k];
      xx -= c * wx[k] * wx[k], xy -= c * wx[k] * wy[k], xz -= c * wx[k] * wz[k];
      yy -= c * wy[k] * wy[k], yz -= c * wy[k] * wz[k], zz -= c * wz[k] * wz[k];
      bx -= c * b[k] * wx[k], by -= c * b[k] * wy[k], bz -= c * b[k] * wz[k];
      iv[k] = 0.0;
    }
    removed += drop;
  }
}

// The normal's two degrees of freedom, rho_d, rho_s and e.
constexpr int kBlinnPhongParameters = 5;

Fit FitBlinnPhong(const PixelSamples& s, const Eigen::Vector3d& view, const Fit& start,
                  const BlinnPhongOptions& options, autodiff::Tape* tape) {
  const int n = s.size();
  Eigen::Matrix<double, Eigen::Dynamic, 3> directions(n, 3);
  Eigen::VectorXd observed(n), inverse_sigma(n);
  for (int k = 0; k < n; ++k) {
    directions.row(k) = s.w[k].transpose();
    observed[k] = s.b[k];
    inverse_sigma[k] = 1.0 / std::sqrt(s.variance[k]);
  }
  const autodiff::BlinnPhongPixel pixel(directions, Eigen::VectorXd::Ones(n), view, observed);

  // Start: the normal of the robust fit and the material of the best point
  // of the exponent grid.
  std::vector<double> cos_light(n), cos_half(n), weight(n);
  for (int k = 0; k < n; ++k) {
    cos_light[k] = std::max(0.0, s.w[k].dot(start.normal));
    cos_half[k] = std::max(0.0, pixel.half_vector(k).dot(start.normal));
    weight[k] = 1.0 / s.variance[k];
  }
  const internal::BlinnPhongMaterial material = internal::BlinnPhongGridStart(
      n, cos_light.data(), cos_half.data(), s.b.data(), weight.data(), start.albedo, options);
  Eigen::Matrix<double, 6, 1> p;
  p << start.normal, material.diffuse_albedo, material.specular_albedo, material.exponent;
  auto project = [&options](Eigen::Matrix<double, 6, 1>* q) {
    q->head<3>().normalize();
    (*q)(3) = std::max(0.0, (*q)(3));
    (*q)(4) = std::max(0.0, (*q)(4));
    (*q)(5) = std::clamp((*q)(5), options.min_exponent, options.max_exponent);
  };
  Eigen::VectorXd residuals;
  Eigen::MatrixXd jacobian;
  auto cost_at = [&](const Eigen::Matrix<double, 6, 1>& q, bool with_jacobian, double* cost) {
    bool ok;
    if (with_jacobian) {
      ok = autodiff::BlinnPhongResidualsAndJacobian(pixel, q.data(), options.derivative, &residuals, &jacobian, tape);
    } else {
      residuals.resize(n);
      ok = pixel(q.data(), residuals.data());
    }
    if (ok) *cost = residuals.cwiseProduct(inverse_sigma).squaredNorm();
    return ok;
  };
  double cost = 0.0;
  if (!cost_at(p, true, &cost)) return Fit{};
  double lambda = 1e-3;
  Eigen::Matrix<double, Eigen::Dynamic, 6> jw;  // fixed width: J^T J without a general GEMM
  Eigen::VectorXd rw;
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    jw = inverse_sigma.asDiagonal() * jacobian;
    rw = residuals.cwiseProduct(inverse_sigma);
    // Coefficient-wise products: for 6 columns and tens of rows a general
    // matrix product's packing costs more than the arithmetic.
    const Eigen::Matrix<double, 6, 6> h = jw.transpose().lazyProduct(jw);
    const Eigen::Matrix<double, 6, 1> g = jw.transpose().lazyProduct(rw);
    bool improved = false;
    while (lambda < 1e12) {
      Eigen::Matrix<double, 6, 6> damped = h;
      damped.diagonal() += lambda * h.diagonal() + Eigen::Matrix<double, 6, 1>::Constant(1e-12);
      Eigen::Matrix<double, 6, 1> candidate = p - damped.ldlt().solve(g);
      project(&candidate);
      double candidate_cost = 0.0;
      if (cost_at(candidate, false, &candidate_cost) && candidate_cost < cost) {
        const double decrease = (cost - candidate_cost) / std::max(cost, 1e-300);
        p = candidate;
        cost = candidate_cost;
        lambda = std::max(lambda / 3.0, 1e-12);
        // A step that lowers chi-square by less than this fraction changes
        // the normal by far less than the noise does: stop there.
        improved = decrease > options.relative_tolerance;
        break;
      }
      lambda *= 4.0;
    }
    if (!improved || !cost_at(p, true, &cost)) break;
  }
  Fit fit;
  fit.ok = std::isfinite(cost);
  fit.normal = p.head<3>().normalized();
  fit.albedo = p(3);
  fit.specular_albedo = p(4);
  fit.exponent = p(5);
  fit.chi2 = cost;
  fit.parameters = kBlinnPhongParameters;
  fit.used = n;
  fit.model = PixelModel::kBlinnPhong;
  return fit;
}

void WriteFit(int pixel, const Fit& fit, NormalMap* out) {
  out->normals.ptr<cv::Vec3f>()[pixel] = cv::Vec3f(float(fit.normal.x()), float(fit.normal.y()), float(fit.normal.z()));
  out->albedo.ptr<float>()[pixel] = static_cast<float>(fit.albedo);
  out->model.ptr<std::uint8_t>()[pixel] = static_cast<std::uint8_t>(fit.model);
  out->specular.ptr<cv::Vec2f>()[pixel] = cv::Vec2f(float(fit.specular_albedo), float(fit.exponent));
  out->usable_lights.ptr<std::uint16_t>()[pixel] = static_cast<std::uint16_t>(fit.used);
  // chi2 / dof is the residual variance relative to the noise: confidence = its
  // inverse, capped; 0 for a fit with no degree of freedom left to test it.
  const int dof = fit.Dof();
  out->confidence.ptr<float>()[pixel] =
      dof > 0 ? static_cast<float>(std::min(1.0, 1.0 / std::max(fit.chi2 / dof, 1e-12))) : 0.0f;
}

}  // namespace

SolverSummary SolvePhotometricStereo(const PhotometricStereoOptions& options, const PhotometricStack& stack,
                                     NormalMap* result) {
  const auto start = Clock::now();
  std::string why;
  if (!options.IsValid(&why)) {
    SolverSummary summary;
    summary.method = MethodName(options.method);
    summary.message = "invalid options: " + why;
    return summary;
  }
  LambertianOptions lambertian = options.lambertian;
  lambertian.exclude_unusable_samples = options.method != Method::kL2;
  // The adequacy tests need the noise; what the stack does not give is
  // estimated from the data first, so that the Lambertian pass can already
  // judge its own fits (its confidence) and spare them a second look.
  PhotometricStack working = stack;
  const bool refine = options.method == Method::kRobust || options.method == Method::kBlinnPhong ||
                      options.method == Method::kAuto;
  // A shadow threshold in read-noise sigmas needs the read noise; `l2` uses
  // every sample whatever the threshold, so it is not estimated for `l2`.
  const bool read_noise_wanted = options.shadow_threshold_read_sigmas > 0.0 && options.method != Method::kL2 &&
                                 !(stack.noise.read_sigma > 0.0);
  const bool estimable = options.estimate_noise && stack.IsValid(nullptr) && lambertian.IsValid(nullptr);
  bool noise_estimated = false;
  if (estimable && ((refine && stack.noise.shot_gain == 0.0) || read_noise_wanted)) {
    working.noise = internal::EstimateNoise(stack, lambertian);
    noise_estimated = true;
  }
  const double absolute_threshold = lambertian.shadow_threshold;
  auto raise_threshold = [&] {
    lambertian.shadow_threshold =
        std::max(absolute_threshold, options.shadow_threshold_read_sigmas * working.noise.read_sigma);
  };
  raise_threshold();
  // An estimated read noise came from fits of the samples just above the
  // absolute threshold, shadows lifted by noise among them: it is estimated
  // once more without them, and the threshold taken from that (a third round
  // moved the estimate by under 2 % on re-imported simulated runs).
  if (noise_estimated && !(stack.noise.read_sigma > 0.0) && lambertian.shadow_threshold > absolute_threshold &&
      lambertian.IsValid(nullptr)) {
    working.noise = internal::EstimateNoise(stack, lambertian);
    raise_threshold();
  }
  if (!lambertian.IsValid(&why)) {
    SolverSummary summary;
    summary.method = MethodName(options.method);
    summary.message = "invalid options: " + why + " (the shadow threshold was raised to " +
                      std::to_string(options.shadow_threshold_read_sigmas) + " read-noise sigmas, " +
                      std::to_string(lambertian.shadow_threshold) + ")";
    summary.shadow_threshold = lambertian.shadow_threshold;
    return summary;
  }
  if (!refine) {
    SolverSummary summary = SolveLambertian(lambertian, working, result);
    summary.method = MethodName(options.method);
    summary.pixels_lambertian = summary.pixels_solved;
    summary.noise_estimated = noise_estimated;
    summary.noise_read_sigma = working.noise.read_sigma;
    summary.noise_shot_gain = working.noise.shot_gain;
    summary.shadow_threshold = lambertian.shadow_threshold;
    summary.total_ms = MillisecondsSince(start);
    return summary;
  }
  if (!(working.noise.read_sigma > 0.0)) working.noise.read_sigma = 1e-9;  // noise-free: any residual counts
  const std::vector<double> quantile = internal::ChiSquareQuantiles(stack.light_count(), options.selection.adequacy_quantile);
  const double gross_u2 = options.selection.gross_outlier_sigma * options.selection.gross_outlier_sigma;
  auto adequate = [&quantile](const Fit& fit) { return fit.ok && fit.Dof() > 0 && fit.chi2 <= quantile[fit.Dof()]; };
  // The screen of `auto`: the Lambertian pass's confidence is expected /
  // observed residual variance, so dof / confidence is its chi-square
  // statistic with the noise variance averaged over the samples, and a pixel
  // with confidence >= dof / quantile[dof] passes the adequacy test without
  // another look at its samples. (The exact test weights each sample by its
  // own variance; the two differ only near the threshold.) Other methods
  // refine every pixel.
  // Float, as the confidence is: the screen only needs to be close (see above).
  std::vector<float> screen_threshold(stack.light_count() + 1, std::numeric_limits<float>::infinity());
  if (options.method == Method::kAuto)
    for (int dof = 1; dof + 3 <= stack.light_count(); ++dof)
      screen_threshold[dof + 3] = static_cast<float>(dof / quantile[dof]);

  // Each pixel's samples are read right after its tile's Lambertian pass,
  // while the tile is still in cache; counts are kept per thread. With the
  // lane fitter, the doubtful pixels of a tile are rechecked there (`auto`)
  // and the samples of the rest copied out; trimming (sixteen pixels at a
  // time), IRLS (eight) and the Blinn-Phong fit (sixteen) run on batches
  // gathered across tiles. The per-pixel fitter refines one pixel after
  // another, the reference.
  const bool lanes = options.blinn_phong.fitter == BlinnPhongOptions::Fitter::kLanes;
  struct Deferred {
    int pixel;
    Fit lambert;
    Eigen::Vector3d start_normal;
    double start_albedo;
    std::size_t row;  // of the thread's sample rows
  };
  struct ThreadState {
    std::vector<std::uint8_t> needs_refit;  // per pixel of the tile
    std::vector<int> doubtful;  // the tile's pixels that need refitting, with lanes
    std::vector<Eigen::Vector3d> doubtful_x;
    std::vector<internal::Recheck> rechecks;
    PixelSamples samples;
    TrimScratch trim;
    autodiff::Tape tape;
    // Every light's sample of the queued pixels, one row per pixel
    // (SampleReader::Row); see `flush`.
    std::vector<double> observed, inverse_sigma;
    std::size_t rows = 0;
    // Pixels queued for trimming (with their Lambertian fit x and, for
    // `auto`, its chi-square and sample count as the recheck found them) and
    // their samples (TrimmedLambertianLanes::CopySamples), one row each.
    struct Trimming {
      int pixel;
      Eigen::Vector3d x;
      double chi2;
      int used;
    };
    std::vector<Trimming> trimming;
    std::vector<float> trim_rows;
    std::vector<Deferred> reweighting, deferred;
    std::unique_ptr<internal::RobustLambertianLanes> irls;  // `robust` only
    std::vector<internal::RobustProblem> robust_problems;
    std::vector<internal::RobustSolution> robust_solutions;
    std::vector<internal::TrimSolution> trim_solutions;
    std::vector<internal::BlinnPhongProblem> problems;
    std::vector<internal::BlinnPhongSolution> solutions;
    std::size_t lambertian = 0, robust = 0, blinn_phong = 0, rejected = 0, failed = 0;
  };
  const int threads = options.lambertian.num_threads > 0 ? options.lambertian.num_threads : omp_get_max_threads();
  std::vector<ThreadState> states(threads);
  if (options.method == Method::kRobust)
    for (ThreadState& state : states)
      state.irls = std::make_unique<internal::RobustLambertianLanes>(working.light_directions, options.robust);
  std::vector<internal::BlinnPhongLaneFitter> fitters;
  std::vector<internal::TrimmedLambertianLanes> trimmers;
  if (lanes) {
    for (int t = 0; t < threads; ++t) {
      fitters.emplace_back(working.light_directions, working.view_direction, options.blinn_phong);
      trimmers.emplace_back(working, lambertian, gross_u2, options.selection.max_rejected_fraction);
    }
  }
  const int lights = working.light_count();
  const SampleReader reader(working, lambertian);
  const internal::RecheckLanes recheck(working, lambertian);
  // Gathers pixel p's samples into a new row, from the planes or from the
  // copy `samples` of them (TrimmedLambertianLanes::CopySamples); the
  // Lambertian fit x is tested on them.
  auto gather_row = [&](ThreadState& state, int p, const Eigen::Vector3d& x, Fit* lambert,
                        const float* samples = nullptr) {
    const std::size_t row = state.rows++;
    // Rows are reused from tile to tile: grow only (a resize would zero-fill
    // every row again for each tile).
    if (state.observed.size() < state.rows * lights) {
      state.observed.resize(2 * state.rows * lights);
      state.inverse_sigma.resize(2 * state.rows * lights);
    }
    int used = 0;
    double* observed = &state.observed[row * lights];
    double* inverse_sigma = &state.inverse_sigma[row * lights];
    const double chi2 = samples ? reader.RowFromSamples(samples, x, observed, inverse_sigma, &used)
                                : reader.Row(p, x, observed, inverse_sigma, &used);
    *lambert = LambertianFit(x, chi2, used, 0);
    return row;
  };
  auto record = [&](ThreadState& state, int p, const Fit& chosen) {
    if (!chosen.ok) {
      result->flags.ptr<std::uint8_t>()[p] = static_cast<std::uint8_t>(PixelFlag::kRejectedByModel);
      result->normals.ptr<cv::Vec3f>()[p] = cv::Vec3f::all(std::numeric_limits<float>::quiet_NaN());
      result->albedo.ptr<float>()[p] = std::numeric_limits<float>::quiet_NaN();
      result->model.ptr<std::uint8_t>()[p] = static_cast<std::uint8_t>(PixelModel::kNone);
      result->confidence.ptr<float>()[p] = 0.0f;
      ++state.failed;
      return;
    }
    WriteFit(p, chosen, result);
    state.rejected += static_cast<std::size_t>(chosen.rejected);
    switch (chosen.model) {
      case PixelModel::kLambertian: ++state.lambertian; break;
      case PixelModel::kRobust: ++state.robust; break;
      case PixelModel::kBlinnPhong: ++state.blinn_phong; break;
      case PixelModel::kNone: break;
    }
  };
  // Neither simple model is adequate: the information criterion decides
  // between the models fitted to all usable samples.
  auto choose_blinn_phong = [&](const Fit& lambert, const Fit& blinn_phong) {
    if (options.method == Method::kBlinnPhong) return blinn_phong;
    return blinn_phong.ok && blinn_phong.Bic() < lambert.Bic() ? blinn_phong : lambert;
  };
  // `auto` fits a richer model only where the samples can tell it apart:
  // with no sample to spare (3 usable) nothing can be tested or trimmed, and
  // with no more samples than its parameters the Blinn-Phong lobe is not
  // determined. Such pixels keep their Lambertian fit.
  auto can_trim = [](const Fit& lambert) { return lambert.Dof() > 0; };
  auto can_fit_lobe = [](int used) { return used > kBlinnPhongParameters; };
  auto tile_x = [&](int p) -> Eigen::Vector3d {
    const cv::Vec3f n = result->normals.ptr<cv::Vec3f>()[p];
    return Eigen::Vector3d(n[0], n[1], n[2]) * result->albedo.ptr<float>()[p] / M_PI;
  };
  // IRLS of one pixel: the lane fitter with a single problem.
  auto reweight_pixel = [&](ThreadState& state, const PixelSamples& s, const Eigen::Vector3d& x) {
    const internal::RobustProblem problem{s.row_observed.data(), s.row_inverse_sigma.data(), x};
    internal::RobustSolution solution;
    state.irls->Fit({&problem, 1}, {&solution, 1});
    return RobustFit(solution);
  };
  // The per-pixel fitter: pixels the cheap screen could not accept, one at a
  // time, through the exact tests and, where the simple models fail, the
  // richer fits.
  auto refine_pixel = [&](ThreadState& state, int p) {
    PixelSamples& s = state.samples;
    reader.Usable(p, &s);
    const Eigen::Vector3d x = tile_x(p);
    const Fit lambert = LambertianFromX(s, x, nullptr, 0.0);
    if (options.method == Method::kAuto && (adequate(lambert) || !can_trim(lambert))) return record(state, p, lambert);
    Fit lit;
    if (options.method == Method::kAuto && reader.FitLit(s.row_observed.data(), s.row_inverse_sigma.data(), x, &lit) &&
        adequate(lit))
      return record(state, p, lit);
    const int max_rejected = static_cast<int>(options.selection.max_rejected_fraction * s.size());
    const Fit robust = options.method == Method::kRobust ? reweight_pixel(state, s, x)
                                                         : FitTrimmed(s, max_rejected, gross_u2, adequate, &state.trim);
    // FitTrimmed never drops more than max_rejected samples.
    if (options.method == Method::kRobust || (options.method == Method::kAuto && adequate(robust)))
      return record(state, p, robust);
    if (options.method == Method::kAuto && !can_fit_lobe(lambert.used)) return record(state, p, lambert);
    const Fit& start = robust.ok ? robust : lambert;
    const Fit lobe = FitBlinnPhong(s, working.view_direction, start, options.blinn_phong, &state.tape);
    record(state, p, choose_blinn_phong(lambert, lobe));
  };
  auto fit_deferred = [&](int thread) {
    ThreadState& state = states[thread];
    const std::size_t count = state.deferred.size();
    state.problems.resize(count);
    state.solutions.assign(count, {});
    for (std::size_t i = 0; i < count; ++i) {
      const Deferred& d = state.deferred[i];
      state.problems[i] = {&state.observed[d.row * lights], &state.inverse_sigma[d.row * lights], d.start_normal,
                           d.start_albedo};
    }
    if (count > 0) fitters[thread].Fit(state.problems, state.solutions);
    for (std::size_t i = 0; i < count; ++i) {
      const internal::BlinnPhongSolution& solution = state.solutions[i];
      Fit fit;
      fit.ok = solution.ok;
      fit.normal = solution.normal;
      fit.albedo = solution.diffuse_albedo;
      fit.specular_albedo = solution.specular_albedo;
      fit.exponent = solution.exponent;
      fit.chi2 = solution.chi2;
      fit.parameters = kBlinnPhongParameters;
      fit.used = state.deferred[i].lambert.used;
      fit.model = PixelModel::kBlinnPhong;
      record(state, state.deferred[i].pixel, choose_blinn_phong(state.deferred[i].lambert, fit));
    }
    state.deferred.clear();
  };
  // `auto` and `blinn-phong` with lanes: trimming; for `auto`, what it cannot
  // explain goes on to the Blinn-Phong fit, for `blinn-phong` every pixel
  // does, from the trimmed fit. Only those have their samples copied out in
  // double.
  auto trim_in_lanes = [&](int thread) {
    ThreadState& state = states[thread];
    const std::size_t count = state.trimming.size();
    state.trim_solutions.assign(count, {});
    if (count > 0) trimmers[thread].Fit(state.trim_rows, quantile, state.trim_solutions);
    for (std::size_t i = 0; i < count; ++i) {
      const ThreadState::Trimming& t = state.trimming[i];
      const internal::TrimSolution& trimmed = state.trim_solutions[i];
      Fit robust;
      robust.ok = trimmed.ok;
      robust.normal = trimmed.x.normalized();
      robust.albedo = M_PI * trimmed.x.norm();
      robust.chi2 = trimmed.chi2;
      robust.used = trimmed.used;
      robust.rejected = trimmed.rejected;
      robust.model = PixelModel::kRobust;
      if (options.method == Method::kAuto && adequate(robust)) {  // it trimmed at most its allowance
        record(state, t.pixel, robust);
        continue;
      }
      if (options.method == Method::kAuto && !can_fit_lobe(t.used)) {
        record(state, t.pixel, LambertianFit(t.x, t.chi2, t.used, 0));
        continue;
      }
      Fit lambert;
      const float* samples = &state.trim_rows[i * trimmers[thread].row_length()];
      const std::size_t row = gather_row(state, t.pixel, t.x, &lambert, samples);
      const Fit& start = robust.ok ? robust : lambert;
      state.deferred.push_back({t.pixel, lambert, start.normal, start.albedo, row});
    }
    state.trimming.clear();
    state.trim_rows.clear();
  };
  // `robust` with lanes: IRLS for every pixel.
  auto reweight_in_lanes = [&](int thread) {
    ThreadState& state = states[thread];
    const std::size_t count = state.reweighting.size();
    state.robust_problems.resize(count);
    state.robust_solutions.assign(count, {});
    for (std::size_t i = 0; i < count; ++i) {
      const Deferred& d = state.reweighting[i];
      state.robust_problems[i] = {&state.observed[d.row * lights], &state.inverse_sigma[d.row * lights],
                                  d.start_normal * d.start_albedo / M_PI};
    }
    if (count > 0) state.irls->Fit(state.robust_problems, state.robust_solutions);
    for (std::size_t i = 0; i < count; ++i) record(state, state.reweighting[i].pixel, RobustFit(state.robust_solutions[i]));
    state.reweighting.clear();
  };
  // The lane stages run on batches gathered across tiles, so that a tile with
  // only a few doubtful pixels does not run a full set of lanes for one of
  // them; a pixel's samples were copied out when it was queued. Once a stage
  // has run, the rows still queued move to the front of the thread's rows,
  // which stay as small as the queues.
  constexpr std::size_t kBatch = 64;
  auto flush = [&](int thread, bool all) {
    ThreadState& state = states[thread];
    if (all || state.trimming.size() >= kBatch) trim_in_lanes(thread);
    const std::size_t queued_before = state.reweighting.size() + state.deferred.size();
    if (all || state.reweighting.size() >= kBatch) reweight_in_lanes(thread);
    if (all || state.deferred.size() >= kBatch) fit_deferred(thread);
    if (state.reweighting.size() + state.deferred.size() == queued_before) return;
    std::vector<Deferred*> queued;
    for (auto* queue : {&state.reweighting, &state.deferred})
      for (Deferred& d : *queue) queued.push_back(&d);
    std::sort(queued.begin(), queued.end(), [](const Deferred* a, const Deferred* b) { return a->row < b->row; });
    for (std::size_t i = 0; i < queued.size(); ++i) {
      // Ascending rows move down or stay, so no row is overwritten before it moves.
      const std::size_t from = queued[i]->row * lights, to = i * lights;
      std::copy_n(&state.observed[from], lights, &state.observed[to]);
      std::copy_n(&state.inverse_sigma[from], lights, &state.inverse_sigma[to]);
      queued[i]->row = i;
    }
    state.rows = queued.size();
  };
  const internal::TileVisitor refine_tile = [&](int thread, int begin, int count) {
    ThreadState& state = states[thread];
    state.needs_refit.resize(count);
    state.lambertian += ScreenTile(result->flags.ptr<std::uint8_t>() + begin,
                                   result->usable_lights.ptr<std::uint16_t>() + begin,
                                   result->confidence.ptr<float>() + begin, count, screen_threshold.data(),
                                   state.needs_refit.data());
    auto doubt = [&](int i) {
      const int p = begin + i;
      if (!lanes) {
        refine_pixel(state, p);  // records the pixel
        return;
      }
      state.doubtful.push_back(p);
      state.doubtful_x.push_back(tile_x(p));
    };
    // Most pixels pass the screen: the flags (0 or 1) are read eight at a
    // time, and each set one is found as the lowest set bit of its word.
    static_assert(std::endian::native == std::endian::little, "byte i of a word is bits 8i..8i+7");
    int i = 0;
    for (; i + 8 <= count; i += 8) {
      std::uint64_t eight;
      std::memcpy(&eight, &state.needs_refit[i], sizeof eight);
      for (; eight != 0; eight &= eight - 1) doubt(i + std::countr_zero(eight) / 8);
    }
    for (; i < count; ++i)
      if (state.needs_refit[i]) doubt(i);
    if (!lanes) return;
    const std::size_t doubtful = state.doubtful.size();
    // `auto` looks again at the doubtful pixels in lanes before copying any
    // samples out: most are settled by the exact test or the lit refit.
    if (options.method == Method::kAuto) {
      state.rechecks.resize(doubtful);
      recheck.Check(state.doubtful, state.doubtful_x, state.rechecks);
    }
    for (std::size_t j = 0; j < doubtful; ++j) {
      const int p = state.doubtful[j];
      const Eigen::Vector3d& x = state.doubtful_x[j];
      if (options.method == Method::kAuto) {
        const internal::Recheck& again = state.rechecks[j];
        const Fit lambert = LambertianFit(x, again.chi2, again.used, 0);
        if (adequate(lambert) || !can_trim(lambert)) {
          record(state, p, lambert);
          continue;
        }
        const Fit lit = LambertianFit(again.lit_x, again.lit_chi2, again.lit_used, again.unlit);
        if (again.refitted && adequate(lit)) {
          record(state, p, lit);
          continue;
        }
      }
      if (options.method != Method::kRobust) {
        const internal::Recheck* again = options.method == Method::kAuto ? &state.rechecks[j] : nullptr;
        state.trimming.push_back({p, x, again ? again->chi2 : 0.0, again ? again->used : 0});
        const std::size_t at = state.trim_rows.size();
        state.trim_rows.resize(at + trimmers[thread].row_length());
        trimmers[thread].CopySamples(p, &state.trim_rows[at]);
        continue;
      }
      Fit lambert;
      const std::size_t row = gather_row(state, p, x, &lambert);
      state.reweighting.push_back({p, lambert, lambert.normal, lambert.albedo, row});
    }
    state.doubtful.clear();
    state.doubtful_x.clear();
    flush(thread, false);
  };
  // What is still queued when a thread runs out of tiles, it fits while the
  // others finish theirs.
  const internal::ThreadDone flush_rest = [&](int thread) {
    if (lanes) flush(thread, true);
  };
  SolverSummary summary = internal::SolveLambertianTiles(lambertian, working, result, refine_tile, flush_rest);
  summary.method = MethodName(options.method);
  summary.shadow_threshold = lambertian.shadow_threshold;
  if (!summary.IsSolutionUsable()) {
    summary.total_ms = MillisecondsSince(start);
    return summary;
  }
  summary.noise_estimated = noise_estimated;
  summary.noise_read_sigma = working.noise.read_sigma;
  summary.noise_shot_gain = working.noise.shot_gain;
  std::size_t lambertian_count = 0, robust_count = 0, blinn_phong_count = 0, rejected_count = 0, failed_count = 0;
  for (const ThreadState& state : states) {
    lambertian_count += state.lambertian;
    robust_count += state.robust;
    blinn_phong_count += state.blinn_phong;
    rejected_count += state.rejected;
    failed_count += state.failed;
  }
  summary.pixels_lambertian = lambertian_count;
  summary.pixels_robust = robust_count;
  summary.pixels_blinn_phong = blinn_phong_count;
  summary.samples_rejected += rejected_count;
  summary.pixels_solved -= failed_count;
  summary.pixels_rejected_by_model += failed_count;
  summary.total_ms = MillisecondsSince(start);
  return summary;
}

}  // namespace photorig::ps
