#include "photorig/solvers/brdf/fit.h"

#include "lobes.h"
#include "synthetic_samples.h"

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace photorig::solvers::brdf {
namespace {

using testing::SyntheticSamples;
using testing::SyntheticSpec;

ModelParams Matte() {
  ModelParams p;
  p.diffuse = {0.6, 0.4, 0.2};
  return p;
}

ModelParams GlossyGgx() {
  ModelParams p;
  p.model = Model::kGgx;
  p.diffuse = {0.25, 0.15, 0.05};
  p.specular = {0.9, 0.7, 0.5};
  p.shape = 0.15;
  return p;
}

ModelParams GlossyBlinnPhong() {
  ModelParams p;
  p.model = Model::kBlinnPhong;
  p.diffuse = {0.25, 0.15, 0.05};
  p.specular = {0.4, 0.3, 0.2};
  p.shape = 60.0;
  return p;
}

// Ngan et al. 2005's Cook-Torrance fit to MERL's blue-metallic-paint.
ModelParams BlueMetallicPaint() {
  ModelParams p;
  p.model = Model::kCookTorrance;
  p.diffuse = {0.0135, 0.00848, 0.0244};
  p.specular = {0.0719, 0.0589, 0.0813};
  p.fresnel_f0 = 0.638;
  p.shape = 0.231;
  return p;
}

ModelParams GlossyWard() {
  ModelParams p;
  p.model = Model::kWard;
  p.diffuse = {0.25, 0.15, 0.05};
  p.specular = {0.3, 0.25, 0.2};
  p.shape = 0.12;
  return p;
}

// A sharp coat (e = 400) over a broad, stronger base lobe (e = 12).
ModelParams TwoLobes() {
  ModelParams p;
  p.model = Model::kTwoBlinnPhong;
  p.diffuse = {0.2, 0.12, 0.05};
  p.specular = {0.08, 0.08, 0.08};
  p.shape = 400.0;
  p.specular2 = {0.3, 0.2, 0.1};
  p.shape2 = 12.0;
  return p;
}

// Noise-free values of `truth` that carry the deviations a measurement would
// (2 % + 0.002 1/sr), for the weighted loss.
std::vector<BrdfSample> NoiseFreeSamples(const ModelParams& truth, int count) {
  SyntheticSpec spec;
  spec.count = count;
  spec.relative_sigma = 0.0;
  spec.absolute_sigma = 0.0;
  std::vector<BrdfSample> samples = SyntheticSamples(truth, spec);
  for (BrdfSample& s : samples) s.sigma = (0.02 * s.value).array() + 0.002;
  return samples;
}

void ExpectWithinPercent(double estimate, double truth, double percent, const char* what) {
  EXPECT_NEAR(estimate, truth, std::abs(truth) * percent / 100.0) << what;
}

// (estimate - truth) / reported sd for every parameter of a fit.
std::vector<double> ZScores(const FitSummary& fit, const ModelParams& truth) {
  std::vector<double> z;
  for (int c = 0; c < 3; ++c) z.push_back((fit.params.diffuse[c] - truth.diffuse[c]) / fit.diffuse_sigma[c]);
  if (truth.model != Model::kLambertian) {
    for (int c = 0; c < 3; ++c) z.push_back((fit.params.specular[c] - truth.specular[c]) / fit.specular_sigma[c]);
    z.push_back((fit.params.shape - truth.shape) / fit.shape_sigma);
  }
  return z;
}

// Over 20 noisy data sets, the estimates scatter about the truth as their
// reported deviations say: with correct deviations 95 % of z-scores fall
// within 2 and essentially none beyond 4 (p = 6e-5 each); we ask for 85 % and
// none, so the test fails on wrong uncertainties, not on bad luck.
void ExpectRecoveredWithinUncertainty(const ModelParams& truth) {
  int within_2 = 0, total = 0;
  for (std::uint32_t seed = 1; seed <= 20; ++seed) {
    SyntheticSpec spec;
    spec.seed = seed;
    const FitSummary fit = FitModel(truth.model, SyntheticSamples(truth, spec));
    ASSERT_TRUE(fit.IsSolutionUsable()) << fit.message;
    ASSERT_TRUE(fit.covariance_available);
    ASSERT_TRUE(fit.lobe_identifiable) << fit.message;
    for (double z : ZScores(fit, truth)) {
      EXPECT_LT(std::abs(z), 4.0) << "seed " << seed;
      within_2 += std::abs(z) < 2.0;
      ++total;
    }
  }
  EXPECT_GE(within_2, 0.85 * total) << within_2 << " of " << total << " z-scores within 2";
}

TEST(BrdfFit, LambertianRecoveredWithinItsUncertainty) { ExpectRecoveredWithinUncertainty(Matte()); }
TEST(BrdfFit, BlinnPhongRecoveredWithinItsUncertainty) { ExpectRecoveredWithinUncertainty(GlossyBlinnPhong()); }
TEST(BrdfFit, GgxRecoveredWithinItsUncertainty) { ExpectRecoveredWithinUncertainty(GlossyGgx()); }

TEST(BrdfFit, LogLossRecoversNoiseFreeGgxWithoutDeviations) {
  SyntheticSpec spec;
  spec.relative_sigma = 0.0;
  spec.absolute_sigma = 0.0;
  FitOptions options;
  options.loss = FitLoss::kLog;
  const FitSummary fit = FitModel(Model::kGgx, SyntheticSamples(GlossyGgx(), spec), options);
  ASSERT_TRUE(fit.IsSolutionUsable()) << fit.message;
  EXPECT_NEAR(fit.params.shape, 0.15, 0.15 * 1e-3);
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(fit.params.diffuse[c], GlossyGgx().diffuse[c], 1e-4);
    EXPECT_NEAR(fit.params.specular[c], GlossyGgx().specular[c], 1e-3);
  }
}

// Noise-free samples of a model recover every one of its parameters within 2 %,
// with either loss.
void ExpectNoiseFreeRecovery(const ModelParams& truth) {
  for (FitLoss loss : {FitLoss::kWeighted, FitLoss::kLog}) {
    FitOptions options;
    options.loss = loss;
    const FitSummary fit = FitModel(truth.model, NoiseFreeSamples(truth, 600), options);
    SCOPED_TRACE(loss == FitLoss::kLog ? "log loss" : "weighted loss");
    ASSERT_TRUE(fit.IsSolutionUsable()) << fit.message;
    EXPECT_TRUE(fit.lobe_identifiable) << fit.message;
    for (int c = 0; c < 3; ++c) {
      ExpectWithinPercent(fit.params.diffuse[c], truth.diffuse[c], 2.0, "diffuse");
      ExpectWithinPercent(fit.params.specular[c], truth.specular[c], 2.0, "specular");
    }
    ExpectWithinPercent(fit.params.shape, truth.shape, 2.0, "shape");
    if (truth.model == Model::kCookTorrance) {
      ExpectWithinPercent(fit.params.fresnel_f0, truth.fresnel_f0, 2.0, "F0");
      EXPECT_TRUE(std::isfinite(fit.fresnel_f0_sigma));
    }
  }
}

TEST(BrdfFit, CookTorranceOfNganBlueMetallicPaintRecoveredNoiseFree) { ExpectNoiseFreeRecovery(BlueMetallicPaint()); }
TEST(BrdfFit, WardRecoveredNoiseFree) { ExpectNoiseFreeRecovery(GlossyWard()); }

TEST(BrdfSelection, PicksCookTorranceAndWardOnTheirOwnSamples) {
  for (const ModelParams& truth : {BlueMetallicPaint(), GlossyWard()}) {
    const SelectionSummary s = SelectModel(NoiseFreeSamples(truth, 600));
    ASSERT_EQ(s.termination, core::Termination::kSuccess) << s.message;
    EXPECT_EQ(s.chosen, truth.model) << ModelName(truth.model) << " chose "
                                     << (s.chosen ? ModelName(*s.chosen) : "none");
    for (const FitSummary& f : s.candidates)
      if (f.params.model != truth.model) {
        EXPECT_GT(f.bic, s.candidates[s.chosen_index].bic + 10.0) << ModelName(f.params.model);
      }
  }
}

TEST(BrdfSelection, PicksLambertianForAMatteSample) {
  const SelectionSummary s = SelectModel(SyntheticSamples(Matte(), {}));
  ASSERT_EQ(s.termination, core::Termination::kSuccess) << s.message;
  ASSERT_EQ(s.candidates.size(), 6u);
  EXPECT_EQ(s.chosen, Model::kLambertian);
  EXPECT_TRUE(s.peak_sampled);
  for (const FitSummary& f : s.candidates) EXPECT_TRUE(std::isfinite(f.bic)) << ModelName(f.params.model);
}

// The candidates' fits, then their folds, each reported once it is done.
TEST(BrdfSelection, ReportsTheFitsThenTheFolds) {
  std::vector<std::pair<std::string, std::int64_t>> reports;
  SelectionOptions options;
  options.progress = [&](const photorig::solvers::core::Progress& p) {
    EXPECT_EQ(p.done, p.total);
    reports.emplace_back(std::string(p.stage), p.total);
  };
  ASSERT_TRUE(SelectModel(SyntheticSamples(Matte(), {}), options).IsSolutionUsable());
  const std::vector<std::pair<std::string, std::int64_t>> expected = {{"fit", 6}, {"held-out", 30}};
  EXPECT_EQ(reports, expected);
}

TEST(BrdfSelection, PicksTheLobeTheGlossySampleWasMadeWith) {
  for (const ModelParams& truth : {GlossyGgx(), GlossyBlinnPhong()}) {
    const SelectionSummary s = SelectModel(SyntheticSamples(truth, {}));
    ASSERT_EQ(s.termination, core::Termination::kSuccess) << s.message;
    EXPECT_EQ(s.chosen, truth.model) << ModelName(truth.model);
    EXPECT_LT(s.candidates[s.chosen_index].bic + 10.0, s.candidates[0].bic);
    // Held out, the true model's residuals are the noise (about one sigma);
    // Lambertian's are the lobe it cannot follow.
    const double true_rms = s.candidates[s.chosen_index].held_out_rms;
    EXPECT_GT(true_rms, 0.8);
    EXPECT_LT(true_rms, 1.25);
    EXPECT_GT(s.candidates[0].held_out_rms, 5.0 * true_rms);
  }
}

TEST(BrdfSelection, ANarrowLobeNeverSampledIsFlaggedNotGuessed) {
  ModelParams truth = GlossyBlinnPhong();
  truth.shape = 2000.0;  // cos^2000 of 20 deg is e^-124: nothing reaches the samples
  SyntheticSpec spec;
  spec.theta_h_min_deg = 20.0;
  const SelectionSummary s = SelectModel(SyntheticSamples(truth, spec));
  EXPECT_FALSE(s.peak_sampled);
  EXPECT_GT(s.min_theta_h_deg, 19.9);
  EXPECT_NE(s.message.find("specular peak"), std::string::npos) << s.message;
  for (const FitSummary& f : s.candidates) {
    if (f.params.model != Model::kLambertian) {
      EXPECT_FALSE(f.lobe_identifiable) << ModelName(f.params.model) << " claims a shape of " << f.params.shape
                                        << " +- " << f.shape_sigma;
    }
  }
  if (s.IsSolutionUsable()) {
    EXPECT_EQ(s.chosen, Model::kLambertian);
  }
}

TEST(BrdfSelection, TooFewSamplesForALobeLeaveOnlyLambertian) {
  SyntheticSpec spec;
  spec.count = 2;  // 6 values: enough for 3 diffuse parameters, not for 7 or 8
  const SelectionSummary s = SelectModel(SyntheticSamples(GlossyGgx(), spec));
  ASSERT_TRUE(s.IsSolutionUsable()) << s.message;
  EXPECT_EQ(s.chosen, Model::kLambertian);
  for (std::size_t i = 1; i < s.candidates.size(); ++i) {
    EXPECT_EQ(s.candidates[i].termination, core::Termination::kFailure);
    EXPECT_NE(s.candidates[i].message.find("cannot fit the " + std::to_string(s.candidates[i].parameters) + " parameters"),
              std::string::npos)
        << s.candidates[i].message;
  }
}

// FitTable's later draw: each candidate started from an earlier fit (not its
// grid) reaches the same optimum, and the truth.
TEST(BrdfSelection, CandidatesStartedFromEarlierFitsReachTheSameOptimum) {
  const ModelParams truth = GlossyGgx();
  const std::vector<BrdfSample> samples = SyntheticSamples(truth, {});
  const SelectionSummary grid = SelectModel(samples);
  ASSERT_EQ(grid.chosen, Model::kGgx) << grid.reason;
  SelectionOptions options;
  for (const FitSummary& f : grid.candidates) options.starts.push_back(f.params);
  options.starts[0].reset();  // absent: that candidate from its grid
  const SelectionSummary started = SelectModel(samples, options);
  ASSERT_EQ(started.chosen, Model::kGgx) << started.reason;
  for (std::size_t c = 0; c < grid.candidates.size(); ++c)
    EXPECT_NEAR(started.candidates[c].cost, grid.candidates[c].cost, 1e-5 * grid.candidates[c].cost)
        << ModelName(grid.candidates[c].params.model);
  const ModelParams& fit = started.candidates[started.chosen_index].params;
  EXPECT_NEAR(fit.shape, truth.shape, 0.05 * truth.shape);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(fit.specular[c], truth.specular[c], 0.05 * truth.specular[c]);
  // A start for another model, or too few starts, is refused.
  options.starts[1] = truth;
  EXPECT_EQ(SelectModel(samples, options).termination, core::Termination::kInvalidOptions);
  options.starts.resize(2);
  EXPECT_EQ(SelectModel(samples, options).termination, core::Termination::kInvalidOptions);
}

TEST(BrdfSelection, InvalidInputAndOptionsAreRefused) {
  std::vector<BrdfSample> samples = SyntheticSamples(Matte(), {});
  EXPECT_EQ(SelectModel({}).termination, core::Termination::kInvalidInput);

  samples[3].value[1] = std::nan("");
  SelectionSummary s = SelectModel(samples);
  EXPECT_EQ(s.termination, core::Termination::kInvalidInput);
  EXPECT_NE(s.message.find("sample 3"), std::string::npos) << s.message;

  samples = SyntheticSamples(Matte(), {});
  samples[5].wo = Eigen::Vector3d(0.0, 0.6, -0.8);
  EXPECT_EQ(FitModel(Model::kLambertian, samples).termination, core::Termination::kInvalidInput);

  samples = SyntheticSamples(Matte(), {});
  samples[0].sigma = Eigen::Vector3d::Zero();
  const FitSummary weighted = FitModel(Model::kLambertian, samples);
  EXPECT_EQ(weighted.termination, core::Termination::kInvalidInput);
  EXPECT_NE(weighted.message.find("log loss"), std::string::npos);
  FitOptions log_loss;
  log_loss.loss = FitLoss::kLog;
  EXPECT_TRUE(FitModel(Model::kLambertian, samples, log_loss).IsSolutionUsable());

  SelectionOptions options;
  options.candidates.clear();
  EXPECT_EQ(SelectModel(samples, options).termination, core::Termination::kInvalidOptions);
  options = {};
  options.fit.max_iterations = 0;
  EXPECT_EQ(SelectModel(samples, options).termination, core::Termination::kInvalidOptions);
}

TEST(BrdfFit, TwoLobesRecoveredNoiseFreeNarrowerFirst) {
  const ModelParams truth = TwoLobes();
  const FitSummary fit = FitModel(Model::kTwoBlinnPhong, NoiseFreeSamples(truth, 600));
  ASSERT_TRUE(fit.IsSolutionUsable()) << fit.message;
  EXPECT_TRUE(fit.lobe_identifiable) << fit.message;
  for (int c = 0; c < 3; ++c) {
    ExpectWithinPercent(fit.params.diffuse[c], truth.diffuse[c], 2.0, "rho_d");
    ExpectWithinPercent(fit.params.specular[c], truth.specular[c], 2.0, "k_s1");
    ExpectWithinPercent(fit.params.specular2[c], truth.specular2[c], 2.0, "k_s2");
  }
  ExpectWithinPercent(fit.params.shape, truth.shape, 2.0, "e1");
  ExpectWithinPercent(fit.params.shape2, truth.shape2, 2.0, "e2");
  EXPECT_EQ(fit.parameters, 11);
}

// With 2 % + 0.002/sr noise, over several data sets: the two-lobe material is
// given two lobes (each parameter within 10 %, e1 within 15 %), a one-lobe
// Blinn-Phong never is, and the two-lobe fit of it is flagged or loses.
TEST(BrdfSelection, TwoLobesChosenForTwoLobesAndNeverForOne) {
  for (std::uint32_t seed = 1; seed <= 4; ++seed) {
    SyntheticSpec spec;
    spec.count = 400;
    spec.seed = seed;
    const ModelParams truth = TwoLobes();
    const SelectionSummary two = SelectModel(SyntheticSamples(truth, spec));
    ASSERT_EQ(two.termination, core::Termination::kSuccess) << two.message;
    ASSERT_EQ(two.chosen, Model::kTwoBlinnPhong) << "seed " << seed << ": " << two.reason;
    const FitSummary& fit = two.candidates[two.chosen_index];
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(fit.params.diffuse[c], truth.diffuse[c], 0.1 * truth.diffuse[c]) << seed;
      EXPECT_NEAR(fit.params.specular[c], truth.specular[c], 0.1 * truth.specular[c]) << seed;
      EXPECT_NEAR(fit.params.specular2[c], truth.specular2[c], 0.1 * truth.specular2[c]) << seed;
    }
    EXPECT_NEAR(fit.params.shape, truth.shape, 0.15 * truth.shape) << seed;
    EXPECT_NEAR(fit.params.shape2, truth.shape2, 0.1 * truth.shape2) << seed;
    EXPECT_NE(two.reason.find("held-out"), std::string::npos) << two.reason;

    const SelectionSummary one = SelectModel(SyntheticSamples(GlossyBlinnPhong(), spec));
    ASSERT_EQ(one.termination, core::Termination::kSuccess) << one.message;
    EXPECT_EQ(one.chosen, Model::kBlinnPhong) << "seed " << seed << ": " << one.reason;
  }
}

