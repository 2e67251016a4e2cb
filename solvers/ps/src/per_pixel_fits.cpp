#include "per_pixel_fits.h"

#include "kernels/lobe_lane_fit.h"
#include "kernels/trimmed_lambertian_fit.h"

#include "photorig/solvers/autodiff/blinn_phong_jacobian.h"
#include "photorig/solvers/autodiff/ggx.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>

namespace photorig::solvers::ps::internal {

PixelFit IrlsFit(const RobustSolution& solution) {
  PixelFit fit;
  fit.model = PixelModel::kIrls;
  fit.ok = solution.ok;
  if (!fit.ok) return fit;
  fit.normal = solution.x.normalized();
  fit.albedo = M_PI * solution.x.norm();
  fit.chi2 = solution.chi2;
  fit.used = solution.used;
  fit.rejected = solution.rejected;
  return fit;
}

PixelFit LobeFitFrom(const LobeSolution& solution, int used, PixelModel model) {
  return {.ok = solution.ok,
          .normal = solution.normal,
          .albedo = solution.diffuse_albedo,
          .specular_albedo = solution.specular_albedo,
          .exponent = solution.exponent,
          .chi2 = solution.chi2,
          .parameters = model == PixelModel::kGgx ? kGgxParameters : kBlinnPhongParameters,
          .used = used,
          .rejected = 0,
          .model = model};
}

PixelFit LowFrequencyFitFrom(const LowFrequencySolution& solution) {
  return {.ok = solution.ok,
          .normal = solution.normal,
          .albedo = M_PI * (solution.a[0] + solution.a[3]),
          .specular_albedo = M_PI * (solution.a[1] + solution.a[2]),
          .exponent = 0.0,
          .chi2 = solution.chi2,
          .parameters = kLowFrequencyParameters,
          .used = solution.used,
          .rejected = solution.left_out,
          .model = PixelModel::kLowFrequency};
}

PixelFit KeptOnLights(const PixelFit& kept, std::span<const int> lights, const double* wx, const double* wy,
                      const double* wz, int stride, const Eigen::Vector3d& view, const double* observed,
                      const double* inverse_sigma, std::vector<double>* predicted_out) {
  const int n = static_cast<int>(lights.size());
  Eigen::Matrix<double, Eigen::Dynamic, 3> directions(n, 3);
  Eigen::VectorXd b(n), predicted(n);
  for (int i = 0; i < n; ++i) {
    const int k = lights[i];
    directions.row(i) << wx[k * stride], wy[k * stride], wz[k * stride];
    b[i] = observed[k];
  }
  PixelFit judged = kept;
  judged.used = n;
  judged.rejected = 0;
  const double q[6] = {kept.normal.x(), kept.normal.y(), kept.normal.z(), kept.albedo, kept.specular_albedo, kept.exponent};
  bool ok = true;
  if (kept.model == PixelModel::kBlinnPhong) {
    ok = solvers::autodiff::BlinnPhongPixel(directions, Eigen::VectorXd::Ones(n), view, b).Predict(q, predicted.data());
  } else if (kept.model == PixelModel::kGgx) {
    ok = solvers::autodiff::GgxPixel(directions, Eigen::VectorXd::Ones(n), view, b).Predict(q, predicted.data());
  } else {
    predicted = (directions * (kept.normal * kept.albedo / M_PI)).cwiseMax(0.0);
  }
  judged.chi2 = 0.0;
  for (int i = 0; i < n; ++i) {
    const double u = (predicted[i] - b[i]) * inverse_sigma[lights[i]];
    judged.chi2 += u * u;
  }
  judged.ok = ok && std::isfinite(judged.chi2);
  if (predicted_out) predicted_out->assign(predicted.data(), predicted.data() + n);
  return judged;
}

namespace {

// Calls visit(k, l, h) for every usable sample k of `samples`, with its
// light direction and half vector.
template <typename Visit>
void ForEachUsableSample(const LowFrequencyProblem& samples, const Visit& visit) {
  for (int k = 0; k < samples.lights; ++k) {
    if (samples.inverse_sigma[k] == 0.0) continue;
    Eigen::Vector3d l, h;
    double cos_d = 0.0;
    samples.Geometry(k, &l, &h, &cos_d);
    visit(k, l, h);
  }
}

}  // namespace

bool SpikePinsNormal(const PixelFit& kept, const LowFrequencyProblem& samples, int spike_samples) {
  double half_maximum_cos = 0.0;
  if (kept.model == PixelModel::kBlinnPhong) {
    half_maximum_cos = std::pow(0.5, 1.0 / std::max(kept.exponent, 1e-6));
  } else if (kept.model == PixelModel::kGgx) {
    const double a2 = kept.exponent * kept.exponent;
    if (a2 >= M_SQRT1_2) return false;  // no half maximum on the hemisphere: no spike
    half_maximum_cos = std::sqrt((1.0 - M_SQRT2 * a2) / (1.0 - a2));
  } else {
    return false;
  }
  int core = 0;
  ForEachUsableSample(samples, [&](int, const Eigen::Vector3d&, const Eigen::Vector3d& h) {
    core += h.dot(kept.normal) >= half_maximum_cos;
  });
  return core >= 1 && core <= spike_samples;
}

double BlinnPhongTermChi2(const PixelFit& kept, const LowFrequencyProblem& samples) {
  // The lobe alone: BlinnPhongShading with no diffuse term.
  const solvers::autodiff::BlinnPhongLobe<double> lobe(0.0, kept.specular_albedo, kept.exponent);
  double chi2 = 0.0;
  ForEachUsableSample(samples, [&](int k, const Eigen::Vector3d& l, const Eigen::Vector3d& h) {
    const double term = solvers::autodiff::BlinnPhongShading(kept.normal, lobe, l, h) * samples.inverse_sigma[k];
    chi2 += term * term;
  });
  return chi2;
}

PixelFit LambertianOnRow(int lights, const double* wx, const double* wy, const double* wz, int stride,
                         const double* observed, const double* inverse_sigma, const Eigen::Vector3d& kept) {
  // Sums over the usable samples as masked lane loops: step 5 calls this for
  // every pixel it offers a lobe, a twentieth of a glossy object's solve
  // where the loops branched per sample.
  double gxx = 0.0, gxy = 0.0, gxz = 0.0, gyy = 0.0, gyz = 0.0, gzz = 0.0, rx = 0.0, ry = 0.0, rz = 0.0;
  int used = 0;
#pragma omp simd reduction(+ : gxx, gxy, gxz, gyy, gyz, gzz, rx, ry, rz, used)
  for (int k = 0; k < lights; ++k) {
    const double usable = inverse_sigma[k] != 0.0 ? 1.0 : 0.0;
    const double x = usable * wx[k * stride], y = usable * wy[k * stride], z = usable * wz[k * stride];
    gxx += x * x, gxy += x * y, gxz += x * z, gyy += y * y, gyz += y * z, gzz += z * z;
    const double b = inverse_sigma[k] != 0.0 ? observed[k] : 0.0;
    rx += b * x, ry += b * y, rz += b * z;
    used += inverse_sigma[k] != 0.0;
  }
  if (used < 3) return PixelFit{};
  Eigen::Matrix3d g;
  g << gxx, gxy, gxz, gxy, gyy, gyz, gxz, gyz, gzz;
  const Eigen::Vector3d x = g.ldlt().solve(Eigen::Vector3d(rx, ry, rz));
  double chi2 = 0.0, kept_chi2 = 0.0;
#pragma omp simd reduction(+ : chi2, kept_chi2)
  for (int k = 0; k < lights; ++k) {
    const double w_x = wx[k * stride] * x.x() + wy[k * stride] * x.y() + wz[k * stride] * x.z();
    const double w_kept = wx[k * stride] * kept.x() + wy[k * stride] * kept.y() + wz[k * stride] * kept.z();
    const double u = (observed[k] - w_x) * inverse_sigma[k];
    const double v = (observed[k] - (w_kept > 0.0 ? w_kept : 0.0)) * inverse_sigma[k];
    chi2 += u * u, kept_chi2 += v * v;  // 0 where unusable
  }
  chi2 = std::min(chi2, kept_chi2);
  PixelFit fit = LambertianFit(x, chi2, used, 0);
  fit.ok = fit.ok && std::isfinite(chi2);
  return fit;
}

PixelFit LambertianOnRow(const SampleReader& reader, const double* observed, const double* inverse_sigma,
                         const Eigen::Vector3d& kept) {
  return LambertianOnRow(reader.lights(), reader.direction_axis(0), reader.direction_axis(1), reader.direction_axis(2), 1,
                         observed, inverse_sigma, kept);
}

namespace {

// The Lambertian fit x of a pixel, tested on its usable samples.
PixelFit LambertianFromX(const PixelSamples& s, const Eigen::Vector3d& x) {
  PixelFit fit;
  const double length = x.norm();
  if (!(length > 0.0)) return fit;
  fit.ok = true;
  fit.normal = x / length;
  fit.albedo = M_PI * length;
  for (int k = 0; k < s.size(); ++k) {
    const double r = s.b[k] - s.w[k].dot(x);
    fit.chi2 += r * r / s.variance[k];
    ++fit.used;
  }
  return fit;
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
// lanes (kernels/lambertian_recheck.cpp).
bool FitLit(const SampleReader& reader, const double* observed, const double* inverse_sigma, const Eigen::Vector3d& x,
            PixelFit* fit) {
  const int lights = reader.lights();
  const double *wx = reader.direction_axis(0), *wy = reader.direction_axis(1), *wz = reader.direction_axis(2);
  const double max_condition = reader.max_condition();
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

// Trimming, the cheap robust stage of kAuto: drop the samples TrimThreshold
// picks (the worst alone, or all gross outliers of a round together) and
// refit (rank-one downdates of the 3 x 3 normal equations), until the fit is
// adequate; a pixel that would have to drop more than `max_rejected` samples
// keeps its inadequate fit. Highlights are a few huge residuals, so this
// usually stops after one or two rounds at O(n) each, where IRLS needs ~10
// weighted passes. The per-pixel reference of TrimmedLambertianLanes.
PixelFit FitTrimmed(const PixelSamples& s, const ModelLadder& ladder, TrimScratch* t) {
  const int max_rejected = ladder.MaxRejected(s.size());
  const double gross_u2 = ladder.gross_u2();
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
    PixelFit fit;
    fit.model = PixelModel::kTrimmed;
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
    if (ladder.Adequate(fit)) return fit;
    // Trimmed samples have u2 = 0, below any threshold that drops something.
    const double threshold = TrimThreshold(worst_u2, gross_u2);
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



// Levenberg-Marquardt on the six parameters of a pixel model (the normal as
// three components, then three of the material) from p, whose cost (chi-square)
// and weighted residuals and Jacobian cost_at has just computed; cost_at(q,
// with_jacobian, &cost) evaluates q (refreshing `residuals` and `jacobian`
// with the Jacobian), project(&q) puts a step back into the parameters'
// domain. Returns the cost at the final p.
template <typename CostAt, typename Project>
double LevenbergMarquardt(Eigen::Matrix<double, 6, 1>* parameters, double cost, const Eigen::VectorXd& inverse_sigma,
                          const Eigen::VectorXd& residuals, const Eigen::MatrixXd& jacobian, const CostAt& cost_at,
                          const Project& project, const BlinnPhongOptions& options) {
  Eigen::Matrix<double, 6, 1>& p = *parameters;
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
  return cost;
}

// A lobe fit's parameters (normal, rho_d, rho_s, shape) kept valid after a
// step: a unit normal, non-negative albedos, the shape within its range.
void ProjectLobe(double min_shape, double max_shape, Eigen::Matrix<double, 6, 1>* q) {
  q->head<3>().normalize();
  (*q)(3) = std::max(0.0, (*q)(3));
  (*q)(4) = std::max(0.0, (*q)(4));
  (*q)(5) = std::clamp((*q)(5), min_shape, max_shape);
}

// The record of a lobe fit that ended at `p` with chi-square `cost`.
PixelFit LobeFit(const Eigen::Matrix<double, 6, 1>& p, double cost, int parameters, int used, PixelModel model) {
  PixelFit fit;
  fit.ok = std::isfinite(cost);
  fit.normal = p.head<3>().normalized();
  fit.albedo = p(3);
  fit.specular_albedo = p(4);
  fit.exponent = p(5);  // Blinn-Phong's e, GGX's roughness
  fit.chi2 = cost;
  fit.parameters = parameters;
  fit.used = used;
  fit.model = model;
  return fit;
}

// The samples of a pixel as the autodiff models take them.
struct ModelSamples {
  Eigen::Matrix<double, Eigen::Dynamic, 3> directions;
  Eigen::VectorXd observed, inverse_sigma;
  explicit ModelSamples(const PixelSamples& s) : directions(s.size(), 3), observed(s.size()), inverse_sigma(s.size()) {
    for (int k = 0; k < s.size(); ++k) {
      directions.row(k) = s.w[k].transpose();
      observed[k] = s.b[k];
      inverse_sigma[k] = 1.0 / std::sqrt(s.variance[k]);
    }
  }
};

// Levenberg-Marquardt's cost_at for a lobe model: evaluates `pixel` at q,
// refreshing the residuals (and, with_jacobian, their Jacobian by
// `derivatives` with the options' method), and puts the chi-square in *cost;
// false where the model cannot be evaluated at q. A held lobe has no
// derivatives: the step leaves rho_s and the shape where they are.
template <typename Pixel>
class LobeCost {
 public:
  using Derivatives = bool (*)(const Pixel&, const double*, solvers::autodiff::DerivativeMethod, Eigen::VectorXd*,
                               Eigen::MatrixXd*, solvers::autodiff::Tape*);
  LobeCost(const Pixel& pixel, Derivatives derivatives, const ModelSamples& m, const BlinnPhongOptions& options,
           solvers::autodiff::Tape* tape, bool hold_lobe = false)
      : pixel_(pixel), derivatives_(derivatives), inverse_sigma_(m.inverse_sigma), method_(options.derivative),
        tape_(tape), hold_lobe_(hold_lobe) {}

  bool operator()(const Eigen::Matrix<double, 6, 1>& q, bool with_jacobian, double* cost) const {
    bool ok;
    if (with_jacobian) {
      ok = derivatives_(pixel_, q.data(), method_, &residuals_, &jacobian_, tape_);
    } else {
      residuals_.resize(inverse_sigma_.size());
      ok = pixel_(q.data(), residuals_.data());
    }
    if (ok) *cost = residuals_.cwiseProduct(inverse_sigma_).squaredNorm();
    if (ok && with_jacobian && hold_lobe_) jacobian_.rightCols<2>().setZero();
    return ok;
  }
  const Eigen::VectorXd& residuals() const { return residuals_; }
  const Eigen::MatrixXd& jacobian() const { return jacobian_; }

 private:
  const Pixel& pixel_;
  Derivatives derivatives_;
  const Eigen::VectorXd& inverse_sigma_;
  solvers::autodiff::DerivativeMethod method_;
  solvers::autodiff::Tape* tape_;
  bool hold_lobe_;
  // What the last call evaluated, which LevenbergMarquardt reads between calls.
  mutable Eigen::VectorXd residuals_;
  mutable Eigen::MatrixXd jacobian_;
};

// The lobe fitted to a pixel's usable samples from `start`'s normal and
// albedo, its material from the grid's best start; or, with `shared` (step
// 5), the lobe held at the region's and only the normal and rho_d fitted.
PixelFit FitBlinnPhong(const PixelSamples& s, const Eigen::Vector3d& view, const PixelFit& start,
                       const BlinnPhongOptions& options, solvers::autodiff::Tape* tape, const SharedLobe* shared = nullptr) {
  const int n = s.size();
  const ModelSamples m(s);
  const solvers::autodiff::BlinnPhongPixel pixel(m.directions, Eigen::VectorXd::Ones(n), view, m.observed);

  // Start: the normal of the robust fit and the material of the best point
  // of the exponent grid.
  std::vector<double> cos_light(n), cos_half(n), weight(n);
  for (int k = 0; k < n; ++k) {
    cos_light[k] = std::max(0.0, s.w[k].dot(start.normal));
    cos_half[k] = std::max(0.0, pixel.half_vector(k).dot(start.normal));
    weight[k] = 1.0 / s.variance[k];
  }
  BlinnPhongMaterial material;
  if (shared) {
    // Lane 0 of the lane start, the other lanes without samples.
    std::vector<double> lanes(4 * static_cast<std::size_t>(n) * kFloatLanes, 0.0);
    double* lane_inputs[4] = {lanes.data(), lanes.data() + n * kFloatLanes, lanes.data() + 2 * n * kFloatLanes,
                              lanes.data() + 3 * n * kFloatLanes};
    for (int k = 0; k < n; ++k) {
      lane_inputs[0][k * kFloatLanes] = cos_light[k], lane_inputs[1][k * kFloatLanes] = cos_half[k];
      lane_inputs[2][k * kFloatLanes] = s.b[k], lane_inputs[3][k * kFloatLanes] = weight[k];
    }
    alignas(64) double albedo[kFloatLanes] = {start.albedo}, specular[kFloatLanes] = {shared->specular_albedo},
                       exponent[kFloatLanes] = {shared->exponent};
    LaneMaterial lane;
    BlinnPhongSharedStartLanes(n, lane_inputs[0], lane_inputs[1], lane_inputs[2], lane_inputs[3], albedo, specular,
                               exponent, &lane);
    material = {lane.diffuse_albedo[0], lane.specular_albedo[0], lane.exponent[0]};
  } else {
    material = BlinnPhongGridStart(n, cos_light.data(), cos_half.data(), s.b.data(), weight.data(), start.albedo,
                                   options);
  }
  Eigen::Matrix<double, 6, 1> p;
  p << start.normal, material.diffuse_albedo, material.specular_albedo, material.exponent;
  auto project = [&options](Eigen::Matrix<double, 6, 1>* q) { ProjectLobe(options.min_exponent, options.max_exponent, q); };
  const LobeCost<solvers::autodiff::BlinnPhongPixel> cost_at(
      pixel, &solvers::autodiff::BlinnPhongResidualsAndJacobian, m, options, tape, shared != nullptr);
  double cost = 0.0;
  if (!cost_at(p, true, &cost) || !std::isfinite(cost)) {
    // As the lane fitter: once more from the diffuse start with no lobe.
    if (shared) {
      p << start.normal, start.albedo, shared->specular_albedo, shared->exponent;
    } else {
      p << start.normal, start.albedo, 0.0, options.min_exponent;
    }
    if (!cost_at(p, true, &cost) || !std::isfinite(cost)) return PixelFit{};
  }
  cost = LevenbergMarquardt(&p, cost, m.inverse_sigma, cost_at.residuals(), cost_at.jacobian(), cost_at, project,
                            options);
  return LobeFit(p, cost, shared ? kSharedLobeParameters : kBlinnPhongParameters, n, PixelModel::kBlinnPhong);
}

}  // namespace

double BlinnPhongChi2(const Eigen::Matrix<double, Eigen::Dynamic, 3>& directions, const Eigen::VectorXd& observed,
                      const Eigen::VectorXd& inverse_sigma, const Eigen::Vector3d& view, const PixelFit& fit) {
  const solvers::autodiff::BlinnPhongPixel pixel(directions, Eigen::VectorXd::Ones(observed.size()), view, observed);
  const double q[6] = {fit.normal.x(), fit.normal.y(), fit.normal.z(), fit.albedo, fit.specular_albedo, fit.exponent};
  Eigen::VectorXd residuals(observed.size());
  if (!pixel(q, residuals.data())) return std::numeric_limits<double>::infinity();
  return residuals.cwiseProduct(inverse_sigma).squaredNorm();
}

namespace {

// Chi-square of a Blinn-Phong fit (normal, rho_d, rho_s, e) on a pixel's
// usable samples.
double BlinnPhongChi2(const PixelSamples& s, const Eigen::Vector3d& view, const PixelFit& fit) {
  const ModelSamples m(s);
  return BlinnPhongChi2(m.directions, m.observed, m.inverse_sigma, view, fit);
}

// A GGX lobe fitted to a pixel's usable samples from `start`'s normal: rho_d
// and rho_s from the best point of the roughness grid (weighted least
// squares, both non-negative), then Levenberg-Marquardt on all six
// parameters with Jacobians from solvers/autodiff by `options.derivative`
// (the per-pixel reference of the lanes' GGX fit, lobe_lane_fit.h).
PixelFit FitGgx(const PixelSamples& s, const Eigen::Vector3d& view, const PixelFit& start,
                const BlinnPhongOptions& options, solvers::autodiff::Tape* tape) {
  const int n = s.size();
  const ModelSamples m(s);
  const solvers::autodiff::GgxPixel pixel(m.directions, Eigen::VectorXd::Ones(n), view, m.observed);
  Eigen::Matrix<double, 6, 1> p;
  double best = std::numeric_limits<double>::infinity();
  Eigen::VectorXd diffuse(n), lobe(n);
  for (double roughness : kGgxStartRoughness) {
    // The model is linear in rho_d and rho_s: its two columns at this normal and roughness.
    const double unit_diffuse[6] = {start.normal.x(), start.normal.y(), start.normal.z(), 1.0, 0.0, roughness};
    const double unit_lobe[6] = {start.normal.x(), start.normal.y(), start.normal.z(), 0.0, 1.0, roughness};
    if (!pixel.Predict(unit_diffuse, diffuse.data()) || !pixel.Predict(unit_lobe, lobe.data())) return PixelFit{};
    const Eigen::VectorXd wd = diffuse.cwiseProduct(m.inverse_sigma), wl = lobe.cwiseProduct(m.inverse_sigma),
                          wb = m.observed.cwiseProduct(m.inverse_sigma);
    const TwoColumnFit fit =
        NonNegativeTwoColumnFit(wd.dot(wd), wd.dot(wl), wl.dot(wl), wd.dot(wb), wl.dot(wb), wb.dot(wb));
    if (std::isfinite(fit.chi2) && fit.chi2 < best) {
      best = fit.chi2;
      p << start.normal, fit.diffuse, fit.lobe, roughness;
    }
  }
  if (!std::isfinite(best)) return PixelFit{};
  auto project = [](Eigen::Matrix<double, 6, 1>* q) { ProjectLobe(kMinGgxRoughness, kMaxGgxRoughness, q); };
  const LobeCost<solvers::autodiff::GgxPixel> cost_at(pixel, &solvers::autodiff::GgxResidualsAndJacobian, m, options,
                                                      tape);
  double cost = 0.0;
  if (!cost_at(p, true, &cost) || !std::isfinite(cost)) return PixelFit{};
  cost = LevenbergMarquardt(&p, cost, m.inverse_sigma, cost_at.residuals(), cost_at.jacobian(), cost_at, project,
                            options);
  return LobeFit(p, cost, kGgxParameters, n, PixelModel::kGgx);
}

}  // namespace

PixelFit PerPixelFits::Refine(int pixel, const Eigen::Vector3d& x, PixelScratch* scratch,
                              RobustLambertianLanes* irls, bool* fell_back, double* evidence) const {
  using Action = LadderStep::Action;
  PixelSamples& s = scratch->samples;
  reader_.Usable(pixel, &s);
  const PixelFit lambertian = LambertianFromX(s, x);
  PixelFit lit, robust, blinn_phong;
  LadderFits fits;
  fits.lambertian = &lambertian;
  for (;;) {
    const LadderStep step = ladder_.Next(fits);
    switch (step.action) {
      case Action::kKeep:
        *fell_back = step.fell_back;
        *evidence = step.evidence;
        return *step.keep;
      case Action::kFitSharedLobe:
      case Action::kFitOwnLobe:
      case Action::kFitGgx:
      case Action::kFitLowFrequency: return *fits.lambertian;  // Next never asks for them (steps 5-7 do)
      case Action::kRefitLit:
        FitLit(reader_, s.row_observed.data(), s.row_inverse_sigma.data(), x, &lit);  // ok stays false without one
        fits.lit = &lit;
        break;
      case Action::kTrim:
        robust = FitTrimmed(s, ladder_, &scratch->trim);
        fits.robust = &robust;
        break;
      case Action::kReweight: {
        const RobustProblem problem{s.row_observed.data(), s.row_inverse_sigma.data(), x};
        RobustSolution solution;
        irls->Fit({&problem, 1}, {&solution, 1});
        robust = IrlsFit(solution);
        fits.robust = &robust;
        break;
      }
      case Action::kFitLobe:
        blinn_phong = FitBlinnPhong(s, view_, *step.start, blinn_phong_, &scratch->tape);
        fits.blinn_phong = &blinn_phong;
        fits.lobe_lambertian = &lambertian;
        break;
    }
  }
}

PixelFit PerPixelFits::ShareLobe(int pixel, const PixelFit& kept, const SharedLobe& shared, bool test_shape,
                                 PixelScratch* scratch, SharedShapeTest* test) const {
  PixelSamples& s = scratch->samples;
  reader_.Usable(pixel, &s);
  const PixelFit lambertian =
      LambertianOnRow(reader_, s.row_observed.data(), s.row_inverse_sigma.data(), kept.normal * kept.albedo / M_PI);
  PixelFit lobe, own;
  SharedLobeFits fits{&kept, &lambertian, nullptr, test_shape};
  for (;;) {
    const LadderStep step = ladder_.NextWithSharedLobe(fits);
    switch (step.action) {
      case LadderStep::Action::kFitSharedLobe:
        lobe = FitBlinnPhong(s, view_, *step.start, blinn_phong_, &scratch->tape, &shared);
        fits.lobe = &lobe;
        break;
      case LadderStep::Action::kFitOwnLobe:
        own = FitBlinnPhong(s, view_, *step.start, blinn_phong_, &scratch->tape);
        fits.own = &own;
        break;
      default:
        if (test) ladder_.AddToShapeTest(fits, test);
        return *step.keep;
    }
  }
}

PixelFit PerPixelFits::KeptOnUsable(int pixel, const PixelFit& kept, bool held_lobe, PixelScratch* scratch) const {
  PixelSamples& s = scratch->samples;
  reader_.Usable(pixel, &s);
  PixelFit on_samples;
  if (kept.model == PixelModel::kBlinnPhong) {
    on_samples = kept;
    on_samples.chi2 = BlinnPhongChi2(s, view_, kept);
    on_samples.ok = std::isfinite(on_samples.chi2);
    on_samples.used = s.size();
    on_samples.parameters = held_lobe ? kSharedLobeParameters : kBlinnPhongParameters;
  } else {
    on_samples = LambertianOnRow(reader_, s.row_observed.data(), s.row_inverse_sigma.data(),
                                 kept.normal * kept.albedo / M_PI);
    on_samples.normal = kept.normal;  // the kept fit is where the GGX fit starts
  }
  return on_samples;
}

PixelFit PerPixelFits::OfferGgx(int pixel, const PixelFit& kept, bool held_lobe, PixelScratch* scratch,
                                SharedShapeTest* test) const {
  const PixelFit on_samples = KeptOnUsable(pixel, kept, held_lobe, scratch);
  const PixelSamples& s = scratch->samples;
  PixelFit ggx;
  GgxFits fits{&on_samples};
  for (;;) {
    const LadderStep step = ladder_.NextWithGgx(fits);
    if (step.action != LadderStep::Action::kFitGgx) {
      if (test && fits.ggx) ladder_.AddToShapeTest(fits, test);
      return step.keep == &ggx ? ggx : kept;
    }
    ggx = FitGgx(s, view_, *step.start, blinn_phong_, &scratch->tape);
    fits.ggx = &ggx;
  }
}

}  // namespace photorig::solvers::ps::internal
