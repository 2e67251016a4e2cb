#pragma once
// Solves W sigma = b for the volume sigma (1/mm) by one of four iterations:
//
//   kArt:  Kaczmarz's row action (algebraic reconstruction technique): one
//          sweep visits every valid ray once, views in a shuffled order, and
//          projects sigma onto the ray's hyperplane, relaxed by lambda.
//   kSirt: simultaneous: sigma += lambda C W^T R (b - W sigma), with R and C
//          the inverse row and column sums of W (the ASTRA / Gregor-Benson form).
//   kSart: ordered-subsets SART (Andersen & Kak 1984; Censor & Elfving 2002),
//          a subset being one view: for each view v in a spread-out order
//          (bit-reversed angles), sigma += lambda C_v W_v^T R_v (b_v - W_v sigma),
//          with R_v, C_v the inverse row and column sums of that view's rays.
//          A pass (each view's rows walked once, then the residual's forward
//          projection for the stopping rule) costs 1.3-1.5 SIRT
//          iterations (measured, docs/tomography.md) and does the work of
//          some ten.
//   kCgls: conjugate gradients on the normal equations; the fastest to the
//          least-squares solution, but no non-negativity (a projection would
//          break its conjugacy).
// ART, SART and SIRT project onto sigma >= 0 (an absorbing sample) after every update.
//
// SART can add total-variation regularisation (ASD-POCS, Sidky & Pan 2008):
// after each pass, tv_steps steepest-descent steps on the volume's isotropic
// TV, together as long as tv_strength times that pass's own data step, so
// that the prior fades as the data fit settles. It assumes a piecewise-
// constant sample (it flattens smooth gradients and thin detail), which the
// data do not say, so it is off unless asked for. The TV steps hold the
// residual above what SART alone reaches: with the discrepancy rule, the
// passes also end at the balance of the two, where a pass lowers the residual
// by less than the noise resolves (kStagnation; see Reconstruct's loop).
//
// ART and SART with a fixed relaxation end in a limit cycle on inconsistent
// data: their residual stops falling above the noise level. That ends
// kFailure (StopReason::kLimitCycle: the volume holds the last pass, for
// inspection, not for use) unless the residual reached the noise level.
//
// With noisy b these iterations semi-converge: the error to the true volume
// falls, then rises as they start fitting the noise. The discrepancy principle
// (Morozov) stops them without a ground truth: at the first iteration whose
// residual ||W sigma - b|| over the valid rays falls to
//   tau * sqrt(sum of var(b)),
// the level the noise alone explains. var(b) comes from the flats and darks
// (Absorbance::variance) or from a given noise_sigma.
//
// What the summary flags rather than hides:
//   * no signal: b is within its noise (sigma = 0 already fits it) -> kFailure;
//   * too few views: fewer valid rays than min_rays_per_voxel times the voxels
//     the rays reach -> kFailure; fewer rays than voxels is reported as
//     underdetermined (the prior, non-negativity and early stopping carry it);
//   * inconsistent data: the residual stalls well above the noise level (a wrong
//     centre of rotation, bad flats, scatter) -> kNoConvergence with the flag;
//   * voxels no valid ray reaches: left at 0 and counted.