// A fit as ChooseModel sees it: parameters, BIC and held-out errors.
FitSummary Scored(Model model, double bic, std::vector<double> held_out) {
  FitSummary f;
  f.termination = core::Termination::kSuccess;
  f.params.model = model;
  f.parameters = ParameterCount(model);
  f.bic = bic;
  f.held_out_errors = std::move(held_out);
  return f;
}

// Held-out errors around `level`, the same wiggle for every model (paired).
std::vector<double> HeldOut(double level, double spread_per_sample = 0.0) {
  std::vector<double> e(200);
  for (std::size_t k = 0; k < e.size(); ++k) e[k] = level + 0.3 * std::sin(0.7 * k) + spread_per_sample * std::cos(1.3 * k);
  return e;
}

TEST(ModelChoice, BicAndHeldOutAgreeingMoveToTheComplexModel) {
  std::string reason;
  const auto chosen = ChooseModel({Scored(Model::kLambertian, 900.0, HeldOut(5.0)),
                                   Scored(Model::kBlinnPhong, 300.0, HeldOut(1.0))},
                                  10.0, 0.01, &reason);
  ASSERT_TRUE(chosen.has_value());
  EXPECT_EQ(*chosen, 1u) << reason;
  EXPECT_NE(reason.find("held-out"), std::string::npos) << reason;
}

