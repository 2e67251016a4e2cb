#pragma once
// What the float lane kernels that read samples from a stack's planes share
// (lambertian_recheck, trimmed_lambertian_fit): the stack's planes, lights,
// thresholds and noise as float arrays, and the test of a sample against them.

#include "lane_math.h"
#include "photorig/solvers/ps/lambertian.h"
#include "photorig/solvers/ps/stack.h"

#include <algorithm>
#include <vector>

namespace photorig::solvers::ps::internal {

struct PlaneSamples {
  PlaneSamples(const PhotometricStack& stack, const LambertianOptions& options);

  int lights() const { return static_cast<int>(planes.size()); }

  std::vector<const float*> planes;
  const float* dark = nullptr;  // null: no dark frame
  std::vector<float> wx, wy, wz, scale, inverse_scale;
  float shadow = 0.0f, saturation = 0.0f, read_variance = 0.0f, shot_gain = 0.0f;
};

// Plain pointers and values for the kernels, which use no std::vector.
struct PlaneConstants {
  explicit PlaneConstants(const PlaneSamples& s)
      : lights(s.lights()),
        planes(s.planes.data()),
        wx(s.wx.data()),
        wy(s.wy.data()),
        wz(s.wz.data()),
        scale(s.scale.data()),
        inverse_scale(s.inverse_scale.data()),
        shadow(s.shadow),
        saturation(s.saturation),
        read_variance(s.read_variance),
        shot_gain(s.shot_gain) {}

  int lights;
  const float* const* planes;
  const float *wx, *wy, *wz, *scale, *inverse_scale;
  float shadow, saturation, read_variance, shot_gain;

  // A sample is usable when it is neither shadowed nor clipped; its variance
  // in input units follows the stack's noise model.
  PHOTORIG_LANE_INLINE bool Usable(float value, float signal) const {
    return (signal > shadow) & (value < saturation);
  }
  PHOTORIG_LANE_INLINE float Variance(float signal) const {
    return read_variance + shot_gain * std::max(signal, 0.0f);
  }
};

}  // namespace photorig::solvers::ps::internal
