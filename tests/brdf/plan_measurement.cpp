#include "plan_measurement.h"

#include <algorithm>
#include <random>

namespace photorig::solvers::brdf::testing {

std::vector<PlanMaterial> PlanMaterials() {
  std::vector<PlanMaterial> materials(3);
  materials[0] = {"rough_ward", "chosen: a matte plastic with a broad sheen (no published fit used)",
                  {Model::kWard, {0.30, 0.25, 0.20}, {0.12, 0.12, 0.12}, 0.30}};
  materials[1] = {"blue_metallic_paint",
                  "Ngan et al. 2005, Cook-Torrance fit of MERL blue-metallic-paint",
                  {Model::kCookTorrance, {0.0135, 0.00848, 0.0244}, {0.0719, 0.0589, 0.0813}, 0.231, 0.638}};
  materials[2] = {"near_mirror_ggx", "chosen: a polished metal, GGX a = 0.04 and F0 near aluminium's",
                  {Model::kGgx, {0.01, 0.01, 0.01}, {0.91, 0.92, 0.92}, 0.04}};
  return materials;
}

std::vector<BrdfSample> MeasurePoses(const ModelParams& truth, const std::vector<PlannedPose>& poses,
                                     const MeasurementNoise& noise) {
  std::mt19937 rng(noise.seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::vector<BrdfSample> samples;
  for (const PlannedPose& pose : poses) {
    const DirectionPair d = ArmDirections(pose.arms);
    BrdfSample s;
    s.wi = d.wi;
    s.wo = d.wo;
    const Eigen::Vector3d f = Evaluate(truth, s.wi, s.wo);
    s.sigma = noise.relative_sigma * f.array() + noise.absolute_sigma;
    s.value = f;
    if (noise.add_noise)
      for (int c = 0; c < 3; ++c) s.value[c] += s.sigma[c] * gauss(rng);
    samples.push_back(s);
  }
  return samples;
}

std::vector<PlanSample> PlanSamplesOf(const std::vector<PlannedPose>& poses, const std::vector<BrdfSample>& samples) {
  std::vector<PlanSample> out;
  for (std::size_t i = 0; i < poses.size(); ++i) out.push_back({poses[i].requested, samples[i].value.mean()});
  return out;
}

AdaptiveMeasurement MeasureAdaptively(const ModelParams& truth, const SamplingSpec& coarse, int total_poses,
                                      int per_pass, const GonioArms& arms, const MeasurementNoise& noise) {
  AdaptiveMeasurement m;
  const PosePlan first = PlanPoses(UniformHalfDiffGrid(coarse), arms);
  m.poses = first.poses;
  MeasurementNoise pass_noise = noise;
  m.samples = MeasurePoses(truth, m.poses, pass_noise);
  m.poses_after_pass.push_back(static_cast<int>(m.poses.size()));
  while (static_cast<int>(m.poses.size()) < total_poses && !m.poses.empty()) {
    PosePlanOptions plan_options;
    plan_options.start = m.poses.back().arms;
    AdaptiveOptions options;
    options.added_poses = std::min(per_pass, total_poses - static_cast<int>(m.poses.size()));
    const AdaptiveProposal proposal = ProposeDenserPoses(PlanSamplesOf(m.poses, m.samples), arms, plan_options, options);
    if (!proposal.IsSolutionUsable()) break;
    ++pass_noise.seed;
    const std::vector<BrdfSample> added = MeasurePoses(truth, proposal.plan.poses, pass_noise);
    m.poses.insert(m.poses.end(), proposal.plan.poses.begin(), proposal.plan.poses.end());
    m.samples.insert(m.samples.end(), added.begin(), added.end());
    m.poses_after_pass.push_back(static_cast<int>(m.poses.size()));
  }
  return m;
}

}  // namespace photorig::solvers::brdf::testing