// BIC prefers the complex model by far, but on samples it did not see it
// predicts no better (its gain is within the noise of the paired difference):
// the simpler one stays, and the reason says why.
TEST(ModelChoice, BicAloneDoesNotAdmitAModelThatPredictsNoBetter) {
  std::string reason;
  const auto chosen = ChooseModel({Scored(Model::kBlinnPhong, 500.0, HeldOut(1.0)),
                                   Scored(Model::kTwoBlinnPhong, 400.0, HeldOut(0.999, 0.5))},
                                  10.0, 0.01, &reason);
  ASSERT_TRUE(chosen.has_value());
  EXPECT_EQ(*chosen, 0u) << reason;
  EXPECT_NE(reason.find("not lower by more than one standard error"), std::string::npos) << reason;
  // Without held-out errors BIC alone decides.
  const auto by_bic = ChooseModel({Scored(Model::kBlinnPhong, 500.0, {}), Scored(Model::kTwoBlinnPhong, 400.0, {})},
                                  10.0, 0.01, &reason);
  EXPECT_EQ(by_bic, std::optional<std::size_t>(1u));
}

// The held-out error prefers the complex model, but BIC's gain is under the
// threshold: the simpler one stays (both criteria must agree).
TEST(ModelChoice, HeldOutAloneDoesNotAdmitAModelBicDoesNotSupport) {
  std::string reason;
  const auto chosen = ChooseModel({Scored(Model::kBlinnPhong, 500.0, HeldOut(1.0)),
                                   Scored(Model::kTwoBlinnPhong, 495.0, HeldOut(0.8))},
                                  10.0, 0.01, &reason);
  EXPECT_EQ(chosen, std::optional<std::size_t>(0u)) << reason;
}

