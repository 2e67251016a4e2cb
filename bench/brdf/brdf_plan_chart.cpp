// Pose plans against fit error, for scripts/chart-brdf-plans.sh: simulated
// gonioreflectometer measurement (2 % + 0.002/sr noise) of three materials
// (tests/brdf/plan_measurement.cpp: rough Ward, Ngan et al. 2005's
// blue-metallic-paint, a near-mirror GGX) at uniform plans of growing size and
// at adaptive ones (a coarse pass, then passes of 8 poses where the measured
// value changes fastest), each fitted with the true model.
//   photorig-brdf-plan-chart RIG.yaml OUT_DIR
// writes OUT_DIR/brdf_plans.csv (material, plan, poses, measurement time,
// error) and OUT_DIR/brdf_plan_models.csv (every model's k-fold held-out error
// on one uniform plan). error = RMS over 4000 configurations of
// (f_fit - f_true) cos theta_i relative to the RMS of f_true cos theta_i.
// Measurement time = arm moves (one axis at a time, the rig's trapezoid
// profile plus its settle time, as the daemon's dry-run counts them) + per
// pose the exposure and the per-step overhead of photorig dry-run.

#include "photorig/config/recipe.h"
#include "photorig/sim/gonio.h"
#include "photorig/solvers/brdf/fit.h"

#include "plan_measurement.h"
#include "synthetic_samples.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>

using namespace photorig;
using namespace photorig::solvers::brdf;
namespace measure = photorig::solvers::brdf::testing;

