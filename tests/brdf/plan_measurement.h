#pragma once
// Simulated gonioreflectometer measurement of materials given by published
// (or stated) model parameters at planned poses, uniform or adaptive: for the
// plan tests and the plan chart (bench/brdf/brdf_plan_chart.cpp).

#include "photorig/solvers/brdf/models.h"
#include "photorig/solvers/brdf/pose_plan.h"
#include "photorig/solvers/brdf/samples.h"

#include <cstdint>
#include <string>
#include <vector>

namespace photorig::solvers::brdf::testing {

struct PlanMaterial {
  std::string name;
  std::string source;  // where the parameters come from
  ModelParams truth;
};

// A rough, a glossy and a near-mirror material (see the sources).
std::vector<PlanMaterial> PlanMaterials();

// Gaussian noise of sd relative_sigma * f + absolute_sigma (1/sr), which the
// samples carry as their sigma; without noise the values are exact and the
// sigma is still that (the weighted loss needs one).
struct MeasurementNoise {
  bool add_noise = true;
  double relative_sigma = 0.02;
  double absolute_sigma = 0.002;
  std::uint32_t seed = 1;
};

// One sample per pose, in the poses' order.
std::vector<BrdfSample> MeasurePoses(const ModelParams& truth, const std::vector<PlannedPose>& poses,
                                     const MeasurementNoise& noise);

// What ProposeDenserPoses reads: each pose's requested angles and the channels' mean.
std::vector<PlanSample> PlanSamplesOf(const std::vector<PlannedPose>& poses, const std::vector<BrdfSample>& samples);

struct AdaptiveMeasurement {
  std::vector<PlannedPose> poses;  // in capture order: the coarse plan, then each pass's
  std::vector<BrdfSample> samples;  // one per pose
  std::vector<int> poses_after_pass;  // pose count after the coarse pass and after each added pass
};

// A coarse uniform pass (`coarse`), then passes of `per_pass` proposed poses
// each (every pass starting where the last ended) until `total_poses` or no
// interval is left to split.
AdaptiveMeasurement MeasureAdaptively(const ModelParams& truth, const SamplingSpec& coarse, int total_poses,
                                      int per_pass, const GonioArms& arms, const MeasurementNoise& noise);

}  // namespace photorig::solvers::brdf::testing