// Forward one step at a time: from Lambertian to the best one-lobe model,
// then on to two lobes only if they beat that, not merely Lambertian.
TEST(ModelChoice, StepsThroughTheSimplestModelsFirst) {
  std::string reason;
  std::vector<FitSummary> fits = {Scored(Model::kLambertian, 5000.0, HeldOut(9.0)),
                                  Scored(Model::kBlinnPhong, 800.0, HeldOut(2.0)),
                                  Scored(Model::kGgx, 305.0, HeldOut(1.02)),
                                  Scored(Model::kTwoBlinnPhong, 300.0, HeldOut(1.0))};
  EXPECT_EQ(ChooseModel(fits, 10.0, 0.01, &reason), std::optional<std::size_t>(2u)) << reason;
  // An untrusted fit never takes part.
  fits[2].lobe_identifiable = false;
  EXPECT_EQ(ChooseModel(fits, 10.0, 0.01, &reason), std::optional<std::size_t>(3u)) << reason;
  for (FitSummary& f : fits) f.termination = core::Termination::kFailure;
  EXPECT_FALSE(ChooseModel(fits, 10.0, 0.01, &reason).has_value());
}

// An implausible fit (a Lambertian albedo of 3.6, F0 pressed against 1) is
// never chosen, however good its BIC and held-out error, and the reason says why.
TEST(ModelChoice, AnImplausibleFitIsNeverChosenAndTheReasonSaysWhy) {
  std::string reason;
  std::vector<FitSummary> fits = {Scored(Model::kLambertian, 5000.0, HeldOut(9.0)),
                                  Scored(Model::kBlinnPhong, 800.0, HeldOut(2.0)),
                                  Scored(Model::kCookTorrance, 300.0, HeldOut(1.0))};
  fits[2].implausible = "F0 pressed against 1";
  EXPECT_EQ(ChooseModel(fits, 10.0, 0.01, &reason), std::optional<std::size_t>(1u)) << reason;
  EXPECT_NE(reason.find("implausible: cook_torrance (F0 pressed against 1)"), std::string::npos) << reason;
  fits[0].implausible = "diffuse albedo rho_d (3.6, 3.6, 3.6) over 1";
  fits[1].implausible = "the lobe's albedo at normal incidence (1.2, 1.2, 1.2) over 1";
  EXPECT_FALSE(ChooseModel(fits, 10.0, 0.01, &reason).has_value());
  EXPECT_NE(reason.find("lambertian (diffuse albedo rho_d (3.6, 3.6, 3.6) over 1)"), std::string::npos) << reason;
}