namespace {

constexpr double kExposureUs = 4000.0;     // config/recipes/brdf-gonio.yaml
constexpr double kStepOverheadMs = 40.0;   // daemon PlanOptions::step_overhead_ms
constexpr int kRepeats = 5;

double Median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// Seconds to visit `poses` in order from the arms' homes.
double MeasurementSeconds(const config::MotionConfig& motion, const GonioArms& arms,
                          const std::vector<PlannedPose>& poses) {
  double light = arms.light_home_deg, camera = arms.camera_home_deg, s = 0.0;
  auto move = [&](double& at, double to) {
    const double distance = std::abs(to - at);
    if (distance > motion.settle.tolerance_deg)
      s += sim::TrapezoidMove(distance, motion.profile).duration_s() + motion.settle.settle_ms / 1000.0;
    at = to;
  };
  for (const PlannedPose& p : poses) {
    move(light, p.arms.light_arm_deg);
    move(camera, p.arms.camera_arm_deg);
    s += (kExposureUs / 1000.0 + kStepOverheadMs) / 1000.0;
  }
  return s;
}

struct Point {
  std::vector<double> error, seconds;
  int poses = 0;
  int unidentified = 0;
};

void Fit(const measure::PlanMaterial& m, const std::vector<BrdfSample>& samples, const std::vector<BrdfSample>& held_out,
         Point* point) {
  const FitSummary fit = FitModel(m.truth.model, samples);
  if (!fit.IsSolutionUsable() || !fit.lobe_identifiable) ++point->unidentified;
  point->error.push_back(fit.IsSolutionUsable() ? measure::RelativeError(fit.params, m.truth, held_out) : std::nan(""));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::cerr << "usage: photorig-brdf-plan-chart RIG.yaml OUT_DIR\n";
    return 2;
  }
  const config::RigConfig rig = config::LoadRigConfig(argv[1]);
  const std::optional<GonioArms> arms = rig.motion ? config::GonioArmsOf(*rig.motion) : std::nullopt;
  if (!arms) {
    std::cerr << argv[1] << " is not a gonioreflectometer\n";
    return 2;
  }
  const std::string dir = argv[2];
  std::ofstream plans(dir + "/brdf_plans.csv"), models(dir + "/brdf_plan_models.csv");
  plans << "material,plan,poses,measurement_s,relative_error,unidentified_of_" << kRepeats << "\n";
  models << "material,model,poses,held_out_rms_sigma,relative_error,bic,chosen_of_" << kRepeats << "\n";
  for (const measure::PlanMaterial& m : measure::PlanMaterials()) {
    measure::SyntheticSpec held_spec;
    held_spec.count = 4000;
    held_spec.seed = 999;
    const auto held_out = measure::SyntheticSamples(m.truth, held_spec);
    // Uniform: n x n in theta_h [0, 60] x theta_d [10, 70].
    for (int n : {4, 5, 6, 8, 10, 13, 17, 21, 25}) {
      SamplingSpec spec;
      spec.theta_h_steps = spec.theta_d_steps = n;
      const PosePlan plan = PlanPoses(UniformHalfDiffGrid(spec), *arms);
      Point point;
      for (int r = 0; r < kRepeats; ++r) {
        measure::MeasurementNoise noise;
        noise.seed = static_cast<std::uint32_t>(100 * n + r);
        Fit(m, measure::MeasurePoses(m.truth, plan.poses, noise), held_out, &point);
      }
      plans << m.name << ",uniform," << plan.poses.size() << ',' << MeasurementSeconds(*rig.motion, *arms, plan.poses)
            << ',' << Median(point.error) << ',' << point.unidentified << '\n';
    }
    // Adaptive: a 5 x 5 coarse pass, then passes of 8; fitted after each pass.
    SamplingSpec coarse;
    coarse.theta_h_steps = coarse.theta_d_steps = 5;
    std::vector<Point> after_pass;
    for (int r = 0; r < kRepeats; ++r) {
      measure::MeasurementNoise noise;
      noise.seed = static_cast<std::uint32_t>(7000 + 100 * r);
      const measure::AdaptiveMeasurement a = measure::MeasureAdaptively(m.truth, coarse, 400, 8, *arms, noise);
      after_pass.resize(std::max(after_pass.size(), a.poses_after_pass.size()));
      for (std::size_t k = 0; k < a.poses_after_pass.size(); ++k) {
        const int count = a.poses_after_pass[k];
        Point& point = after_pass[k];
        point.poses = count;
        Fit(m, std::vector<BrdfSample>(a.samples.begin(), a.samples.begin() + count), held_out, &point);
        point.seconds.push_back(
            MeasurementSeconds(*rig.motion, *arms, std::vector<PlannedPose>(a.poses.begin(), a.poses.begin() + count)));
      }
    }
    for (std::size_t k = 0; k < after_pass.size(); ++k)
      if (k < 4 || k % 3 == 0 || k + 1 == after_pass.size())
        plans << m.name << ",adaptive," << after_pass[k].poses << ',' << Median(after_pass[k].seconds) << ','
              << Median(after_pass[k].error) << ',' << after_pass[k].unidentified << '\n';
    // Every model's held-out error on the 25 x 13 uniform plan.
    SamplingSpec spec;
    spec.theta_h_steps = 25;
    const PosePlan plan = PlanPoses(UniformHalfDiffGrid(spec), *arms);
    const std::vector<Model> candidates = SelectionOptions{}.candidates;
    std::vector<std::vector<double>> held(candidates.size()), error(candidates.size()), bic(candidates.size());
    std::vector<int> chosen(candidates.size(), 0);
    for (int r = 0; r < kRepeats; ++r) {
      measure::MeasurementNoise noise;
      noise.seed = static_cast<std::uint32_t>(9000 + r);
      const SelectionSummary s = SelectModel(measure::MeasurePoses(m.truth, plan.poses, noise));
      for (std::size_t i = 0; i < s.candidates.size(); ++i) {
        const FitSummary& f = s.candidates[i];
        if (!f.IsSolutionUsable()) continue;
        held[i].push_back(f.held_out_rms);
        error[i].push_back(measure::RelativeError(f.params, m.truth, held_out));
        bic[i].push_back(f.bic);
      }
      if (s.IsSolutionUsable()) ++chosen[s.chosen_index];
    }
    for (std::size_t i = 0; i < candidates.size(); ++i)
      models << m.name << ',' << ModelName(candidates[i]) << ',' << plan.poses.size() << ',' << Median(held[i]) << ','
             << Median(error[i]) << ',' << Median(bic[i]) << ',' << chosen[i] << '\n';
    std::cerr << m.name << " done\n";
  }
  return 0;
}
