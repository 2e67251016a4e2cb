// The fit's bounds and the plausibility of its parameters: lobes as sharp as
// measured ones are within the range, a shape at a bound is flagged and never
// chosen, and a fit whose F0 presses against 1 or whose albedo exceeds 1 is
// refused for the choice with the reason.
#include "photorig/solvers/brdf/fit.h"

#include "synthetic_samples.h"

#include <gtest/gtest.h>

#include <cmath>

namespace photorig::solvers::brdf {
namespace {

using testing::SyntheticSamples;
using testing::SyntheticSpec;

// Noise-free values carrying a measurement's deviations (2 % + 0.002 1/sr):
// 300 configurations within `peak_deg` of the specular peak and 300 over
// theta_h up to 60 deg.
std::vector<BrdfSample> PeakAndBroad(const ModelParams& truth, double peak_deg) {
  SyntheticSpec peak, broad;
  peak.theta_h_max_deg = peak_deg;
  broad.seed = 2;
  std::vector<BrdfSample> samples;
  for (const SyntheticSpec& spec : {peak, broad}) {
    SyntheticSpec noise_free = spec;
    noise_free.relative_sigma = noise_free.absolute_sigma = 0.0;
    for (BrdfSample s : SyntheticSamples(truth, noise_free)) {
      s.sigma = (0.02 * s.value).array() + 0.002;
      samples.push_back(s);
    }
  }
  return samples;
}

ModelParams SharpBlinnPhong(double exponent) {
  ModelParams p;
  p.model = Model::kBlinnPhong;
  p.diffuse = {0.1, 0.08, 0.05};
  p.specular = {0.3, 0.3, 0.3};
  p.shape = exponent;
  return p;
}

TEST(NormalAlbedo, ResolvesALobeOfAnyWidthTheFitAllows) {
  // Giesen's normalisation: the Blinn-Phong lobe reflects k_s at normal incidence.
  for (double e : {20.0, 1e3, 1e5, kMaxExponent}) {
    const Eigen::Vector3d a = NormalAlbedo(SharpBlinnPhong(e));
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], SharpBlinnPhong(e).diffuse[c] + 0.3, 0.003) << e;
  }
  // A broad GGX lobe agrees with the hemisphere quadrature over w_o.
  ModelParams ggx;
  ggx.model = Model::kGgx;
  ggx.diffuse = {0.2, 0.1, 0.0};
  ggx.specular = {1.0, 0.5, 0.05};
  ggx.shape = 0.3;
  const Eigen::Vector3d quadrature = DirectionalAlbedo(ggx, Eigen::Vector3d::UnitZ());
  const Eigen::Vector3d half_vector = NormalAlbedo(ggx);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(half_vector[c], quadrature[c], 0.002) << c;
}

// MERL's sharpest lobes need exponents of about 37,000; the old bound of 1e4
// pinned them. Inside the range now, recovered and not flagged.
TEST(FitBounds, ALobeAsSharpAsMeasuredOnesIsRecoveredInsideTheRange) {
  const ModelParams truth = SharpBlinnPhong(37000.0);
  const FitSummary fit = FitModel(Model::kBlinnPhong, PeakAndBroad(truth, 1.0));
  ASSERT_EQ(fit.termination, core::Termination::kSuccess) << fit.message;
  EXPECT_NEAR(fit.params.shape, truth.shape, 0.01 * truth.shape);
  EXPECT_TRUE(fit.at_bound.empty()) << fit.at_bound;
  EXPECT_TRUE(fit.lobe_identifiable) << fit.message;
  EXPECT_TRUE(fit.implausible.empty()) << fit.implausible;
}

