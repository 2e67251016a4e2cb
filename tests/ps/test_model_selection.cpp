// The model ladder on hand-made fits: which fit it keeps, and which it asks
// for next, for each method.
#include "kernels/low_frequency_fit.h"
#include "model_selection.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

namespace photorig::solvers::ps {
namespace {

using internal::GgxFits;
using internal::kNoFit;
using internal::LadderFits;
using internal::LadderStep;
using internal::LowFrequencyFits;
using internal::ModelLadder;
using internal::PixelFit;
using internal::SharedShapeTest;
using Action = LadderStep::Action;

constexpr int kLights = 48;

// A fit on `used` samples whose chi-square is `per_dof` times its degrees of
// freedom (1: at the noise level; 3 on 40 samples: far above it).
PixelFit FitWith(int used, double per_dof, PixelModel model = PixelModel::kLambertian, int parameters = 3) {
  PixelFit fit;
  fit.ok = true;
  fit.normal = Eigen::Vector3d::UnitZ();
  fit.albedo = 0.5;
  fit.used = used;
  fit.parameters = parameters;
  fit.chi2 = per_dof * (used - parameters);
  fit.model = model;
  return fit;
}

ModelLadder Ladder(Method method) { return ModelLadder(method, ModelSelectionOptions{}, kLights); }

TEST(ModelLadder, AutoKeepsAnAdequateLambertianFitWithoutAskingForMore) {
  const PixelFit lambertian = FitWith(40, 1.0);
  const LadderStep step = Ladder(Method::kAuto).Next({&lambertian});
  ASSERT_EQ(step.action, Action::kKeep);
  EXPECT_EQ(step.keep, &lambertian);
}

TEST(ModelLadder, AutoClimbsLitRefitTrimmingAndLobeInThatOrder) {
  const ModelLadder ladder = Ladder(Method::kAuto);
  const PixelFit lambertian = FitWith(40, 3.0), trimmed = FitWith(34, 3.0, PixelModel::kTrimmed);
  const PixelFit lobe = FitWith(40, 1.0, PixelModel::kBlinnPhong, 5);
  ASSERT_FALSE(ladder.Adequate(lambertian));
  LadderFits fits{&lambertian};
  EXPECT_EQ(ladder.Next(fits).action, Action::kRefitLit);
  fits.lit = &kNoFit;  // no refit stands
  EXPECT_EQ(ladder.Next(fits).action, Action::kTrim);
  fits.robust = &trimmed;
  const LadderStep fit_lobe = ladder.Next(fits);
  ASSERT_EQ(fit_lobe.action, Action::kFitLobe);
  EXPECT_EQ(fit_lobe.start, &trimmed);  // the lobe starts from the trimmed fit
  fits.blinn_phong = &lobe;
  fits.lobe_lambertian = &lambertian;
  const LadderStep kept = ladder.Next(fits);
  ASSERT_EQ(kept.action, Action::kKeep);
  EXPECT_EQ(kept.keep, &lobe);
}

TEST(ModelLadder, AutoKeepsTheFirstAdequateRefit) {
  const ModelLadder ladder = Ladder(Method::kAuto);
  const PixelFit lambertian = FitWith(40, 3.0), good_lit = FitWith(38, 1.0), bad_lit = FitWith(38, 3.0);
  PixelFit trimmed = FitWith(34, 1.0, PixelModel::kTrimmed);
  trimmed.rejected = 6;
  EXPECT_EQ(ladder.Next({&lambertian, &good_lit}).keep, &good_lit);
  // An adequate trimmed fit that dropped samples is weighed against the lobe
  // first, and kept where the lobe does not pay for its parameters.
  EXPECT_EQ(ladder.Next({&lambertian, &bad_lit, &trimmed}).action, Action::kFitLobe);
  PixelFit lobe = FitWith(40, 3.0, PixelModel::kBlinnPhong, 5);
  lobe.chi2 = lambertian.chi2 - 1.0;
  EXPECT_EQ(ladder.Next({&lambertian, &bad_lit, &trimmed, &lobe, &lambertian}).keep, &trimmed);
  lobe.chi2 = lambertian.chi2 - 50.0;
  EXPECT_EQ(ladder.Next({&lambertian, &bad_lit, &trimmed, &lobe, &lambertian}).keep, &lobe);
}

TEST(ModelLadder, AutoLooksForALobeBehindALambertianFitBetweenTheTwoQuantiles) {
  ModelSelectionOptions options;
  options.lambertian_quantile = 0.99;  // stricter than the adequacy quantile (by default they are equal)
  const ModelLadder ladder(Method::kAuto, options, kLights);
  const std::vector<double> strict = internal::ChiSquareQuantiles(kLights, options.lambertian_quantile);
  PixelFit between = FitWith(40, 1.0);
  between.chi2 = 0.5 * (strict[37] + ladder.quantiles()[37]);
  ASSERT_TRUE(ladder.Adequate(between));
  EXPECT_EQ(ladder.Next({&between}).action, Action::kRefitLit);
  // Trimming drops nothing: the lobe decides against the Lambertian fit itself.
  const PixelFit untrimmed = FitWith(40, 1.0, PixelModel::kTrimmed);
  EXPECT_EQ(ladder.Next({&between, &kNoFit, &untrimmed}).action, Action::kFitLobe);
  PixelFit lobe = FitWith(40, 1.0, PixelModel::kBlinnPhong, 5);
  lobe.chi2 = between.chi2 - 1.0;
  EXPECT_EQ(ladder.Next({&between, &kNoFit, &untrimmed, &lobe, &between}).keep, &between);
  const PixelFit below = FitWith(40, 0.8);
  EXPECT_EQ(ladder.Next({&below}).keep, &below);
}

TEST(ModelLadder, AutoWeighsTheLobeAgainstTheLambertianFitOnItsOwnSamples) {
  const ModelLadder ladder = Ladder(Method::kAuto);
  const PixelFit lambertian = FitWith(40, 3.0);
  // Trimming failed: the lobe starts from the Lambertian fit.
  EXPECT_EQ(ladder.Next({&lambertian, &kNoFit, &kNoFit}).start, &lambertian);
  // A lobe whose chi-square is barely lower does not pay for its two parameters.
  const PixelFit same_samples = FitWith(40, 3.0);
  PixelFit lobe = FitWith(40, 3.0, PixelModel::kBlinnPhong, 5);
  lobe.chi2 = same_samples.chi2 - 1.0;
  EXPECT_EQ(ladder.Next({&lambertian, &kNoFit, &kNoFit, &lobe, &same_samples}).keep, &same_samples);
  lobe.chi2 = same_samples.chi2 - 20.0;
  EXPECT_EQ(ladder.Next({&lambertian, &kNoFit, &kNoFit, &lobe, &same_samples}).keep, &lobe);
}

TEST(ModelLadder, AutoFitsNothingRicherThanTheSamplesDetermine) {
  const ModelLadder ladder = Ladder(Method::kAuto);
  const PixelFit exact = FitWith(3, 0.0);  // no degree of freedom: nothing to test or trim
  EXPECT_EQ(ladder.Next({&exact}).keep, &exact);
  const PixelFit five = FitWith(5, 20.0);  // as many samples as the lobe's parameters
  const PixelFit trimmed = FitWith(4, 20.0, PixelModel::kTrimmed);
  ASSERT_FALSE(ladder.Adequate(five));
  ASSERT_FALSE(ladder.Adequate(trimmed));
  EXPECT_EQ(ladder.Next({&five, &kNoFit, &trimmed}).keep, &five);
}

// Step 5: a pixel kept without a lobe in a glossy region is offered the
// region's lobe, which has as many parameters of its own as the Lambertian
// fit, so chi-square alone decides.
TEST(ModelLadder, AutoOffersTheRegionsLobeOnlyToPixelsKeptWithoutOne) {
  using internal::SharedLobeFits;
  const ModelLadder ladder = Ladder(Method::kAuto);
  const PixelFit lambertian = FitWith(40, 1.0);
  for (const PixelModel model : {PixelModel::kLambertian, PixelModel::kTrimmed}) {
    const PixelFit kept = FitWith(model == PixelModel::kTrimmed ? 36 : 40, 1.0, model);
    const LadderStep ask = ladder.NextWithSharedLobe({&kept, &lambertian});
    EXPECT_EQ(ask.action, Action::kFitSharedLobe);
    EXPECT_EQ(ask.start, &kept);
    PixelFit lobe = FitWith(40, 1.0, PixelModel::kBlinnPhong, internal::kSharedLobeParameters);
    lobe.chi2 = lambertian.chi2 - 0.5;
    EXPECT_EQ(ladder.NextWithSharedLobe({&kept, &lambertian, &lobe}).keep, &lobe);
    lobe.chi2 = lambertian.chi2 + 0.5;  // the pixel's samples show less lobe than the region has
    EXPECT_EQ(ladder.NextWithSharedLobe({&kept, &lambertian, &lobe}).keep, &kept);
    lobe.ok = false;
    EXPECT_EQ(ladder.NextWithSharedLobe({&kept, &lambertian, &lobe}).keep, &kept);
  }
  // Not for a pixel that has a lobe of its own, nor where no sample is left to test one.
  const PixelFit own_lobe = FitWith(40, 1.0, PixelModel::kBlinnPhong, 5);
  EXPECT_EQ(ladder.NextWithSharedLobe({&own_lobe, &lambertian}).keep, &own_lobe);
  const PixelFit three = FitWith(3, 0.0);
  EXPECT_EQ(ladder.NextWithSharedLobe({&three, &three}).keep, &three);
  // Nor for any other method.
  for (const Method method : {Method::kL2, Method::kLambertian, Method::kRobust, Method::kBlinnPhong}) {
    const PixelFit kept = FitWith(40, 1.0);
    EXPECT_EQ(Ladder(method).NextWithSharedLobe({&kept, &lambertian}).keep, &kept) << MethodName(method);
  }
}

TEST(ModelLadder, EachSingleModelMethodAsksForItsOwnFit) {
  const PixelFit lambertian = FitWith(40, 3.0), reweighted = FitWith(40, 3.0, PixelModel::kIrls);
  const PixelFit lobe = FitWith(40, 10.0, PixelModel::kBlinnPhong, 5);
  EXPECT_EQ(Ladder(Method::kLambertian).Next({&lambertian}).keep, &lambertian);
  EXPECT_EQ(Ladder(Method::kRobust).Next({&lambertian}).action, Action::kReweight);
  EXPECT_EQ(Ladder(Method::kRobust).Next({&lambertian, nullptr, &reweighted}).keep, &reweighted);
  EXPECT_EQ(Ladder(Method::kBlinnPhong).Next({&lambertian}).action, Action::kTrim);
  EXPECT_EQ(Ladder(Method::kBlinnPhong).Next({&lambertian, nullptr, &kNoFit}).action, Action::kFitLobe);
  // `blinn-phong` keeps its lobe whatever the information criterion says.
  EXPECT_EQ(Ladder(Method::kBlinnPhong).Next({&lambertian, nullptr, &kNoFit, &lobe, &lambertian}).keep, &lobe);
}

// Where the fit a method asks for fails, the pixel keeps the rung below it,
// labelled by that rung's model and marked as a fallback; only a pixel whose
// every rung failed is left without a normal.
TEST(ModelLadder, EachMethodFallsBackWhereItsOwnFitFails) {
  const PixelFit lambertian = FitWith(40, 3.0), trimmed = FitWith(34, 3.0, PixelModel::kTrimmed);
  const ModelLadder blinn_phong = Ladder(Method::kBlinnPhong);
  LadderStep step = blinn_phong.Next({&lambertian, nullptr, &trimmed, &kNoFit, &lambertian});
  EXPECT_EQ(step.keep, &trimmed);
  EXPECT_TRUE(step.fell_back);
  step = blinn_phong.Next({&lambertian, nullptr, &kNoFit, &kNoFit, &lambertian});
  EXPECT_EQ(step.keep, &lambertian);
  EXPECT_TRUE(step.fell_back);
  step = blinn_phong.Next({&kNoFit, nullptr, &kNoFit, &kNoFit, &kNoFit});
  EXPECT_FALSE(step.keep->ok);  // nothing to fall back to: flagged
  EXPECT_FALSE(step.fell_back);
  const PixelFit lobe = FitWith(40, 1.0, PixelModel::kBlinnPhong, 5);
  step = blinn_phong.Next({&lambertian, nullptr, &trimmed, &lobe, &lambertian});
  EXPECT_EQ(step.keep, &lobe);
  EXPECT_FALSE(step.fell_back);

  const ModelLadder robust = Ladder(Method::kRobust);
  step = robust.Next({&lambertian, nullptr, &kNoFit});
  EXPECT_EQ(step.keep, &lambertian);
  EXPECT_TRUE(step.fell_back);

  // `auto`: a failed lobe leaves the Lambertian fit on the lobe's samples.
  step = Ladder(Method::kAuto).Next({&lambertian, &kNoFit, &trimmed, &kNoFit, &lambertian});
  EXPECT_EQ(step.keep, &lambertian);
  EXPECT_TRUE(step.fell_back);
}

// Step 6: a GGX lobe replaces the kept fit only where the information
// criterion prefers it on the same samples; its two parameters over a held
// lobe's (or a Lambertian fit's) cost 2 ln n, none over a lobe of its own.
TEST(ModelLadder, AutoTakesGgxWhereItsInformationCriterionIsLower) {
  const ModelLadder ladder = Ladder(Method::kAuto);
  const PixelFit held = FitWith(40, 1.2, PixelModel::kBlinnPhong, 3);  // chi2 44.4
  GgxFits fits{&held};
  const LadderStep fit = ladder.NextWithGgx(fits);
  ASSERT_EQ(fit.action, Action::kFitGgx);
  EXPECT_EQ(fit.start, &held);
  PixelFit ggx = FitWith(40, 1.0, PixelModel::kGgx, 5);  // chi2 35: 9.4 lower, 2 ln 40 = 7.4 dearer
  fits.ggx = &ggx;
  LadderStep step = ladder.NextWithGgx(fits);
  ASSERT_EQ(step.action, Action::kKeep);
  EXPECT_EQ(step.keep, &ggx);
  EXPECT_NEAR(step.evidence, 9.4 - 2.0 * std::log(40.0), 1e-9);
  ggx.chi2 = 38.0;  // 6.4 lower: not enough
  EXPECT_EQ(ladder.NextWithGgx(fits).keep, &held);
  const PixelFit own = FitWith(40, 1.1, PixelModel::kBlinnPhong, 5);  // chi2 38.5, as many parameters
  EXPECT_EQ(ladder.NextWithGgx({&own, &ggx}).keep, &ggx);
  ggx.ok = false;
  EXPECT_EQ(ladder.NextWithGgx({&own, &ggx}).keep, &own);
  // Not for a pixel with no sample beyond the lobe's parameters, nor for another method.
  const PixelFit few = FitWith(5, 2.0);
  EXPECT_EQ(ladder.NextWithGgx({&few}).keep, &few);
  EXPECT_EQ(Ladder(Method::kBlinnPhong).NextWithGgx({&held}).keep, &held);
}

// Step 7: the low-frequency fit is offered to a kept lobe that fails the
// adequacy test (unless a sampled spike pins its normal), and replaces it
// only on very strong evidence on the same samples.
TEST(ModelLadder, AutoOffersTheLowFrequencyFitToALobeThatDoesNotExplainItsSamples) {
  const ModelLadder ladder = Ladder(Method::kAuto);
  // Fits without a lobe stand, adequate or not (steps 4-6 weighed a lobe against them already).
  const PixelFit adequate = FitWith(40, 1.0), inadequate = FitWith(40, 3.0);
  const PixelFit trimmed = FitWith(36, 3.0, PixelModel::kTrimmed);
  EXPECT_EQ(ladder.NextWithLowFrequency({&adequate}).keep, &adequate);
  EXPECT_EQ(ladder.NextWithLowFrequency({&inadequate}).keep, &inadequate);
  EXPECT_EQ(ladder.NextWithLowFrequency({&trimmed}).keep, &trimmed);
  // An adequate lobe stands; an inadequate one is offered it, unless a spike pins it.
  const PixelFit good_lobe = FitWith(40, 1.0, PixelModel::kBlinnPhong, 5);
  EXPECT_EQ(ladder.NextWithLowFrequency({&good_lobe}).keep, &good_lobe);
  const PixelFit lobe = FitWith(40, 3.0, PixelModel::kBlinnPhong, 5);
  EXPECT_EQ(ladder.NextWithLowFrequency({&lobe}).action, Action::kFitLowFrequency);
  LowFrequencyFits pinned{&lobe};
  pinned.spike_pins_normal = true;
  EXPECT_EQ(ladder.NextWithLowFrequency(pinned).keep, &lobe);
  // On the 36 samples it fitted: the kept lobe's chi2 there against the low-frequency fit's.
  const PixelFit judged = FitWith(36, 2.0, PixelModel::kBlinnPhong, 5);  // chi2 62, BIC 62 + 5 ln 36
  PixelFit low = FitWith(36, 1.0, PixelModel::kLowFrequency, internal::kLowFrequencyParameters);  // chi2 30
  const LowFrequencyFits fitted{&lobe, &low, &judged};
  ASSERT_GT(judged.Bic() - low.Bic(), internal::kConfidentLobeEvidence);  // 32 - ln 36 = 28.4
  EXPECT_EQ(ladder.NextWithLowFrequency(fitted).keep, &low);
  EXPECT_EQ(ladder.NextWithLowFrequency(fitted).low_frequency_rule, internal::LowFrequencyRule::kStrongEvidence);
  low.chi2 = judged.chi2 - std::log(36.0) - 0.5 * internal::kConfidentLobeEvidence;  // lower, but not by 10
  EXPECT_EQ(ladder.NextWithLowFrequency(fitted).keep, &lobe);
  // Where the low-frequency fit is far above the noise too (chi2 / dof 100),
  // the difference counts a hundredth: 3,000 less chi-square is 30, enough;
  // 1,000 less is 10 less the penalty, not.
  low.chi2 = 100.0 * low.Dof();
  PixelFit far = judged;
  far.chi2 = low.chi2 + 3000.0;
  EXPECT_EQ(ladder.NextWithLowFrequency({&lobe, &low, &far}).keep, &low);
  far.chi2 = low.chi2 + 1000.0;
  EXPECT_EQ(ladder.NextWithLowFrequency({&lobe, &low, &far}).keep, &lobe);
  low.chi2 = 30.0;
  low.ok = false;
  EXPECT_EQ(ladder.NextWithLowFrequency(fitted).keep, &lobe);
  // Off, or another refining method: never offered.
  ModelSelectionOptions off;
  off.low_frequency = false;
  EXPECT_EQ(ModelLadder(Method::kAuto, off, kLights).NextWithLowFrequency({&lobe}).keep, &lobe);
  EXPECT_EQ(Ladder(Method::kBlinnPhong).NextWithLowFrequency({&lobe}).keep, &lobe);
}

// Step 5's shape test sums, over pixels the held lobe explains, its
// chi-square less the pixel's own lobe's: a likelihood ratio of nested
// models, so an own fit that converged worse than the held one counts 0.
TEST(ModelLadder, TheShapeTestCountsAnOwnLobeThatFitsWorseAsNoGain) {
  const ModelLadder ladder = Ladder(Method::kAuto);
  const PixelFit lambertian = FitWith(40, 3.0);                             // chi2 111
  const PixelFit held = FitWith(40, 1.0, PixelModel::kBlinnPhong, 3);       // chi2 37, adequate
  PixelFit own = FitWith(40, 0.8, PixelModel::kBlinnPhong, 5);              // chi2 28
  SharedShapeTest test;
  ladder.AddToShapeTest({&lambertian, &lambertian, &held, true, &own}, &test);
  EXPECT_EQ(test.pixels, 1);
  EXPECT_NEAR(test.chi2_gain, 9.0, 1e-12);
  own.chi2 = 45.0;  // stopped short of the held fit
  ladder.AddToShapeTest({&lambertian, &lambertian, &held, true, &own}, &test);
  EXPECT_EQ(test.pixels, 2);
  EXPECT_NEAR(test.chi2_gain, 9.0, 1e-12);
  // 2 pixels: rejects above chi-square's adequacy quantile for 4 degrees of freedom.
  EXPECT_FALSE(ladder.RejectsSharedShape(test));
  test.chi2_gain = 40.0;
  EXPECT_TRUE(ladder.RejectsSharedShape(test));
}

// A region tested on its own lobes: a lobe counts for GGX only where GGX's
// criterion is below it by very strong evidence (same parameters: by
// chi-square), and the region rejects the shape where more than half do.
TEST(ModelLadder, TheOwnLobesTestCountsVeryStrongEvidenceForGgxAndRejectsOnAMajority) {
  const ModelLadder ladder = Ladder(Method::kAuto);
  const PixelFit own = FitWith(40, 1.5, PixelModel::kBlinnPhong, 5);  // chi2 52.5
  PixelFit ggx = FitWith(40, 1.0, PixelModel::kGgx, 5);               // chi2 35: evidence 17.5
  SharedShapeTest test;
  ladder.AddToShapeTest(GgxFits{&own, &ggx}, &test);
  EXPECT_EQ(test.own_lobes, 1);
  EXPECT_EQ(test.own_lobes_ggx, 1);
  ggx.chi2 = 43.0;  // evidence 9.5: below very strong
  ladder.AddToShapeTest(GgxFits{&own, &ggx}, &test);
  ladder.AddToShapeTest(GgxFits{&own, nullptr}, &test);  // the ladder kept no GGX fit
  EXPECT_EQ(test.own_lobes, 3);
  EXPECT_EQ(test.own_lobes_ggx, 1);
  const PixelFit lambertian = FitWith(40, 1.5);  // not an own lobe: no part
  ladder.AddToShapeTest(GgxFits{&lambertian, &ggx}, &test);
  EXPECT_EQ(test.own_lobes, 3);
  EXPECT_FALSE(ladder.RejectsSharedShape(test));
  test.own_lobes_ggx = 2;
  EXPECT_TRUE(ladder.RejectsSharedShape(test));
  test = {.own_lobes = 4, .own_lobes_ggx = 2};  // half: not more than half
  EXPECT_FALSE(ladder.RejectsSharedShape(test));
}

// Step 7 in a region whose pixels reject one Blinn-Phong shape (step 5): an
// inadequate Blinn-Phong lobe there takes the low-frequency fit outright,
// without the evidence a pixel of another region needs; an adequate lobe,
// a GGX lobe (the shape step 6 offered instead), a pinned spike, a lobe the
// samples do not see and one at the exponent's lower bound do not.
TEST(ModelLadder, AutoTakesTheLowFrequencyFitForAnInadequateLobeWhereItsRegionRejectsTheShape) {
  const ModelLadder ladder = Ladder(Method::kAuto);
  const PixelFit lobe = FitWith(40, 3.0, PixelModel::kBlinnPhong, 5);
  const PixelFit judged = FitWith(36, 2.0, PixelModel::kBlinnPhong, 5);  // chi2 62 on the fit's samples
  // Worse than the lobe on its samples (chi2 90 against 62): elsewhere the lobe stands.
  PixelFit low = FitWith(36, 3.0, PixelModel::kLowFrequency, internal::kLowFrequencyParameters);
  LowFrequencyFits fits{&lobe, &low, &judged};
  // The lobe's own term moves the samples by chi-square 40: seen (the
  // two-degree quantile at the adequacy level 0.999 is 13.8).
  fits.lobe_term_chi2 = 40.0;
  EXPECT_EQ(ladder.NextWithLowFrequency(fits).keep, &lobe);
  fits.region_rejects_shape = true;
  EXPECT_EQ(ladder.NextWithLowFrequency(fits).keep, &low);
  EXPECT_EQ(ladder.NextWithLowFrequency(fits).low_frequency_rule, internal::LowFrequencyRule::kRegionRejectsShape);
  // A lobe within the noise (a sharp one between the lights whose tail
  // touches a sample) has no shape for its region to reject, nor has one as
  // broad as the diffuse term: the evidence decides, and here keeps the lobe.
  LowFrequencyFits unseen = fits;
  unseen.lobe_term_chi2 = 13.0;
  EXPECT_EQ(ladder.NextWithLowFrequency(unseen).keep, &lobe);
  unseen.lobe_term_chi2 = 14.0;
  EXPECT_EQ(ladder.NextWithLowFrequency(unseen).keep, &low);
  LowFrequencyFits broadest = fits;
  broadest.lobe_at_exponent_bound = true;
  EXPECT_EQ(ladder.NextWithLowFrequency(broadest).keep, &lobe);
  // Asked for before it is fitted, as for any inadequate lobe.
  LowFrequencyFits unfitted{&lobe};
  unfitted.region_rejects_shape = true;
  EXPECT_EQ(ladder.NextWithLowFrequency(unfitted).action, Action::kFitLowFrequency);
  // A failed low-frequency fit leaves the lobe, as does one its samples do
  // not determine (fewer degrees of freedom left than its 6 parameters).
  low.ok = false;
  EXPECT_EQ(ladder.NextWithLowFrequency(fits).keep, &lobe);
  low.ok = true;
  PixelFit few = FitWith(11, 3.0, PixelModel::kLowFrequency, internal::kLowFrequencyParameters);
  const PixelFit few_judged = FitWith(11, 2.0, PixelModel::kBlinnPhong, 5);
  LowFrequencyFits undetermined{&lobe, &few, &few_judged};
  undetermined.region_rejects_shape = true;
  undetermined.lobe_term_chi2 = fits.lobe_term_chi2;
  EXPECT_EQ(ladder.NextWithLowFrequency(undetermined).keep, &lobe);
  few = FitWith(12, 3.0, PixelModel::kLowFrequency, internal::kLowFrequencyParameters);
  EXPECT_EQ(ladder.NextWithLowFrequency(undetermined).keep, &few);
  // An adequate lobe explains its samples whatever its region says.
  const PixelFit good_lobe = FitWith(40, 1.0, PixelModel::kBlinnPhong, 5);
  LowFrequencyFits adequate{&good_lobe, &low, &judged};
  adequate.region_rejects_shape = true;
  EXPECT_EQ(ladder.NextWithLowFrequency(adequate).keep, &good_lobe);
  // A GGX lobe is judged on the evidence, as elsewhere.
  const PixelFit ggx = FitWith(40, 3.0, PixelModel::kGgx, 5);
  const PixelFit ggx_judged = FitWith(36, 2.0, PixelModel::kGgx, 5);
  LowFrequencyFits other_shape{&ggx, &low, &ggx_judged};
  other_shape.region_rejects_shape = true;
  EXPECT_EQ(ladder.NextWithLowFrequency(other_shape).keep, &ggx);
  // A sampled spike that pins the normal keeps it.
  fits.spike_pins_normal = true;
  EXPECT_EQ(ladder.NextWithLowFrequency(fits).keep, &lobe);
}

// Step 7's lobe-shift test: any lobe but a pinned spike, adequate or not,
// takes a determined low-frequency fit whose normal lies beyond the
// chi-square quantile (two degrees of freedom, at the adequacy level 0.999:
// -2 ln 0.001 = 13.82) from where the same fit puts the lobe's prediction,
// and beyond it from the lobe's own normal; below it the ladder goes on as
// without the test.
TEST(ModelLadder, AutoTakesTheLowFrequencyFitWhereItLandsAwayFromTheLobesOwn) {
  const ModelLadder ladder = Ladder(Method::kAuto);
  EXPECT_FALSE(ladder.LobeShifted(13.81));
  EXPECT_TRUE(ladder.LobeShifted(13.82));
  const PixelFit good_lobe = FitWith(40, 1.0, PixelModel::kBlinnPhong, 5);
  const PixelFit judged = FitWith(36, 1.0, PixelModel::kBlinnPhong, 5);
  // Determined but not adequate (an adequate one is the next test's case).
  const PixelFit low = FitWith(36, 2.2, PixelModel::kLowFrequency, internal::kLowFrequencyParameters);
  ASSERT_FALSE(ladder.Adequate(low));
  // Without the test an adequate lobe is not even offered the fit; with it, it is.
  LowFrequencyFits unfitted{&good_lobe};
  EXPECT_EQ(ladder.NextWithLowFrequency(unfitted).keep, &good_lobe);
  unfitted.test_lobe_shift = true;
  EXPECT_EQ(ladder.NextWithLowFrequency(unfitted).action, Action::kFitLowFrequency);
  LowFrequencyFits fits{&good_lobe, &low, &judged};
  fits.test_lobe_shift = true;
  fits.lobe_offset_chi2 = 20.0;
  fits.lobe_shift_chi2 = 13.0;
  fits.lobe_bias_chi2 = 1.0;
  EXPECT_EQ(ladder.NextWithLowFrequency(fits).keep, &good_lobe);
  fits.lobe_shift_chi2 = 14.0;
  EXPECT_EQ(ladder.NextWithLowFrequency(fits).keep, &low);
  EXPECT_EQ(ladder.NextWithLowFrequency(fits).low_frequency_rule, internal::LowFrequencyRule::kLobeShifted);
  // Not where the fit is further off on the lobe's own prediction (its
  // bias on this lobe) than the samples move it, nor where that was not measured.
  fits.lobe_bias_chi2 = 15.0;
  EXPECT_EQ(ladder.NextWithLowFrequency(fits).keep, &good_lobe);
  fits.lobe_bias_chi2 = std::numeric_limits<double>::infinity();
  EXPECT_EQ(ladder.NextWithLowFrequency(fits).keep, &good_lobe);
  fits.lobe_bias_chi2 = 1.0;
  // Nor where the two normals agree within the noise.
  fits.lobe_offset_chi2 = 13.0;
  EXPECT_EQ(ladder.NextWithLowFrequency(fits).keep, &good_lobe);
  fits.lobe_offset_chi2 = 20.0;
  // Measured but not asked for, it counts for nothing.
  fits.test_lobe_shift = false;
  EXPECT_EQ(ladder.NextWithLowFrequency(fits).keep, &good_lobe);
  fits.test_lobe_shift = true;
  // A GGX lobe the same; a pinned spike never; an undetermined fit never.
  const PixelFit ggx = FitWith(40, 1.0, PixelModel::kGgx, 5);
  LowFrequencyFits ggx_fits{&ggx, &low, &judged};
  ggx_fits.test_lobe_shift = true, ggx_fits.lobe_shift_chi2 = 14.0, ggx_fits.lobe_bias_chi2 = 1.0;
  ggx_fits.lobe_offset_chi2 = 20.0;
  EXPECT_EQ(ladder.NextWithLowFrequency(ggx_fits).keep, &low);
  fits.spike_pins_normal = true;
  EXPECT_EQ(ladder.NextWithLowFrequency(fits).keep, &good_lobe);
  fits.spike_pins_normal = false;
  const PixelFit few = FitWith(11, 1.0, PixelModel::kLowFrequency, internal::kLowFrequencyParameters);
  LowFrequencyFits undetermined{&good_lobe, &few, &judged};
  undetermined.test_lobe_shift = true, undetermined.lobe_shift_chi2 = 100.0, undetermined.lobe_bias_chi2 = 1.0;
  undetermined.lobe_offset_chi2 = 100.0;
  EXPECT_EQ(ladder.NextWithLowFrequency(undetermined).keep, &good_lobe);
  // A fit without a lobe has no lobe to test.
  const PixelFit lambertian = FitWith(40, 1.0);
  LowFrequencyFits matte{&lambertian};
  matte.test_lobe_shift = true;
  EXPECT_EQ(ladder.NextWithLowFrequency(matte).keep, &lambertian);
  // Off: the ladder does not try it.
  ModelSelectionOptions off;
  off.lobe_shift_test = false;
  EXPECT_FALSE(ModelLadder(Method::kAuto, off, kLights).lobe_shift_test());
  EXPECT_TRUE(ladder.lobe_shift_test());
  EXPECT_FALSE(Ladder(Method::kBlinnPhong).lobe_shift_test());
}

// In a scene whose lobes fail the shift test, an adequate, determined
// low-frequency fit whose normal lies beyond the noise from the lobe's
// replaces the lobe, though the lobe is adequate and bends the fit as far
// as the samples do (no shift): the difference is the lobe shape's tilt.
TEST(ModelLadder, AutoTakesAnAdequateLowFrequencyFitThatDisagreesWithTheLobeInASceneOfWrongLobes) {
  const ModelLadder ladder = Ladder(Method::kAuto);
  const PixelFit lobe = FitWith(40, 1.0, PixelModel::kBlinnPhong, 5);
  const PixelFit judged = FitWith(36, 1.0, PixelModel::kBlinnPhong, 5);
  const PixelFit low = FitWith(36, 1.2, PixelModel::kLowFrequency, internal::kLowFrequencyParameters);
  ASSERT_TRUE(ladder.Adequate(lobe));
  ASSERT_TRUE(ladder.Adequate(low));
  LowFrequencyFits fits{&lobe, &low, &judged};
  fits.test_lobe_shift = true;
  fits.lobe_offset_chi2 = 20.0;  // beyond the noise (13.82)
  fits.lobe_shift_chi2 = 1.0;    // the lobe's prediction moves the fit as the samples do
  fits.lobe_bias_chi2 = 20.0;
  EXPECT_EQ(ladder.NextWithLowFrequency(fits).keep, &low);
  EXPECT_EQ(ladder.NextWithLowFrequency(fits).low_frequency_rule, internal::LowFrequencyRule::kExplainsApart);
  // A GGX lobe the same.
  const PixelFit ggx = FitWith(40, 1.0, PixelModel::kGgx, 5);
  LowFrequencyFits ggx_fits = fits;
  ggx_fits.kept = &ggx;
  EXPECT_EQ(ladder.NextWithLowFrequency(ggx_fits).keep, &low);
  // Not where the two normals agree within the noise.
  fits.lobe_offset_chi2 = 13.0;
  EXPECT_EQ(ladder.NextWithLowFrequency(fits).keep, &lobe);
  EXPECT_EQ(ladder.NextWithLowFrequency(fits).low_frequency_rule, internal::LowFrequencyRule::kNone);
  fits.lobe_offset_chi2 = 20.0;
  // Not in a scene whose lobes pass the test, nor where a sampled spike pins the lobe's normal.
  fits.test_lobe_shift = false;
  EXPECT_EQ(ladder.NextWithLowFrequency(fits).keep, &lobe);
  fits.test_lobe_shift = true;
  fits.spike_pins_normal = true;
  EXPECT_EQ(ladder.NextWithLowFrequency(fits).keep, &lobe);
  fits.spike_pins_normal = false;
  // Not where the low-frequency fit leaves its samples unexplained, nor where they do not determine it.
  const PixelFit misfit = FitWith(36, 2.2, PixelModel::kLowFrequency, internal::kLowFrequencyParameters);
  LowFrequencyFits misfit_fits = fits;
  misfit_fits.low_frequency = &misfit;
  EXPECT_EQ(ladder.NextWithLowFrequency(misfit_fits).keep, &lobe);
  const PixelFit few = FitWith(11, 0.5, PixelModel::kLowFrequency, internal::kLowFrequencyParameters);
  ASSERT_TRUE(ladder.Adequate(few));
  LowFrequencyFits few_fits = fits;
  few_fits.low_frequency = &few;
  EXPECT_EQ(ladder.NextWithLowFrequency(few_fits).keep, &lobe);
}

// A scene's lobes fail the test as a whole where the binomial tail of the
// shifts counted, at the test's own level 0.001, is below 0.001: with 256
// tested, P(X >= 3) = 2.3e-3 and P(X >= 4) = 1.4e-4; one of one is 0.001
// exactly, not below.
TEST(ModelLadder, LobesFailTheShiftTestOnlyBeyondChance) {
  const ModelLadder ladder = Ladder(Method::kAuto);
  EXPECT_FALSE(ladder.LobesFailShiftTest(0, 256));
  EXPECT_FALSE(ladder.LobesFailShiftTest(3, 256));
  EXPECT_TRUE(ladder.LobesFailShiftTest(4, 256));
  EXPECT_TRUE(ladder.LobesFailShiftTest(200, 256));
  EXPECT_FALSE(ladder.LobesFailShiftTest(1, 1));
  EXPECT_TRUE(ladder.LobesFailShiftTest(2, 2));  // 1e-6
  EXPECT_FALSE(ladder.LobesFailShiftTest(0, 0));
  EXPECT_FALSE(ladder.LobesFailShiftTest(3, 2));
}

// The `low-frequency` method takes its fit wherever it succeeds, else falls back to the Lambertian fit.
TEST(ModelLadder, TheLowFrequencyMethodKeepsItsFitOrFallsBack) {
  const ModelLadder ladder = Ladder(Method::kLowFrequency);
  const PixelFit lambertian = FitWith(40, 1.0);
  EXPECT_EQ(ladder.Next({&lambertian}).keep, &lambertian);  // the tiles keep the pass's fit
  const LadderStep ask = ladder.NextWithLowFrequency({&lambertian});
  ASSERT_EQ(ask.action, Action::kFitLowFrequency);
  PixelFit low = FitWith(36, 5.0, PixelModel::kLowFrequency, internal::kLowFrequencyParameters);
  const PixelFit judged = FitWith(36, 1.0);
  LadderStep step = ladder.NextWithLowFrequency({&lambertian, &low, &judged});
  EXPECT_EQ(step.keep, &low);  // no comparison: the method is the model
  EXPECT_FALSE(step.fell_back);
  low.ok = false;
  step = ladder.NextWithLowFrequency({&lambertian, &low, &judged});
  EXPECT_EQ(step.keep, &lambertian);
  EXPECT_TRUE(step.fell_back);
}

TEST(ModelLadder, OnlyAutoScreensOnTheLambertianConfidence) {
  const std::vector<float> screen = Ladder(Method::kAuto).ScreenThresholds();
  ASSERT_EQ(screen.size(), kLights + 1u);
  EXPECT_TRUE(std::isinf(screen[3]));  // dof 0: never accepted unseen
  EXPECT_GT(screen[40], 0.4f);
  EXPECT_LT(screen[40], 1.0f);  // dof / quantile: a little below 1
  for (float threshold : Ladder(Method::kRobust).ScreenThresholds()) EXPECT_TRUE(std::isinf(threshold));
}

}  // namespace
}  // namespace photorig::solvers::ps
