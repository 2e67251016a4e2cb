#include "held_lobe_fit.h"

#include "lane_math.h"
#include "lobe_lane_fit.h"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <vector>

namespace photorig::solvers::ps::internal {
namespace {

constexpr int kPixels = kFloatLanes;
constexpr float kInvPiF = std::numbers::inv_pi_v<float>;
// As LobeLaneFitter: cost changes below this fraction are float rounding.
constexpr double kEvaluationPrecision = 1e-5;
// A held fit whose chi-square falls, or is promised to fall, by less than
// this has settled: near the minimum chi-square rises by the squared
// Mahalanobis distance to it, so its normal lies within sqrt(0.003) = 0.055
// standard deviations of the minimum's (shiny sphere: the mean error moves
// by 3e-7 deg, and a batch of lanes needs 3.3 evaluations instead of 4.5:
// its slowest lanes were crawling).
constexpr double kSettledChi2 = 0.003;

// A lane's point: the unit normal, its tangent basis and rho_d (the held
// lobe is the lanes', Lanes::lobe_scale and exponent).
struct alignas(64) Point {
  float n[3][kPixels], t1[3][kPixels], t2[3][kPixels];
  float rho_d[kPixels];
};

// Normal equations of the weighted residuals at a point: cost, J^T J
// (t1 t1, t1 t2, t1 d, t2 t2, t2 d, d d) and J^T r (t1, t2, d).
struct alignas(64) Equations {
  float cost[kPixels], h[6][kPixels], g[3][kPixels];
};

// The pixels' samples in solver units, [light * kPixels + lane]: b = (I - D)
// / s and 1 / sigma (0: shadowed or clipped), and what the lanes hold fixed.
struct Lanes {
  // Not zero-filled: LoadLanes writes b and isig, StartSums the start's
  // values, before anything reads them (a fill cost 1.4 % of shiny `auto`'s
  // instructions).
  explicit Lanes(int lights)
      : size(static_cast<std::size_t>(lights) * kPixels),
        storage(std::make_unique_for_overwrite<float[]>(4 * size)),
        b(storage.get()),
        isig(b + size),
        start_lobe(isig + size),
        start_inverse_h(start_lobe + size) {}
  std::size_t size;
  std::unique_ptr<float[]> storage;
  float *b, *isig;
  // At the start normal, as StartSums makes them for Evaluate<true>: each
  // sample's lobe k h^e and 1 / h (the logarithm and exponential are most of
  // a pass's cost, and the first evaluation is at that normal).
  float *start_lobe, *start_inverse_h;
  alignas(64) int pixel[kPixels];
  alignas(64) float dark[kPixels], lobe_scale[kPixels], exponent[kPixels];
};

struct Geometry {
  int lights;
  const float *wx, *wy, *wz, *hx, *hy, *hz;
};

// Light k's direction, half vector and the lanes' samples under it.
struct LightRow {
  float wx, wy, wz, hx, hy, hz;
  const float *b, *isig;
};
PHOTORIG_LANE_INLINE LightRow RowOf(const Geometry& geo, const Lanes& l, int k) {
  return {geo.wx[k], geo.wy[k], geo.wz[k], geo.hx[k], geo.hy[k], geo.hz[k], &l.b[k * kPixels], &l.isig[k * kPixels]};
}

// Reads every lane's samples from the planes and sums the Lambertian normal
// equations of the usable ones (unweighted, as LambertianOnRow):
// g = xx, xy, xz, yy, yz, zz; r = sum b w.
PHOTORIG_PS_MULTIVERSION
void LoadLanes(const PlaneConstants& c, Lanes* l, float g[6][kPixels], float r[3][kPixels], float used[kPixels]) {
  for (int i = 0; i < kPixels; ++i) {
    used[i] = r[0][i] = r[1][i] = r[2][i] = 0.0f;
    for (int e = 0; e < 6; ++e) g[e][i] = 0.0f;
  }
  for (int k = 0; k < c.lights; ++k) {
    const float* plane = c.planes[k];
    const float wx = c.wx[k], wy = c.wy[k], wz = c.wz[k], scale = c.scale[k], inverse_scale = c.inverse_scale[k];
    float* b = &l->b[k * kPixels];
    float* isig = &l->isig[k * kPixels];
#pragma omp simd
    for (int i = 0; i < kPixels; ++i) {
      const float value = plane[l->pixel[i]];
      const float signal = value - l->dark[i];
      const float in = c.Usable(value, signal) ? 1.0f : 0.0f;
      const float bi = in * signal * inverse_scale;
      b[i] = bi;
      isig[i] = in * scale / std::sqrt(c.Variance(signal));
      used[i] += in;
      g[0][i] += in * wx * wx, g[1][i] += in * wx * wy, g[2][i] += in * wx * wz;
      g[3][i] += in * wy * wy, g[4][i] += in * wy * wz, g[5][i] += in * wz * wz;
      r[0][i] += bi * wx, r[1][i] += bi * wy, r[2][i] += bi * wz;
    }
  }
}

// Every lane's Lambertian normal equations g x = r (as LoadLanes sums them)
// solved in double by the adjugate, where the determinant is safely
// positive: well_posed[i] = 1. Elsewhere (0) x is left for the caller's
// pivoted solve. One vector pass where a 3 x 3 factorisation per lane cost
// as many instructions as the lanes' Lambertian pass itself.
PHOTORIG_PS_MULTIVERSION
void SolveLambertianLanes(const float g[6][kPixels], const float r[3][kPixels], float x[3][kPixels],
                          double well_posed[kPixels]) {
#pragma omp simd
  for (int i = 0; i < kPixels; ++i) {
    const double xx = g[0][i], xy = g[1][i], xz = g[2][i], yy = g[3][i], yz = g[4][i], zz = g[5][i];
    const double a_xx = yy * zz - yz * yz, a_xy = xz * yz - xy * zz, a_xz = xy * yz - xz * yy;
    const double a_yy = xx * zz - xz * xz, a_yz = xy * xz - xx * yz, a_zz = xx * yy - xy * xy;
    const double det = xx * a_xx + xy * a_xy + xz * a_xz;
    // det = l1 l2 l3 > 1e-6 trace^3 >= 1e-6 l1^3 (eigenvalues l1 >= l2 >=
    // l3) bounds the condition number l1 / l3 below 10^6: the adjugate in
    // double then keeps ten digits, more than the float result holds.
    const double trace = xx + yy + zz;
    const bool ok = det > 1e-6 * trace * trace * trace;
    const double inverse_det = ok ? 1.0 / det : 0.0;
    const double rx = r[0][i], ry = r[1][i], rz = r[2][i];
    x[0][i] = static_cast<float>((a_xx * rx + a_xy * ry + a_xz * rz) * inverse_det);
    x[1][i] = static_cast<float>((a_xy * rx + a_yy * ry + a_yz * rz) * inverse_det);
    x[2][i] = static_cast<float>((a_xz * rx + a_yz * ry + a_zz * rz) * inverse_det);
    well_posed[i] = ok ? 1.0 : 0.0;
  }
}

// Chi-square of the Lambertian solutions x (as fitted) and kept (its
// attached shadow clamped) on every lane's usable samples.
PHOTORIG_PS_MULTIVERSION
void LambertianChi2(const Geometry& geo, const Lanes& l, const float x[3][kPixels], const float kept[3][kPixels],
                    float chi2[kPixels], float kept_chi2[kPixels]) {
  for (int i = 0; i < kPixels; ++i) chi2[i] = kept_chi2[i] = 0.0f;
  for (int k = 0; k < geo.lights; ++k) {
    const float wx = geo.wx[k], wy = geo.wy[k], wz = geo.wz[k];
    const float* b = &l.b[k * kPixels];
    const float* isig = &l.isig[k * kPixels];
#pragma omp simd
    for (int i = 0; i < kPixels; ++i) {
      const float u = (b[i] - (wx * x[0][i] + wy * x[1][i] + wz * x[2][i])) * isig[i];
      const float v = (b[i] - std::max(0.0f, wx * kept[0][i] + wy * kept[1][i] + wz * kept[2][i])) * isig[i];
      chi2[i] += u * u, kept_chi2[i] += v * v;  // 0 where unusable
    }
  }
}

// rho_d >= 0 at each lane's normal by weighted least squares with the held
// lobe subtracted (BlinnPhongSharedStartLanes in float): sum_a = sum w c^2,
// sum_b = sum w c (b - lobe c), rho_d = pi sum_b / sum_a.
PHOTORIG_PS_MULTIVERSION
void StartSums(const Geometry& geo, Lanes* l, const Point& p, float sum_a[kPixels], float sum_b[kPixels]) {
  for (int i = 0; i < kPixels; ++i) sum_a[i] = sum_b[i] = 0.0f;
  for (int k = 0; k < geo.lights; ++k) {
    const LightRow row = RowOf(geo, *l, k);  // members, not bindings: OpenMP regions cannot name bindings
    float* start_lobe = &l->start_lobe[k * kPixels];
    float* start_inverse_h = &l->start_inverse_h[k * kPixels];
#pragma omp simd
    for (int i = 0; i < kPixels; ++i) {
      const float c = std::max(0.0f, row.wx * p.n[0][i] + row.wy * p.n[1][i] + row.wz * p.n[2][i]);
      const float h = row.hx * p.n[0][i] + row.hy * p.n[1][i] + row.hz * p.n[2][i];
      float inverse_h;
      const float full = l->lobe_scale[i] * LaneExp(l->exponent[i] * LaneLogAndInverse(std::max(h, 1e-30f), &inverse_h));
      const float lobe = h > 0.0f ? full : 0.0f;
      start_lobe[i] = full, start_inverse_h[i] = inverse_h;
      const float w = row.isig[i] * row.isig[i];
      sum_a[i] += w * c * c, sum_b[i] += w * c * (row.b[i] - lobe * c);
    }
  }
}

// The normal equations at p (EvaluateLanesOf's Blinn-Phong pass without the
// lobe's two columns): with c = w . n, h = w_h . n, the lobe L = k h^e,
//   dI/dn = (rho_d / pi + L) w + k e h^(e-1) c w_h, dI/drho_d = c / pi,
// zero where c <= 0, the w_h term zero where h <= 0.
// at_start: p's normals are the start's, whose lobes StartSums kept.
template <bool at_start>
PHOTORIG_LANE_INLINE void EvaluateLanes(const Geometry& geo, const Lanes& l, const Point& p, Equations* out) {
  float acc[10][kPixels] = {};
  for (int k = 0; k < geo.lights; ++k) {
    const LightRow row = RowOf(geo, l, k);  // members, not bindings: OpenMP regions cannot name bindings
    const float* start_lobe = &l.start_lobe[k * kPixels];
    const float* start_inverse_h = &l.start_inverse_h[k * kPixels];
#pragma omp simd
    for (int i = 0; i < kPixels; ++i) {
      const float c = row.wx * p.n[0][i] + row.wy * p.n[1][i] + row.wz * p.n[2][i];
      const float h = row.hx * p.n[0][i] + row.hy * p.n[1][i] + row.hz * p.n[2][i];
      const float lit_c = std::max(c, 0.0f);
      float inverse_h, lobe;
      if constexpr (at_start) {
        inverse_h = start_inverse_h[i], lobe = start_lobe[i];
      } else {
        lobe = l.lobe_scale[i] * LaneExp(l.exponent[i] * LaneLogAndInverse(std::max(h, 1e-30f), &inverse_h));
      }
      const float brdf = p.rho_d[i] * kInvPiF + lobe;
      const float sigma = row.isig[i];
      const float r = (brdf * lit_c - row.b[i]) * sigma;
      const float cs = lit_c * sigma;
      const float a = c > 0.0f ? brdf * sigma : 0.0f;
      const float s = h > 0.0f ? l.exponent[i] * lobe * inverse_h * cs : 0.0f;
      const float d0 = a * (row.wx * p.t1[0][i] + row.wy * p.t1[1][i] + row.wz * p.t1[2][i]) +
                       s * (row.hx * p.t1[0][i] + row.hy * p.t1[1][i] + row.hz * p.t1[2][i]);
      const float d1 = a * (row.wx * p.t2[0][i] + row.wy * p.t2[1][i] + row.wz * p.t2[2][i]) +
                       s * (row.hx * p.t2[0][i] + row.hy * p.t2[1][i] + row.hz * p.t2[2][i]);
      const float d2 = cs * kInvPiF;
      acc[0][i] += r * r;
      acc[1][i] += d0 * d0, acc[2][i] += d0 * d1, acc[3][i] += d0 * d2;
      acc[4][i] += d1 * d1, acc[5][i] += d1 * d2, acc[6][i] += d2 * d2;
      acc[7][i] += d0 * r, acc[8][i] += d1 * r, acc[9][i] += d2 * r;
    }
  }
  for (int i = 0; i < kPixels; ++i) {
    out->cost[i] = acc[0][i];
    for (int e = 0; e < 6; ++e) out->h[e][i] = acc[1 + e][i];
    for (int e = 0; e < 3; ++e) out->g[e][i] = acc[7 + e][i];
  }
}

PHOTORIG_PS_MULTIVERSION
void Evaluate(const Geometry& geo, const Lanes& l, const Point& p, Equations* out) {
  EvaluateLanes<false>(geo, l, p, out);
}

PHOTORIG_PS_MULTIVERSION
void EvaluateAtStart(const Geometry& geo, const Lanes& l, const Point& p, Equations* out) {
  EvaluateLanes<true>(geo, l, p, out);
}

void SetNormal(const Eigen::Vector3d& n, int i, Point* p) {
  const Eigen::Vector3d u = n.normalized();
  const TangentPair<float> t = TangentBasis(static_cast<float>(u.x()), static_cast<float>(u.y()), static_cast<float>(u.z()));
  for (int a = 0; a < 3; ++a) p->n[a][i] = static_cast<float>(u[a]), p->t1[a][i] = t.t1[a], p->t2[a][i] = t.t2[a];
}

Eigen::Vector3d NormalOf(const Point& p, int i) {
  return Eigen::Vector3d(p.n[0][i], p.n[1][i], p.n[2][i]);
}

// The damped step of every lane from p with its equations: (H + lambda
// diag(H) + 1e-12 I) step = g by Cholesky, the candidate p - step (normal
// renormalised, rho_d >= 0) into q. positive[i] is 0 where the damped matrix
// is not positive definite; predicted[i] is the decrease the linearised
// model promises, 2 step.g - step.H.step.
PHOTORIG_PS_MULTIVERSION
void Propose(const Point& p, const Equations& eq, const double lambda[kPixels], Point* q, double positive[kPixels],
             double predicted[kPixels]) {
#pragma omp simd
  for (int i = 0; i < kPixels; ++i) {
    const double h00 = eq.h[0][i], h01 = eq.h[1][i], h02 = eq.h[2][i], h11 = eq.h[3][i], h12 = eq.h[4][i],
                 h22 = eq.h[5][i];
    const double g0 = eq.g[0][i], g1 = eq.g[1][i], g2 = eq.g[2][i];
    const double damping = 1.0 + lambda[i];
    const double a = h00 * damping + 1e-12;
    const double l00 = std::sqrt(std::max(a, 1e-300)), l10 = h01 / l00, l20 = h02 / l00;
    const double s11 = h11 * damping + 1e-12 - l10 * l10;
    const double l11 = std::sqrt(std::max(s11, 1e-300)), l21 = (h12 - l20 * l10) / l11;
    const double s22 = h22 * damping + 1e-12 - l20 * l20 - l21 * l21;
    const double l22 = std::sqrt(std::max(s22, 1e-300));
    positive[i] = (a > 0.0) & (s11 > 0.0) & (s22 > 0.0) ? 1.0 : 0.0;
    const double y0 = g0 / l00, y1 = (g1 - l10 * y0) / l11, y2 = (g2 - l20 * y0 - l21 * y1) / l22;
    const double x2 = y2 / l22, x1 = (y1 - l21 * x2) / l11, x0 = (y0 - l10 * x1 - l20 * x2) / l00;
    predicted[i] = 2.0 * (x0 * g0 + x1 * g1 + x2 * g2) -
                   (x0 * x0 * h00 + x1 * x1 * h11 + x2 * x2 * h22 + 2.0 * (x0 * x1 * h01 + x0 * x2 * h02 + x1 * x2 * h12));
    const float step0 = static_cast<float>(x0), step1 = static_cast<float>(x1);
    const float nx = p.n[0][i] - step0 * p.t1[0][i] - step1 * p.t2[0][i];
    const float ny = p.n[1][i] - step0 * p.t1[1][i] - step1 * p.t2[1][i];
    const float nz = p.n[2][i] - step0 * p.t1[2][i] - step1 * p.t2[2][i];
    const float inverse_length = 1.0f / std::sqrt(nx * nx + ny * ny + nz * nz);
    const float ux = nx * inverse_length, uy = ny * inverse_length, uz = nz * inverse_length;
    const TangentPair<float> t = TangentBasis(ux, uy, uz);
    q->n[0][i] = ux, q->n[1][i] = uy, q->n[2][i] = uz;
    for (int a = 0; a < 3; ++a) q->t1[a][i] = t.t1[a], q->t2[a][i] = t.t2[a];
    q->rho_d[i] = static_cast<float>(std::max(0.0, p.rho_d[i] - x2));
  }
}

void CopyLane(const Point& from, int i, Point* to) {
  for (int a = 0; a < 3; ++a) to->n[a][i] = from.n[a][i], to->t1[a][i] = from.t1[a][i], to->t2[a][i] = from.t2[a][i];
  to->rho_d[i] = from.rho_d[i];
}

// Levenberg-Marquardt from each lane's `candidate` with LobeLaneFitter's
// rules: the start is always taken; a lower cost is accepted (lambda / 3), a
// higher one rejected (lambda x 4); stop on a relative decrease within the
// tolerance or a decrease below kSettledChi2, a promised one below either,
// or lambda at 1e12. A start that does
// not evaluate is tried once more with rho_d = start_albedo. Lanes from
// `count` on idle. The fit into `current`, its cost and accepted steps.
void Descend(const Geometry& geo, const Lanes& lanes, int count, double tolerance, int max_iterations,
             const float start_albedo[kPixels], Point* candidate, Point* current, double current_cost[kPixels],
             int iterations[kPixels]) {
  Equations at_candidate, at_current;
  double lambda[kPixels];
  bool active[kPixels], restarted[kPixels];
  for (int i = 0; i < kPixels; ++i) {
    current_cost[i] = std::numeric_limits<double>::infinity();
    lambda[i] = 1e-3, iterations[i] = 0, active[i] = i < count, restarted[i] = false;
  }
  *current = *candidate;  // what a lane that never evaluates reports
  Point proposal;
  bool stepping[kPixels];
  double positive[kPixels], predicted[kPixels];
  // Until a lane steps, every candidate normal is the start's.
  for (int live = count, evaluations = 0; live > 0; ++evaluations) {
    (evaluations == 0 ? EvaluateAtStart : Evaluate)(geo, lanes, *candidate, &at_candidate);
    auto finish = [&](int i) { active[i] = false, --live; };
    for (int i = 0; i < kPixels; ++i) {
      stepping[i] = false;
      if (!active[i]) continue;
      const double cost = at_candidate.cost[i];
      const bool at_start = std::isinf(current_cost[i]);
      bool done = false;
      if (cost < current_cost[i]) {
        const double decrease = (current_cost[i] - cost) / std::max(current_cost[i], 1e-300);
        const bool settled = current_cost[i] - cost <= kSettledChi2;
        CopyLane(*candidate, i, current);
        at_current.cost[i] = at_candidate.cost[i];
        for (int e = 0; e < 6; ++e) at_current.h[e][i] = at_candidate.h[e][i];
        for (int e = 0; e < 3; ++e) at_current.g[e][i] = at_candidate.g[e][i];
        current_cost[i] = cost;
        if (!at_start) {
          ++iterations[i];
          lambda[i] = std::max(lambda[i] / 3.0, 1e-12);
          done = decrease <= tolerance || settled || iterations[i] >= max_iterations;
        }
      } else if (at_start) {
        done = restarted[i];
        if (!done) {
          restarted[i] = true;
          candidate->rho_d[i] = start_albedo[i];
          continue;  // not stepping: the candidate is evaluated as it is
        }
      } else {
        lambda[i] *= 4.0;
        done = lambda[i] >= 1e12 || cost - current_cost[i] <= tolerance * current_cost[i];
      }
      if (done) {
        finish(i);
      } else {
        stepping[i] = true;
      }
    }
    // All lanes' steps at once; a lane whose damped matrix is not positive
    // definite raises its damping and all go round again.
    ProposeWhilePositiveDefinite<kPixels>(
        stepping, lambda, positive, [&] { Propose(*current, at_current, lambda, &proposal, positive, predicted); },
        finish);
    for (int i = 0; i < kPixels; ++i) {
      if (!stepping[i]) continue;
      // The linearised model promises less than the tolerance: converged.
      if (!(predicted[i] > std::max(tolerance * current_cost[i], kSettledChi2))) {
        finish(i);
        continue;
      }
      CopyLane(proposal, i, candidate);
    }
  }
}

}  // namespace

HeldLobeLanes::HeldLobeLanes(const PhotometricStack& stack, const LambertianOptions& lambertian,
                             const BlinnPhongOptions& options)
    : samples_(stack, lambertian),
      tolerance_(std::max(options.relative_tolerance, kEvaluationPrecision)),
      max_iterations_(options.max_iterations) {
  // The half vectors as the lane fitter makes them (zero for a light
  // opposite the camera: no highlight).
  const int lights = stack.light_count();
  std::vector<double> towards_light(3 * lights), geometry(6 * lights);
  for (int k = 0; k < lights; ++k)
    for (int i = 0; i < 3; ++i) towards_light[3 * k + i] = stack.light_directions[k].normalized()[i];
  BlinnPhongGeometry(lights, towards_light.data(), stack.view_direction, geometry.data());
  for (int k = 0; k < lights; ++k) {
    half_x_.push_back(static_cast<float>(geometry[6 * k + 3]));
    half_y_.push_back(static_cast<float>(geometry[6 * k + 4]));
    half_z_.push_back(static_cast<float>(geometry[6 * k + 5]));
  }
}

void HeldLobeLanes::Fit(std::span<const HeldLobeProblem> problems, std::span<HeldLobeSolution> solutions) const {
  Run(problems, solutions, true);
}

void HeldLobeLanes::Judge(std::span<const HeldLobeProblem> problems, std::span<HeldLobeSolution> judged) const {
  Run(problems, judged, false);
}

void HeldLobeLanes::Run(std::span<const HeldLobeProblem> problems, std::span<HeldLobeSolution> solutions,
                        bool fit) const {
  const PlaneConstants c(samples_);
  const Geometry geo{c.lights, c.wx, c.wy, c.wz, half_x_.data(), half_y_.data(), half_z_.data()};
  Lanes lanes(c.lights);
  for (std::size_t first = 0; first < problems.size(); first += kPixels) {
    const int count = static_cast<int>(std::min<std::size_t>(kPixels, problems.size() - first));
    Point current, candidate;
    alignas(64) float kept[3][kPixels], start_albedo[kPixels];
    for (int i = 0; i < kPixels; ++i) {
      // A lane past the last problem repeats problem 0 of the pass.
      const HeldLobeProblem& problem = problems[first + (i < count ? i : 0)];
      lanes.pixel[i] = problem.pixel;
      lanes.dark[i] = samples_.dark ? samples_.dark[problem.pixel] : 0.0f;
      lanes.exponent[i] = static_cast<float>(problem.exponent);
      lanes.lobe_scale[i] = static_cast<float>(problem.specular_albedo * (problem.exponent + 2.0) * 0.5 *
                                               std::numbers::inv_pi);
      for (int a = 0; a < 3; ++a) kept[a][i] = static_cast<float>(problem.kept_x[a]);
      start_albedo[i] = static_cast<float>(problem.start_albedo);
      SetNormal(problem.start_normal, i, &candidate);
    }

    // The Lambertian fit on every usable sample, as LambertianOnRow.
    alignas(64) float g[6][kPixels], r[3][kPixels], used[kPixels], x[3][kPixels];
    LoadLanes(c, &lanes, g, r, used);
    bool solvable[kPixels];
    alignas(64) double well_posed[kPixels];
    SolveLambertianLanes(g, r, x, well_posed);
    for (int i = 0; i < kPixels; ++i) {
      solvable[i] = used[i] >= 3.0f;
      if (solvable[i] && well_posed[i] == 0.0) {
        // Near singular (lights nearly coplanar): pivoted LDL^T, as before.
        Eigen::Matrix3d m;
        m << g[0][i], g[1][i], g[2][i], g[1][i], g[3][i], g[4][i], g[2][i], g[4][i], g[5][i];
        const Eigen::Vector3d solution = m.ldlt().solve(Eigen::Vector3d(r[0][i], r[1][i], r[2][i]));
        for (int a = 0; a < 3; ++a) x[a][i] = static_cast<float>(solution[a]);
      }
      if (!solvable[i]) x[0][i] = x[1][i] = x[2][i] = 0.0f;
    }
    alignas(64) float chi2[kPixels], kept_chi2[kPixels];
    LambertianChi2(geo, lanes, x, kept, chi2, kept_chi2);

    double cost[kPixels];
    int iterations[kPixels] = {};
    if (fit) {
      // The start: rho_d by least squares with the lobe held at the start normal.
      alignas(64) float sum_a[kPixels], sum_b[kPixels];
      StartSums(geo, &lanes, candidate, sum_a, sum_b);
      for (int i = 0; i < kPixels; ++i)
        candidate.rho_d[i] =
            sum_a[i] > 0.0f ? std::max(0.0f, std::numbers::pi_v<float> * sum_b[i] / sum_a[i]) : start_albedo[i];
      Descend(geo, lanes, count, tolerance_, max_iterations_, start_albedo, &candidate, &current, cost, iterations);
    } else {
      for (int i = 0; i < kPixels; ++i) candidate.rho_d[i] = start_albedo[i];
      Equations at_start;
      Evaluate(geo, lanes, candidate, &at_start);
      for (int i = 0; i < kPixels; ++i) cost[i] = at_start.cost[i];
      current = candidate;
    }

    for (int i = 0; i < count; ++i) {
      HeldLobeSolution& out = solutions[first + i];
      out.ok = std::isfinite(cost[i]);
      out.normal = NormalOf(current, i).normalized();
      out.diffuse_albedo = current.rho_d[i];
      out.chi2 = cost[i];
      out.iterations = iterations[i];
      out.used = static_cast<int>(used[i]);
      out.lambertian_x = Eigen::Vector3d(x[0][i], x[1][i], x[2][i]);
      out.lambertian_chi2 = std::min(chi2[i], kept_chi2[i]);
      out.lambertian_ok = solvable[i] && std::isfinite(out.lambertian_chi2);
    }
  }
}

}  // namespace photorig::solvers::ps::internal
