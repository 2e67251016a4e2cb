#pragma once
// The fit of a pixel's normal and rho_d with its Blinn-Phong lobe held
// (rho_s and e given: a region's shared lobe, `auto`'s step 5), sixteen
// pixels per pass in float lanes, straight from the stack's planes.
//
// LobeLaneFitter fits the same problem with the lobe's two parameters frozen,
// but from rows of doubles gathered beforehand, through a start grid and 5 x 5
// normal equations: a pixel's row and fit there cost several times the fit
// itself. Here a pixel's samples go from the planes to the lanes once, the
// start (rho_d by linear least squares with the lobe subtracted at the start
// normal, as BlinnPhongSharedStartLanes) is one pass, and each
// Levenberg-Marquardt iteration accumulates 3 x 3 normal equations (two
// tangent-plane steps of the normal, rho_d) with the same acceptance,
// damping and stopping rules as LobeLaneFitter, so the two land on the same
// minimum. The load pass also fits the Lambertian model to every usable sample
// (step 5's comparison, LambertianOnRow), from the same lanes. Judge
// evaluates a given fit the same way without moving it (step 6's judgement
// of the fit a pixel kept).

#include "plane_samples.h"

#include "photorig/solvers/ps/photometric_stereo.h"

#include <Eigen/Core>

#include <span>
#include <vector>

namespace photorig::solvers::ps::internal {

struct HeldLobeProblem {
  int pixel = 0;
  Eigen::Vector3d start_normal = Eigen::Vector3d::UnitZ();
  double start_albedo = 0.0;  // rho_d if the start does not evaluate
  double specular_albedo = 0.0, exponent = 1.0;  // the held lobe
  // The fit the pixel kept: x = albedo / pi n (LambertianOnRow's `kept`).
  Eigen::Vector3d kept_x = Eigen::Vector3d::Zero();
};

struct HeldLobeSolution {
  // The lobe fit: ok (a finite chi-square), normal, rho_d, chi-square on the
  // usable samples and accepted steps.
  bool ok = false;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  double diffuse_albedo = 0.0, chi2 = 0.0;
  int iterations = 0;
  // The usable samples, and LambertianOnRow's fit on them: x by unweighted
  // least squares (lambertian_ok: at least three samples, finite), its
  // chi-square the lower of x's and kept_x's (attached shadow clamped).
  int used = 0;
  bool lambertian_ok = false;
  Eigen::Vector3d lambertian_x = Eigen::Vector3d::Zero();
  double lambertian_chi2 = 0.0;
};

class HeldLobeLanes {
 public:
  // Distant lights of `stack` seen from stack.view_direction; thresholds from
  // `lambertian`, the stopping rules from `options` (BlinnPhongOptions').
  HeldLobeLanes(const PhotometricStack& stack, const LambertianOptions& lambertian, const BlinnPhongOptions& options);

  // solutions[i] answers problems[i]; any count.
  void Fit(std::span<const HeldLobeProblem> problems, std::span<HeldLobeSolution> solutions) const;
  // No fit: each problem's start (normal, start_albedo as rho_d, the lobe;
  // rho_s 0 for none) judged on the pixel's usable samples, its chi-square
  // into `chi2` (iterations 0), with the Lambertian fit as Fit's. Step 6
  // judges the fit a pixel kept so.
  void Judge(std::span<const HeldLobeProblem> problems, std::span<HeldLobeSolution> judged) const;

 private:
  // Fit (fit) or Judge (!fit).
  void Run(std::span<const HeldLobeProblem> problems, std::span<HeldLobeSolution> out, bool fit) const;

  PlaneSamples samples_;
  std::vector<float> half_x_, half_y_, half_z_;  // per light: the half vector of w and the view
  double tolerance_;
  int max_iterations_;
};

}  // namespace photorig::solvers::ps::internal