// A fit the iteration limit stopped is not at its optimum: however good its
// BIC and held-out error look, it is never chosen, and the reason names it.
TEST(ModelChoice, AFitThatDidNotConvergeIsNeverChosen) {
  std::string reason;
  std::vector<FitSummary> fits = {Scored(Model::kLambertian, 5000.0, HeldOut(9.0)),
                                  Scored(Model::kBlinnPhong, 800.0, HeldOut(2.0)),
                                  Scored(Model::kTwoBlinnPhong, 300.0, HeldOut(1.0))};
  fits[2].termination = core::Termination::kNoConvergence;
  fits[2].iterations = 200;
  EXPECT_EQ(ChooseModel(fits, 10.0, 0.01, &reason), std::optional<std::size_t>(1u)) << reason;
  EXPECT_NE(reason.find("two_blinn_phong (200 iterations)"), std::string::npos) << reason;
  EXPECT_NE(reason.find("did not converge"), std::string::npos) << reason;
  // Nothing converged: no choice, and the reason still says why.
  fits[0].termination = fits[1].termination = core::Termination::kNoConvergence;
  EXPECT_FALSE(ChooseModel(fits, 10.0, 0.01, &reason).has_value());
  EXPECT_NE(reason.find("did not converge"), std::string::npos) << reason;
}