#include "photorig/solvers/core/names.h"
#include "photorig/solvers/core/progress.h"
#include "photorig/solvers/core/summary.h"
#include "photorig/solvers/tomography/absorbance.h"
#include "photorig/solvers/tomography/projector.h"

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace photorig::solvers::tomography {

enum class Method { kArt, kSirt, kCgls, kSart };
inline constexpr core::NameTable<Method, 4> kMethodNames = {
    {{Method::kSirt, "sirt"}, {Method::kArt, "art"}, {Method::kCgls, "cgls"}, {Method::kSart, "sart"}}};
inline std::optional<Method> ParseMethod(std::string_view name) { return core::ParseName(kMethodNames, name); }
inline const char* MethodName(Method method) { return core::NameOf(kMethodNames, method); }

enum class StopRule {
  kDiscrepancy,  // stop when the residual reaches the noise level (needs a noise estimate)
  kIterations    // run max_iterations
};

enum class StopReason {
  kNone,           // did not iterate (failed before)
  kDiscrepancy,    // the residual reached the noise level
  kMaxIterations,  // max_iterations came first
  kStagnation,     // the residual stopped falling (SIRT, CGLS, SART with TV at its balance: converged)
  kLimitCycle      // ART, SART without TV: the residual stopped falling, the iterates cycling
};

const char* StopReasonName(StopReason reason);

struct ReconstructOptions {
  Method method = Method::kSirt;
  int max_iterations = 200;  // sweeps for ART, passes for SART
  // How messages name max_iterations to whoever set it: the CLI's flag
  // (--max-iterations), a recipe's key.
  std::string iteration_limit_name = "max_iterations";
  // Relaxation lambda; 0 picks the method's default: ART 0.25 (gentle sweeps,
  // so that the stopping rule has iterations to choose between), SART 0.25
  // (on the 128^2 Shepp-Logan slice at 1 % noise the error minimum comes at
  // pass 15: steps fine enough for the rule to stop near it; 0.5 reaches it
  // at 7 and 1.0 at 3, where one pass too many costs 5-10 %), SIRT 1.9
  // (within its (0, 2) range of convergence). CGLS has none.
  double relaxation = 0.0;
  bool non_negative = true;  // ART, SART and SIRT; CGLS cannot keep it
  // Total-variation regularisation, SART only (see above). Off by default.
  bool total_variation = false;
  // The TV steps of a pass move the volume by this times the pass's data
  // step. Default 1.0: on the 128^2 Shepp-Logan slice at 1 % noise it
  // lowers the stopped error from 0.110 to 0.071 (0.5: 0.085), stopped at
  // tau 1.2; at tau 1 its residual stays above the level (0.5 reaches it).
  double tv_strength = 1.0;
  int tv_steps = 10;  // steepest-descent steps a pass
  StopRule stop_rule = StopRule::kDiscrepancy;
  double discrepancy_factor = 1.0;  // tau in the rule above; 1 is Morozov's choice
  // Standard deviation of every b when the measurements carry no variance
  // (0: none given; the discrepancy rule then needs Absorbance::variance).
  double noise_sigma = 0.0;
  // Fewer valid rays per reached voxel than this is too few views. Default
  // 0.25: 64 views of 128 pixels for a 128^2 slice give 0.5 and reconstruct well.
  double min_rays_per_voxel = 0.25;
  // Stops when an iteration lowers the residual by less than this fraction.
  double stagnation_tolerance = 1e-5;
  // Called after every iteration with its number (from 1) and the volume: for
  // error-against-iterations charts. It must not keep the reference.
  std::function<void(int, const Eigen::VectorXf&)> on_iteration;
  // Stage: the method's name; total: max_iterations. A stopping rule that
  // ends the iterations sooner is reported as Progress::stopped.
  solvers::core::ProgressCallback progress;

  bool IsValid(std::string* why) const;
};

struct ReconstructionSummary : solvers::core::Summary {
  Method method = Method::kSirt;
  int iterations = 0;
  double relaxation = 0.0;               // the lambda used
  double tv_strength = 0.0;              // 0: no TV regularisation
  // ||W sigma - b|| over valid rays; [0] before the first iteration. SART's
  // entries far from the stopping target are the residual its views met during
  // the pass (no extra forward projection); the last entry is always exact.
  std::vector<double> residual_history;
  double discrepancy_target = 0.0;       // tau sqrt(sum var(b)); 0 when no noise estimate
  StopReason stop_reason = StopReason::kNone;
  std::int64_t rays_used = 0;
  std::int64_t voxels_reached = 0;  // voxels some valid ray crosses
  std::int64_t voxels_unreached = 0;
  bool underdetermined = false;  // rays_used < voxels_reached
  bool inconsistent = false;     // the residual stalled above 1.5 x the noise level
};

// Fills *sigma (voxels, 1/mm) from the measurements of the rays `system`
// holds. *sigma is the starting point when it has the right size, otherwise
// it starts from zero. ART and SART visit one ray or one view at a time and
// need a Projector (every row in this process); another SystemMatrix with
// them ends kInvalidOptions.
ReconstructionSummary Reconstruct(const SystemMatrix& system, const Absorbance& measurements,
                                  const ReconstructOptions& options, Eigen::VectorXf* sigma);

}  // namespace photorig::solvers::tomography
