#pragma once
// Fitting the analytic models of models.h to measured samples
// (Levenberg-Marquardt on forward-mode automatic derivatives, the step
// projected onto bounds keeping the albedos, GGX's scale and every F0
// non-negative and F0 <= 1; the covariance from Ceres), and choosing the
// simplest model the data support.
//
// Fitting space (FitLoss):
//   kWeighted  residual (f_model - f_measured) / sigma per sample and channel,
//              in BRDF units (1/sr): a chi-square, the right loss when the
//              deviations are known; the parameter covariance is then absolute.
//   kLog       residual log(1 + f_model cos theta_i) - log(1 + f_measured cos theta_i)
//              (Löw et al. 2012): cosine-weighted and compressed, for samples
//              without deviations; the covariance is scaled by the residual
//              variance.
// The lobe's shape (exponent or roughness) is fitted as its logarithm, so its
// reported uncertainty is relative in essence and the solver never tries a
// negative one.
//
// Large sample sets (a whole measured table) are fitted on an evenly spaced
// subsample (FitOptions::max_fit_samples); the cost and BIC are then those of
// every sample at the subsample's solution.

#include "photorig/solvers/brdf/models.h"
#include "photorig/solvers/brdf/samples.h"
#include "photorig/solvers/core/names.h"
#include "photorig/solvers/core/progress.h"
#include "photorig/solvers/core/summary.h"

#include <Eigen/Core>

#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace photorig::solvers::brdf {

// The lobe shapes a fit may reach. Roughness (Ward's a, GGX's a,
// Beckmann's m) from 0.003, a lobe about 0.2 deg wide, narrower than the
// sharpest measured ones (MERL's need m of about 0.007), to 1; the
// Blinn-Phong exponent from 1 to 2 / 0.003^2 = 222,222, the same width
// (cos^e theta_h ~ exp(-e theta_h^2 / 2) against exp(-theta_h^2 / m^2)).
// A shape at either end is a bound, not an estimate (FitSummary::at_bound).
inline constexpr double kMinRoughness = 0.003, kMaxRoughness = 1.0;
inline constexpr double kMinExponent = 1.0, kMaxExponent = 2.0 / (kMinRoughness * kMinRoughness);

enum class FitLoss { kWeighted, kLog };
inline constexpr core::NameTable<FitLoss, 2> kFitLossNames = {{{FitLoss::kWeighted, "weighted"}, {FitLoss::kLog, "log"}}};
inline const char* FitLossName(FitLoss loss) { return core::NameOf(kFitLossNames, loss); }

struct FitOptions {
  FitLoss loss = FitLoss::kWeighted;  // kWeighted needs sigma > 0 on every sample
  int max_iterations = 200;           // Levenberg-Marquardt iterations
  // A lobe whose fitted shape has a relative standard deviation above this
  // (or no covariance at all) is flagged not identifiable: the samples do not
  // pin its width down, typically because none lies near the specular peak.
  double max_relative_shape_sigma = 0.25;
  // The least residual variance the log loss's tests assume (the F0 bound's
  // score test): 1e-6, an RMS of 0.1 % in log(1 + f cos theta_i), below any
  // measured table's accuracy. A noise-free table's residuals are the
  // optimiser's rounding, which is not noise to test against.
  double min_log_residual_variance = 1e-6;
  // Above this many samples the least squares see every (n / max)-th sample
  // only (in the order given: a table's grid order makes that a stratified
  // subsample over theta_h, theta_d and phi_d); 0 = always all of them.
  // The final cost, BIC and the covariance's scale come from all samples.
  std::size_t max_fit_samples = 20000;
  // Where the least squares start; absent = the best point of a grid over the
  // lobe's shape (and F0), with the linear parameters solved at each. Its
  // model must be the one fitted. SelectModel starts each held-out fold from
  // the fit to all samples: a fold lacks only 1/folds of them, so its optimum
  // is near, and the grid (most of a fit's cost) is not needed again.
  std::optional<ModelParams> start;