// A held-out gain within what the data resolve is no gain, however many
// standard errors it is: a noise-free table fitted by its own model and by a
// richer one (the richer BIC lower by 100 under the log loss, the held-out
// errors apart by 1e-9) keeps the simpler model.
TEST(ModelChoice, AHeldOutGainWithinTheDatasResolutionKeepsTheSimplerModel) {
  std::vector<double> simple(200), rich(200);
  for (std::size_t k = 0; k < simple.size(); ++k) {
    simple[k] = 2e-9 + 1e-10 * std::sin(0.7 * k);
    rich[k] = simple[k] - 1e-9;
  }
  std::string reason;
  const auto chosen = ChooseModel({Scored(Model::kBlinnPhong, -5000.0, simple),
                                   Scored(Model::kTwoBlinnPhong, -5100.0, rich)},
                                  10.0, 1e-6, &reason);
  EXPECT_EQ(chosen, std::optional<std::size_t>(0u)) << reason;
  EXPECT_NE(reason.find("within what the data resolve"), std::string::npos) << reason;
  // The same margins well above the floor move to the richer model.
  for (std::size_t k = 0; k < simple.size(); ++k) {
    simple[k] *= 1e4;
    rich[k] *= 1e4;
  }
  EXPECT_EQ(ChooseModel({Scored(Model::kBlinnPhong, -5000.0, simple), Scored(Model::kTwoBlinnPhong, -5100.0, rich)},
                        10.0, 1e-6, &reason),
            std::optional<std::size_t>(1u))
      << reason;
}


