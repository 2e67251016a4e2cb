#pragma once
// The lobe fit (Blinn-Phong, or GGX for `auto`'s step 6) of many pixels
// under one set of lights, one pixel per SIMD lane. A pixel's Levenberg-Marquardt fit is a few iterations, each a
// pass over its K samples with a pow per sample; run one pixel at a time that
// pass is scalar (and, with forward-mode derivatives, carries six tangents
// through every operation). Here kFloatLanes pixels share each pass: the light
// loop is the same for all, the per-lane control flow (accept, reject,
// converge) runs between passes, and a lane whose fit has converged takes
// the next pixel at once, so no lane idles while others finish. The pass
// itself runs in float, sixteen pixels per AVX-512 register (the model and
// its derivatives need no more than float's seven digits against data whose
// noise is in the second or third); the iteration's state, its normal
// equations and the damped steps stay in double.
//
// Derivatives are the closed forms of the autodiff library's symbolic
// Jacobians (SymbolicBlinnPhongJacobian, SymbolicGgxJacobian; the tests check
// the lanes' Jacobian against forward-mode automatic differentiation). The
// normal moves on the sphere: each step is in the tangent plane of the current
// normal, so the normal has two parameters and the 5 x 5 normal equations
// are well posed, where the three-component form is singular along n.

#include "lane_math.h"
#include "photorig/solvers/ps/photometric_stereo.h"

#include <Eigen/Core>

#include <algorithm>
#include <memory>
#include <span>
#include <vector>

namespace photorig::solvers::ps::internal {

// Start material for a Blinn-Phong fit at a fixed normal: the exponent from a
// doubling grid over [min_exponent, max_exponent] (each grid lobe is the
// previous one squared, so no pow), with rho_d and rho_s >= 0 for each by
// linear least squares; the grid point with the lowest chi-square wins.
// cos_light and cos_half are the clamped cosines of each sample's light and
// half vector with the normal, weight 1 / variance (0 drops the sample);
// start_albedo is rho_d if no grid point fits. From this start
// Levenberg-Marquardt needs a few iterations, not tens.
struct BlinnPhongMaterial {
  double diffuse_albedo = 0.0, specular_albedo = 0.0, exponent = 1.0;
};
struct alignas(64) LaneMaterial {
  double diffuse_albedo[kFloatLanes], specular_albedo[kFloatLanes], exponent[kFloatLanes];
};
// kFloatLanes pixels at once, one per lane; arrays are [light * kFloatLanes + lane],
// and cos_light, cos_half and observed are overwritten.
void BlinnPhongGridStartLanes(int lights, double* cos_light, double* cos_half, double* observed, const double* weight,
                              const double* start_albedo, double min_exponent, double max_exponent,
                              LaneMaterial* out);
// One pixel (lane 0 of the above).
BlinnPhongMaterial BlinnPhongGridStart(int samples, const double* cos_light, const double* cos_half,
                                       const double* observed, const double* weight, double start_albedo,
                                       const BlinnPhongOptions& options);
// The start where the lobe is given (rho_s and e per lane, a region's shared
// lobe): rho_d >= 0 by linear least squares with the lobe subtracted. The
// inputs are only read.
void BlinnPhongSharedStartLanes(int lights, const double* cos_light, const double* cos_half, const double* observed,
                                const double* weight, const double* start_albedo, const double* specular_albedo,
                                const double* exponent, LaneMaterial* out);

// One pixel: observed values in solver units for every light of the set, and
// 1 / sigma for each (0 marks a sample the fit must not use); for a fitter
// made without shared lights, the pixel's own geometry (BlinnPhongGeometry:
// under near LEDs and a perspective camera every pixel has its own light and
// half vectors) and, for its GGX lobe, its own view.
struct LobeProblem {
  const double* observed = nullptr;
  const double* inverse_sigma = nullptr;
  Eigen::Vector3d start_normal = Eigen::Vector3d::UnitZ();
  double start_albedo = 0.0;  // rho_d if no grid point fits
  // shared_exponent > 0: the lobe is held at (shared_specular_albedo,
  // shared_exponent), the one the pixel's region shares, and only the normal
  // and rho_d are fitted.
  double shared_specular_albedo = 0.0, shared_exponent = 0.0;
  const double* geometry = nullptr;
  Eigen::Vector3d view = Eigen::Vector3d::UnitZ();  // towards the camera; the half vectors' (geometry's)
};

struct LobeSolution {
  bool ok = false;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  double diffuse_albedo = 0.0, specular_albedo = 0.0;
  double exponent = 0.0;  // Blinn-Phong's e; GGX's roughness a
  double chi2 = 0.0;
  int iterations = 0;  // accepted steps
};

// The geometry the fit reads for one pixel: per light its unit vector
// towards the light w (3) then the half vector of w and `view` (3), the unit
// vector towards the camera; six doubles per light into `geometry`. A light
// exactly opposite the camera has no half vector (zero): no highlight.
void BlinnPhongGeometry(int lights, const double* towards_light, const Eigen::Vector3d& view, double* geometry);

// The lobe a fitter fits. Blinn-Phong: rho_d / pi + rho_s (e + 2) / (2 pi) h^e
// (autodiff::BlinnPhongPixel). GGX: rho_d / pi + rho_s D G1 G1 / (4 v.n)
// with roughness a (autodiff::GgxPixel); GGX problems start from a roughness
// grid (GgxGridStartLanes) and hold no lobe.
enum class LaneLobe { kBlinnPhong, kGgx };

// GGX's roughness range: below 0.01 the lobe falls between the lights of any
// practical dome; 1 is the broadest lobe GGX has.
inline constexpr double kMinGgxRoughness = 0.01, kMaxGgxRoughness = 1.0;
// The roughness grid a GGX fit starts from: each point a factor 1.4 from the
// last, so the best is within a sixth of the width of the lobe that made the samples.
inline constexpr double kGgxStartRoughness[] = {0.03, 0.042, 0.06, 0.084, 0.12, 0.17, 0.24, 0.33, 0.47, 0.66};

// Non-negative least squares in a model's two linear columns d (diffuse) and
// l (lobe) from their weighted sums dd = d.d, dl, ll, db = d.b, lb and
// bb = b.b: the free solution, else the better of the two with one held at
// 0; and the chi-square it leaves. The GGX starts' fit at each grid point.
struct TwoColumnFit {
  double diffuse = 0.0, lobe = 0.0, chi2 = 0.0;
};
inline TwoColumnFit NonNegativeTwoColumnFit(double dd, double dl, double ll, double db, double lb, double bb) {
  const double det = dd * ll - dl * dl;
  double d = (ll * db - dl * lb) / det, l = (dd * lb - dl * db) / det;
  if (!(det > 0.0 && d >= 0.0 && l >= 0.0)) {
    const double only_d = dd > 0.0 ? std::max(0.0, db / dd) : 0.0;
    const double only_l = ll > 0.0 ? std::max(0.0, lb / ll) : 0.0;
    const bool diffuse = 2.0 * only_d * db - only_d * only_d * dd >= 2.0 * only_l * lb - only_l * only_l * ll;
    d = diffuse ? only_d : 0.0, l = diffuse ? 0.0 : only_l;
  }
  return {d, l, bb - 2.0 * (d * db + l * lb) + d * d * dd + 2.0 * d * l * dl + l * l * ll};
}

class LobeLaneFitter {
 public:
  // light_directions: unit vectors towards the lights; view: towards the camera.
  LobeLaneFitter(const std::vector<Eigen::Vector3d>& light_directions, const Eigen::Vector3d& view,
                 const BlinnPhongOptions& options, LaneLobe lobe = LaneLobe::kBlinnPhong);
  // A fitter whose problems each bring their own geometry (LobeProblem::geometry, and view for GGX).
  LobeLaneFitter(int lights, const BlinnPhongOptions& options, LaneLobe lobe = LaneLobe::kBlinnPhong);
  ~LobeLaneFitter();
  LobeLaneFitter(LobeLaneFitter&&) noexcept;