  bool IsValid(std::string* why) const;
};

struct FitSummary : core::Summary {
  ModelParams params;
  // One standard deviation of each parameter from the covariance (NaN where
  // the covariance could not be computed).
  Eigen::Vector3d diffuse_sigma = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  Eigen::Vector3d specular_sigma = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  double shape_sigma = std::numeric_limits<double>::quiet_NaN();
  double fresnel_f0_sigma = std::numeric_limits<double>::quiet_NaN();      // cook_torrance only
  double specular_scale_sigma = std::numeric_limits<double>::quiet_NaN();  // ggx only
  // two_blinn_phong only: the second lobe's.
  Eigen::Vector3d specular2_sigma = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  double shape2_sigma = std::numeric_limits<double>::quiet_NaN();
  bool covariance_available = false;
  // False when a lobe's shape is not pinned down (see FitOptions) or sits at
  // a bound of its range, for two lobes either one's; always true for
  // Lambertian. A fit with an unidentifiable lobe is not a result.
  bool lobe_identifiable = true;
  // The parameters the fit left at a bound, in words ("exponent 2.222e+05 at
  // its upper bound"); empty when none. A shape at a bound means the optimum
  // lies beyond it; F0 (Cook-Torrance, GGX) counts only when the data press
  // against 1, i.e. the loss still falls towards F0 > 1 (score test, below),
  // since F0 = 1 is a lobe without a Fresnel rise, not a bound of the data.
  std::string at_bound;
  // The albedo at normal incidence per channel, rho_d plus the lobes' (by
  // quadrature over theta_h, which resolves any lobe the bounds allow).
  Eigen::Vector3d normal_albedo = Eigen::Vector3d::Zero();
  // Why the parameters are not physically plausible, empty when they are:
  // rho_d over 1, the lobes' albedo at normal incidence over 1, or F0 pressed
  // against 1 (a Fresnel reflectance that would fall towards grazing).
  // ChooseModel refuses such a fit.
  std::string implausible;

  std::size_t samples = 0;
  std::size_t fitted_samples = 0;  // the subsample the least squares saw (FitOptions::max_fit_samples)
  std::size_t residuals = 0;  // samples x 3 channels
  int parameters = 0;
  double cost = 0.0;  // sum of squared residuals (a chi-square for kWeighted)
  // Bayesian information criterion: cost + k ln n for kWeighted,
  // n ln(cost / n) + k ln n for kLog; lower is better.
  double bic = 0.0;
  int iterations = 0;
  // RMS residual (in the loss's units: sigmas for kWeighted) of samples the
  // fit did not see, over SelectionOptions::held_out_folds folds; NaN when
  // not computed. About 1 for the right model with the weighted loss.
  double held_out_rms = std::numeric_limits<double>::quiet_NaN();
  // Each sample's held-out squared residual (mean over channels) when its
  // fold was left out; empty when not computed. SelectModel compares models
  // sample by sample on these.
  std::vector<double> held_out_errors;
};

FitSummary FitModel(Model model, const std::vector<BrdfSample>& samples, const FitOptions& options = {});