// A large set is fitted on an even subsample; the cost is every sample's at
// that solution, so it is never below the full fit's, and the two fits agree
// within their deviations.
TEST(BrdfFit, LargeSetsAreFittedOnASubsampleAndCostedOnAll) {
  SyntheticSpec spec;
  spec.count = 60000;
  const std::vector<BrdfSample> samples = SyntheticSamples(GlossyGgx(), spec);
  FitOptions full_options;
  full_options.max_fit_samples = 0;
  const FitSummary full = FitModel(Model::kGgx, samples, full_options);
  const FitSummary sub = FitModel(Model::kGgx, samples);  // default: 20000
  ASSERT_TRUE(full.IsSolutionUsable() && sub.IsSolutionUsable());
  EXPECT_EQ(full.fitted_samples, 60000u);
  EXPECT_EQ(sub.fitted_samples, 20000u);
  EXPECT_EQ(sub.samples, 60000u);
  EXPECT_GE(sub.cost, full.cost * (1.0 - 1e-12));
  EXPECT_LT(sub.cost, full.cost * 1.001);
  EXPECT_LT(std::abs(sub.bic - full.bic), 0.001 * full.bic);
  // The deviations are the whole set's (the subsample's scaled by 20000 / 60000).
  EXPECT_NEAR(sub.shape_sigma / full.shape_sigma, 1.0, 0.1);
  for (int c = 0; c < 3; ++c) {
    EXPECT_LT(std::abs(sub.params.diffuse[c] - full.params.diffuse[c]), 3.0 * sub.diffuse_sigma[c] * std::sqrt(3.0)) << c;
    EXPECT_LT(std::abs(sub.params.specular[c] - full.params.specular[c]), 3.0 * sub.specular_sigma[c] * std::sqrt(3.0))
        << c;
  }
  EXPECT_LT(std::abs(sub.params.shape - full.params.shape), 3.0 * sub.shape_sigma * std::sqrt(3.0));
}

// Ceres' parameter blocks of a GGX fit with the weighted loss: the
// reference the fit's deviations are checked against.
struct GgxWeightedResidual {
  Geometry g;
  Eigen::Vector3d value, sigma;
  template <typename T>
  bool operator()(const T* kd, const T* lobe, const T* scale, T* residual) const {
    using std::exp;
    const T roughness = exp(lobe[3]);
    for (int c = 0; c < 3; ++c)
      residual[c] = (kd[c] / M_PI + internal::Lobe(Model::kGgx, lobe[c], roughness, scale[0], g) - value[c]) / sigma[c];
    return true;
  }
};