  // Fits every problem; solutions[i] answers problems[i].
  void Fit(std::span<const LobeProblem> problems, std::span<LobeSolution> solutions);

  // The normal equations a fit builds at one point, to check its derivatives:
  // cost = sum r^2 with r = (I - observed) / sigma, hessian = J^T J and
  // gradient = J^T r, J taken w.r.t. (steps along tangent[0] and tangent[1],
  // rho_d, rho_s, e or a); tangent is the basis the fitter uses at `normal`.
  struct Linearization {
    double cost = 0.0;
    Eigen::Matrix<double, 5, 5> hessian;
    Eigen::Matrix<double, 5, 1> gradient;
    Eigen::Vector3d tangent[2];
  };
  Linearization Linearize(const LobeProblem& problem, const Eigen::Vector3d& normal, double diffuse_albedo,
                          double specular_albedo, double exponent);

 private:
  struct State;  // lane registers, in lobe_lane_fit.cpp

  // Every problem's start material, kFloatLanes problems per pass.
  void GridStarts(std::span<const LobeProblem> problems);
  void Load(int lane, const LobeProblem& problem, const BlinnPhongMaterial& start);
  // A problem's samples into a lane, with per_lane_geometry_ its geometry and view too.
  void LoadSamples(int lane, const LobeProblem& problem);

  int lights_;
  BlinnPhongOptions options_;
  LaneLobe lobe_ = LaneLobe::kBlinnPhong;
  double min_shape_, max_shape_;  // the bounds of e (Blinn-Phong) or a (GGX)
  Eigen::Vector3d view_ = Eigen::Vector3d::UnitZ();  // towards the camera, every lane's unless per_lane_geometry_
  // Per light: w (3), w_h (3), shared by every lane; or, with
  // per_lane_geometry_, each lane's in float, [(6 light + i) * kFloatLanes + lane].
  std::vector<double> geometry_;
  std::vector<float> evaluation_geometry_;  // the same in float
  // view_ in float; or, with per_lane_geometry_, each lane's, [i * kFloatLanes + lane].
  std::vector<float> evaluation_view_;
  bool per_lane_geometry_ = false;
  // Struct-of-arrays over lanes: [light * kFloatLanes + lane].
  std::vector<float> observed_, inverse_sigma_;
  // The start grid's inputs, [light * kFloatLanes + lane], and its answers per problem.
  std::vector<double> cos_light_, cos_half_, start_observed_, weight_;
  std::vector<BlinnPhongMaterial> starts_;
  std::unique_ptr<State> state_;
};

}  // namespace photorig::solvers::ps::internal
