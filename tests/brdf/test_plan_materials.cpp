// Pose plans measured on simulated materials of published (or stated)
// parameters: what a uniform and an adaptive plan let the fit recover.

#include "photorig/solvers/brdf/fit.h"

#include "plan_measurement.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

namespace photorig::solvers::brdf {
namespace {

using testing::MeasurementNoise;
using testing::PlanMaterial;

// Every parameter of `got` within `tolerance` (relative) of `truth`.
void ExpectParamsNear(const ModelParams& got, const ModelParams& truth, double tolerance, const std::string& what) {
  ASSERT_EQ(got.model, truth.model) << what;
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(got.diffuse[c], truth.diffuse[c], tolerance * truth.diffuse[c]) << what << " diffuse " << c;
    EXPECT_NEAR(got.specular[c], truth.specular[c], tolerance * truth.specular[c]) << what << " specular " << c;
  }
  EXPECT_NEAR(got.shape, truth.shape, tolerance * truth.shape) << what << " shape";
  EXPECT_NEAR(got.fresnel_f0, truth.fresnel_f0, tolerance * truth.fresnel_f0) << what << " F0";
}

double WorstRelativeError(const ModelParams& got, const ModelParams& truth) {
  double worst = std::abs(got.shape / truth.shape - 1.0);
  for (int c = 0; c < 3; ++c)
    worst = std::max({worst, std::abs(got.diffuse[c] / truth.diffuse[c] - 1.0),
                      std::abs(got.specular[c] / truth.specular[c] - 1.0)});
  if (truth.model == Model::kCookTorrance) worst = std::max(worst, std::abs(got.fresnel_f0 / truth.fresnel_f0 - 1.0));
  return worst;
}

// In-plane, 2.5 deg steps in theta_h: fine enough to see the near mirror's lobe.
SamplingSpec TestSpec() {
  SamplingSpec spec;
  spec.theta_h_steps = 25;
  return spec;
}

TEST(PlanMaterials, NoiseFreeUniformPlanRecoversEachMaterialWithItsModelChosen) {
  const PosePlan plan = PlanPoses(UniformHalfDiffGrid(TestSpec()), GonioArms());
  ASSERT_TRUE(plan.IsSolutionUsable()) << plan.message;
  for (const PlanMaterial& m : testing::PlanMaterials()) {
    MeasurementNoise noise;
    noise.add_noise = false;
    const SelectionSummary s = SelectModel(testing::MeasurePoses(m.truth, plan.poses, noise));
    ASSERT_TRUE(s.IsSolutionUsable()) << m.name << ": " << s.message;
    ASSERT_EQ(s.chosen, m.truth.model) << m.name << " chose " << ModelName(*s.chosen);
    ExpectParamsNear(s.candidates[s.chosen_index].params, m.truth, 0.02, m.name);
    std::printf("%s, %zu poses, noise-free: worst parameter error %.2g %%\n", m.name.c_str(), plan.poses.size(),
                100.0 * WorstRelativeError(s.candidates[s.chosen_index].params, m.truth));
  }
}

TEST(PlanMaterials, DefaultNoiseKeepsTheModelAndItsParametersClose) {
  const PosePlan plan = PlanPoses(UniformHalfDiffGrid(TestSpec()), GonioArms());
  for (const PlanMaterial& m : testing::PlanMaterials()) {
    const SelectionSummary s = SelectModel(testing::MeasurePoses(m.truth, plan.poses, MeasurementNoise()));
    ASSERT_TRUE(s.IsSolutionUsable()) << m.name << ": " << s.message;
    ASSERT_EQ(s.chosen, m.truth.model) << m.name << " chose " << ModelName(*s.chosen);
    const double worst = WorstRelativeError(s.candidates[s.chosen_index].params, m.truth);
    std::printf("%s, %zu poses, 2 %% + 0.002/sr noise: worst parameter error %.2f %%\n", m.name.c_str(),
                plan.poses.size(), 100.0 * worst);
    EXPECT_LT(worst, 0.10) << m.name;
  }
}

TEST(PlanMaterials, TooFewPosesForAModelAreFlaggedNotFitted) {
  // Two poses give 6 values: too few for any lobe model (7 or 8 parameters).
  SamplingSpec spec;
  spec.theta_h_max_deg = 20.0;
  spec.theta_h_steps = 2;
  spec.theta_d_min_deg = spec.theta_d_max_deg = 30.0;
  spec.theta_d_steps = 1;
  const PosePlan plan = PlanPoses(UniformHalfDiffGrid(spec), GonioArms());
  ASSERT_EQ(plan.poses.size(), 2u);
  const PlanMaterial m = testing::PlanMaterials()[1];
  const SelectionSummary s = SelectModel(testing::MeasurePoses(m.truth, plan.poses, MeasurementNoise()));
  for (const FitSummary& f : s.candidates) {
    if (f.params.model == Model::kLambertian) continue;
    EXPECT_EQ(f.termination, core::Termination::kFailure) << ModelName(f.params.model);
    EXPECT_NE(f.message.find("cannot fit the " + std::to_string(ParameterCount(f.params.model)) + " parameters"),
              std::string::npos)
        << f.message;
  }
  EXPECT_NE(s.chosen, Model::kCookTorrance);
}

TEST(PlanMaterials, AdaptivePassesFindTheNearMirrorsLobe) {
  // The same number of poses, uniform against a coarse pass plus adaptive
  // ones: the adaptive passes split the lobe's flanks, which a uniform grid
  // as coarse as the coarse pass steps over.
  const PlanMaterial m = testing::PlanMaterials()[2];
  SamplingSpec coarse;
  coarse.theta_h_steps = 7;  // 10 deg steps: the lobe (a = 0.04, about 2 deg) is seen at theta_h = 0 only
  coarse.theta_d_steps = 7;
  const testing::AdaptiveMeasurement adaptive =
      testing::MeasureAdaptively(m.truth, coarse, 80, 8, GonioArms(), MeasurementNoise());
  ASSERT_EQ(adaptive.poses.size(), 80u);
  int near_peak = 0;
  for (const PlannedPose& p : adaptive.poses) near_peak += p.requested.theta_h > 0.0 && p.requested.theta_h < 5.0 * M_PI / 180;
  EXPECT_GE(near_peak, 8);  // poses at 0 < theta_h < 5 deg, which the coarse grid has none of
  const FitSummary fit = FitModel(m.truth.model, adaptive.samples);
  ASSERT_TRUE(fit.IsSolutionUsable()) << fit.message;
  EXPECT_TRUE(fit.lobe_identifiable);
  EXPECT_NEAR(fit.params.shape, m.truth.shape, 0.05 * m.truth.shape);
}

}  // namespace
}  // namespace photorig::solvers::brdf