// The deviations are the diagonal of (J^T J)^-1 at the solution, computed
// from the solver's own Jacobian: the same as ceres::Covariance (DENSE_SVD)
// gives on the same residuals.
TEST(BrdfFit, DeviationsAreCeresCovarianceOfTheSolution) {
  const std::vector<BrdfSample> samples = SyntheticSamples(GlossyGgx(), {});
  const FitSummary fit = FitModel(Model::kGgx, samples);
  ASSERT_TRUE(fit.IsSolutionUsable()) << fit.message;
  ASSERT_TRUE(fit.covariance_available);
  const ModelParams& p = fit.params;
  double kd[3] = {p.diffuse[0], p.diffuse[1], p.diffuse[2]};
  double lobe[4] = {p.specular[0], p.specular[1], p.specular[2], std::log(p.shape)};
  double scale[1] = {p.specular_scale};
  ceres::Problem problem;
  for (const BrdfSample& s : samples)
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<GgxWeightedResidual, 3, 3, 4, 1>(
                                 new GgxWeightedResidual{GeometryOf(s.wi, s.wo), s.value, s.sigma}),
                             nullptr, kd, lobe, scale);
  ceres::Covariance::Options options;
  options.algorithm_type = ceres::DENSE_SVD;
  ceres::Covariance covariance(options);
  const std::vector<const double*> blocks = {kd, lobe, scale};
  std::vector<std::pair<const double*, const double*>> pairs;
  for (const double* a : blocks)
    for (const double* b : blocks) pairs.emplace_back(a, b);
  Eigen::Matrix<double, 8, 8, Eigen::RowMajor> cov;
  ASSERT_TRUE(covariance.Compute(pairs, &problem) && covariance.GetCovarianceMatrix(blocks, cov.data()));
  const Eigen::Matrix<double, 8, 1> sd = cov.diagonal().cwiseSqrt();
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(fit.diffuse_sigma[c], sd[c], 1e-6 * sd[c]) << c;
    EXPECT_NEAR(fit.specular_sigma[c], sd[3 + c], 1e-6 * sd[3 + c]) << c;
  }
  EXPECT_NEAR(fit.shape_sigma, p.shape * sd[6], 1e-6 * p.shape * sd[6]);
  EXPECT_NEAR(fit.specular_scale_sigma, sd[7], 1e-6 * sd[7]);
}

// A start near the optimum (as each held-out fold gets: the fit to all
// samples) reaches the grid start's solution in fewer iterations.
TEST(BrdfFit, AStartNearTheOptimumReachesTheSameSolution) {
  const std::vector<BrdfSample> samples = SyntheticSamples(GlossyGgx(), {});
  const FitSummary grid = FitModel(Model::kGgx, samples);
  ASSERT_TRUE(grid.IsSolutionUsable()) << grid.message;
  FitOptions options;
  options.start = GlossyGgx();  // the truth, not the optimum of these noisy samples
  options.start->shape *= 1.3;
  const FitSummary started = FitModel(Model::kGgx, samples, options);
  ASSERT_TRUE(started.IsSolutionUsable()) << started.message;
  EXPECT_NEAR(started.params.shape, grid.params.shape, 1e-4 * grid.params.shape);
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(started.params.diffuse[c], grid.params.diffuse[c], 1e-4 * grid.params.diffuse[c]) << c;
    EXPECT_NEAR(started.params.specular[c], grid.params.specular[c], 1e-4 * grid.params.specular[c]) << c;
  }
  EXPECT_NEAR(started.cost, grid.cost, 1e-6 * grid.cost);

  // A start of another model is a caller's mistake, named.
  options.start = GlossyBlinnPhong();
  const FitSummary wrong = FitModel(Model::kGgx, samples, options);
  EXPECT_EQ(wrong.termination, core::Termination::kInvalidOptions);
  EXPECT_NE(wrong.message.find("blinn_phong"), std::string::npos) << wrong.message;
  options.start->shape = std::nan("");
  EXPECT_EQ(FitModel(Model::kBlinnPhong, samples, options).termination, core::Termination::kInvalidOptions);
  // SelectModel fits several models: one start cannot serve them all.
  SelectionOptions selection;
  selection.fit.start = GlossyGgx();
  EXPECT_EQ(SelectModel(samples, selection).termination, core::Termination::kInvalidOptions);
}

}  // namespace
}  // namespace photorig::solvers::brdf