// A lobe at or beyond the range's end: every lobe model's shape sits at its
// bound, is flagged and never chosen; the data show a lobe whose width the
// range cannot give, so the selection fails saying so rather than report
// Lambertian as if it fitted.
TEST(FitBounds, AShapeAtABoundIsFlaggedAndNeverChosen) {
  for (double exponent : {kMaxExponent, 1e6}) {
    SCOPED_TRACE(exponent);
    const std::vector<BrdfSample> samples = PeakAndBroad(SharpBlinnPhong(exponent), 0.3);
    const FitSummary fit = FitModel(Model::kBlinnPhong, samples);
    ASSERT_TRUE(fit.IsSolutionUsable()) << fit.message;
    EXPECT_NEAR(fit.params.shape, kMaxExponent, 1e-3 * kMaxExponent);
    EXPECT_NE(fit.at_bound.find("exponent"), std::string::npos) << fit.at_bound;
    EXPECT_NE(fit.at_bound.find("upper bound"), std::string::npos) << fit.at_bound;
    EXPECT_FALSE(fit.lobe_identifiable);
    EXPECT_NE(fit.message.find("not identifiable"), std::string::npos) << fit.message;

    const SelectionSummary s = SelectModel(samples);
    for (const FitSummary& f : s.candidates)
      if (f.params.model == Model::kBlinnPhong || f.params.model == Model::kTwoBlinnPhong) {
        EXPECT_FALSE(f.at_bound.empty()) << ModelName(f.params.model);
      }
    EXPECT_EQ(s.termination, core::Termination::kFailure) << s.reason;
    EXPECT_NE(s.message.find("bound"), std::string::npos) << s.message;
  }
}

// Schlick's F0 above 1 (a reflectance that falls towards grazing, as no
// material's does): Cook-Torrance's F0 presses against 1, the fit is called
// implausible, and the choice refuses it saying why.
TEST(FitPlausibility, FresnelPressingAgainstOneIsRefusedForTheChoice) {
  ModelParams truth;
  truth.model = Model::kCookTorrance;
  truth.diffuse = {0.05, 0.04, 0.03};
  truth.specular = {0.06, 0.05, 0.04};
  truth.fresnel_f0 = 1.3;
  truth.shape = 0.2;
  const std::vector<BrdfSample> samples = PeakAndBroad(truth, 10.0);
  const FitSummary fit = FitModel(Model::kCookTorrance, samples);
  ASSERT_TRUE(fit.IsSolutionUsable()) << fit.message;
  EXPECT_DOUBLE_EQ(fit.params.fresnel_f0, 1.0);
  EXPECT_NE(fit.at_bound.find("F0 pressed against its bound 1"), std::string::npos) << fit.at_bound;
  EXPECT_NE(fit.implausible.find("Fresnel reflectance above 1"), std::string::npos) << fit.implausible;

  const SelectionSummary s = SelectModel(samples);
  ASSERT_TRUE(s.chosen.has_value()) << s.message;
  EXPECT_NE(*s.chosen, Model::kCookTorrance);
  EXPECT_NE(s.reason.find("not considered, implausible:"), std::string::npos) << s.reason;
  EXPECT_NE(s.reason.find("cook_torrance (F0 pressed against 1"), std::string::npos) << s.reason;
}

// F0 = 1 is not a bound of the data: a Cook-Torrance lobe without a Fresnel
// rise fits at F0 = 1 without pressing, and stays plausible.
TEST(FitPlausibility, FresnelOfOneItselfIsNotPressing) {
  ModelParams truth;
  truth.model = Model::kCookTorrance;
  truth.diffuse = {0.05, 0.04, 0.03};
  truth.specular = {0.06, 0.05, 0.04};
  truth.fresnel_f0 = 1.0;
  truth.shape = 0.2;
  const FitSummary fit = FitModel(Model::kCookTorrance, PeakAndBroad(truth, 10.0));
  ASSERT_EQ(fit.termination, core::Termination::kSuccess) << fit.message;
  EXPECT_NEAR(fit.params.fresnel_f0, 1.0, 1e-4);
  EXPECT_TRUE(fit.at_bound.empty()) << fit.at_bound;
  EXPECT_TRUE(fit.implausible.empty()) << fit.implausible;
}

}  // namespace
}  // namespace photorig::solvers::brdf
