#include "plane_samples.h"

#include <cmath>
#include <limits>

namespace photorig::solvers::ps::internal {

PlaneSamples::PlaneSamples(const PhotometricStack& stack, const LambertianOptions& options) {
  for (int k = 0; k < stack.light_count(); ++k) {
    planes.push_back(stack.images[k].ptr<float>());
    wx.push_back(static_cast<float>(stack.light_directions[k].x()));
    wy.push_back(static_cast<float>(stack.light_directions[k].y()));
    wz.push_back(static_cast<float>(stack.light_directions[k].z()));
    scale.push_back(static_cast<float>(stack.light_scales[k]));
    inverse_scale.push_back(static_cast<float>(1.0 / stack.light_scales[k]));
  }
  dark = stack.dark.empty() ? nullptr : stack.dark.ptr<float>();
  shadow = static_cast<float>(options.shadow_threshold);
  saturation = std::isfinite(options.saturation_level) ? static_cast<float>(options.saturation_level)
                                                       : std::numeric_limits<float>::infinity();
  read_variance = static_cast<float>(stack.noise.read_sigma * stack.noise.read_sigma);
  shot_gain = static_cast<float>(stack.noise.shot_gain);
}

}  // namespace photorig::solvers::ps::internal