struct SelectionOptions {
  FitOptions fit;
  std::vector<Model> candidates = {Model::kLambertian, Model::kBlinnPhong,   Model::kWard,
                                   Model::kGgx,        Model::kCookTorrance, Model::kTwoBlinnPhong};
  // A model is chosen over one with fewer parameters only when its BIC is
  // lower by more than this (10: "very strong" evidence on Kass and
  // Raftery's scale) and, with held-out folds, its held-out error is lower
  // too (see ChooseModel).
  double min_bic_improvement = 10.0;
  // A held-out gain (the mean squared error's, in the loss's units) at or
  // below this is no gain, however small its standard error: the data do
  // not resolve it, and the simpler model stands. Weighted loss: 0.01
  // sigma^2 (predicting half a percent of the noise's RMS better). Log loss:
  // 1e-6, an RMS of 1e-3 in log(1 + f cos theta_i), 0.1 % of the value,
  // far below any measured table's accuracy: a noise-free table fitted by
  // its own model and by a richer one differs by the fits' precision there.
  double min_held_out_gain_weighted = 0.01;
  double min_held_out_gain_log = 1e-6;
  // The samples are said to see the specular peak when one has theta_h below this.
  double peak_theta_h_deg = 5.0;
  // Folds of the held-out error (sample k, i.e. pose k, in fold k mod
  // folds, unless `folds` says otherwise; 0 = none, BIC alone chooses). Each
  // costs one more fit per candidate.
  int held_out_folds = 5;
  // Each sample's fold in [0, held_out_folds), or empty (fold k mod
  // held_out_folds). FitTable puts whole theta_h bands in one fold, so that
  // no held-out sample shares its theta_h level with the fit that predicts it.
  std::vector<int> folds;
  // The least squares of each held-out fold see at most this many of its
  // samples (evenly spaced, as FitOptions::max_fit_samples), starting from
  // the fit to all samples: a fold only needs its parameters near the
  // optimum to predict the samples it left out, and on a whole table the
  // folds were most of the choice's time. 0 = FitOptions::max_fit_samples. Default 5000.
  std::size_t fold_fit_samples = 5000;
  // Each candidate's start (FitOptions::start), absent for its grid; empty:
  // every candidate from its grid. FitTable starts a later draw's fits from
  // the previous draw's, which estimate the same all-cell loss.
  std::vector<std::optional<ModelParams>> starts;
  // Called once the candidates are fitted (stage "fit") and once their folds
  // are (stage "held-out"); a whole measured table takes a second or two.
  core::ProgressCallback progress;

  bool IsValid(std::string* why) const;
};

struct SelectionSummary : core::Summary {
  std::vector<FitSummary> candidates;  // one per SelectionOptions::candidates, in that order
  std::optional<Model> chosen;
  std::size_t chosen_index = 0;
  double min_theta_h_deg = 0.0;  // the sample nearest the specular peak
  bool peak_sampled = false;     // min_theta_h_deg < peak_theta_h_deg
  std::string reason;            // why the chosen model, in words (ChooseModel)
};

// The choice among fitted candidates. Only trusted fits (converged: kSuccess,
// lobes identifiable, parameters plausible) take part; one the iteration
// limit stopped (kNoConvergence) is usable but never chosen, and `reason`
// names it, as it names each implausible fit with why.
// Starting from the trusted fit with the fewest parameters (ties: lower
// BIC), the choice moves to another fit when that one
//   - has as many parameters and a lower BIC, or
//   - has more parameters, a BIC lower by more than min_bic_improvement and,
//     when both carry held-out errors, a held-out mean squared error lower by
//     more than one standard error of the sample-by-sample difference and by
//     more than min_held_out_gain;
// among the fits it may move to, to the one with the fewest parameters (ties:
// the lowest BIC), and again from there until none qualifies. So BIC ranks,
// and a more complex model must also predict samples it did not see better. Returns the chosen index
// into `fits` (nothing when no fit is trusted) and says why in `reason`.
std::optional<std::size_t> ChooseModel(const std::vector<FitSummary>& fits, double min_bic_improvement,
                                       double min_held_out_gain, std::string* reason);

// Fits every candidate (and its held-out folds) and chooses by ChooseModel.
// The candidates' fits run in parallel, then every (candidate, fold) pair.
// Ends kFailure when no candidate is usable, or when a lobe model is far
// better than every trusted one but its shape is not identifiable (the data
// show a lobe whose width they cannot give).
SelectionSummary SelectModel(const std::vector<BrdfSample>& samples, const SelectionOptions& options = {});

}  // namespace photorig::solvers::brdf
