#include "model_selection.h"

#include "photorig/solvers/core/normal_quantile.h"

#include <cmath>
#include <limits>

namespace photorig::solvers::ps::internal {

namespace {

// Wilson and Hilferty's cube-root approximation of the chi-square quantile
// with `dof` degrees of freedom at the normal quantile z.
double WilsonHilferty(int dof, double z) {
  const double v = dof, t = 1.0 - 2.0 / (9.0 * v) + z * std::sqrt(2.0 / (9.0 * v));
  return v * t * t * t;
}

}  // namespace

double ChiSquareQuantile(int dof, double p) { return WilsonHilferty(dof, core::NormalQuantile(p)); }

std::vector<double> ChiSquareQuantiles(int max_dof, double p) {
  // One normal quantile for every dof: its bisection is 200 erfc calls, as
  // long as a matte tile's refinement.
  const double z = core::NormalQuantile(p);
  std::vector<double> quantile(max_dof + 1, 0.0);
  for (int dof = 1; dof <= max_dof; ++dof) quantile[dof] = WilsonHilferty(dof, z);
  return quantile;
}

bool ModelLadder::RejectsSharedShape(const SharedShapeTest& test) const {
  return (test.pixels > 0 && test.chi2_gain > ChiSquareQuantile(2 * test.pixels, adequacy_quantile_)) ||
         (test.own_lobes > 0 && 2 * test.own_lobes_ggx > test.own_lobes);
}

ModelLadder::ModelLadder(Method method, const ModelSelectionOptions& options, int lights)
    : method_(method),
      quantile_(ChiSquareQuantiles(lights, options.adequacy_quantile)),
      lambertian_quantile_(ChiSquareQuantiles(lights, options.lambertian_quantile)),
      gross_u2_(options.gross_outlier_sigma * options.gross_outlier_sigma),
      max_rejected_fraction_(options.max_rejected_fraction),
      adequacy_quantile_(options.adequacy_quantile),
      two_dof_quantile_(-2.0 * std::log1p(-options.adequacy_quantile)),
      low_frequency_(options.low_frequency),
      lobe_shift_test_(options.lobe_shift_test) {}

bool ModelLadder::LobesFailShiftTest(int shifted, int tested) const {
  if (shifted <= 0 || shifted > tested) return false;
  // P(X >= shifted) for X binomial(tested, alpha), summed term by term (no
  // difference of nearly equal numbers): below alpha, chance is not the
  // explanation. A single lobe tested and shifted is exactly alpha: not enough.
  const double alpha = 1.0 - adequacy_quantile_;
  double term = std::pow(1.0 - alpha, tested), tail = 0.0;
  for (int i = 0; i <= tested; ++i) {
    if (i >= shifted) tail += term;
    term *= (tested - i) / (i + 1.0) * alpha / (1.0 - alpha);
  }
  return tail < alpha;
}

std::vector<float> ModelLadder::ScreenThresholds() const {
  const int lights = static_cast<int>(quantile_.size()) - 1;
  std::vector<float> threshold(lights + 1, std::numeric_limits<float>::infinity());
  if (method_ == Method::kAuto)
    for (int dof = 1; dof + 3 <= lights; ++dof)
      threshold[dof + 3] = static_cast<float>(dof / lambertian_quantile_[dof]);
  return threshold;
}

}  // namespace photorig::solvers::ps::internal
