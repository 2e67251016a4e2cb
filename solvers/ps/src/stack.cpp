#include "photorig/solvers/ps/stack.h"
#include "photorig/solvers/core/summary.h"

#include <cmath>
#include <sstream>

namespace photorig::solvers::ps {

bool PhotometricStack::IsValid(std::string* why) const {
  if (images.empty()) return core::Refuse(why, "the stack has no images");
  const std::size_t k = images.size();
  if (light_directions.size() != k)
    return core::Refuse(why, "the stack has " + std::to_string(k) + " images but " +
                             std::to_string(light_directions.size()) + " light directions");
  if (light_scales.size() != k)
    return core::Refuse(why, "the stack has " + std::to_string(k) + " images but " +
                             std::to_string(light_scales.size()) + " light scales");
  const cv::Size size = images.front().size();
  for (std::size_t i = 0; i < k; ++i) {
    const cv::Mat& image = images[i];
    if (image.type() != CV_32F || !image.isContinuous()) {
      return core::Refuse(why, "image " + std::to_string(i) + " is not a continuous single-channel float image");
    }
    if (image.size() != size) {
      std::ostringstream text;
      text << "image " << i << " is " << image.cols << "x" << image.rows << " but image 0 is "
           << size.width << "x" << size.height;
      return core::Refuse(why, text.str());
    }
    const double length = light_directions[i].norm();
    if (!(std::abs(length - 1.0) < 1e-6))
      return core::Refuse(why, "light direction " + std::to_string(i) + " is not unit length (|w| = " +
                               std::to_string(length) + ")");
    if (!(light_scales[i] > 0.0) || !std::isfinite(light_scales[i]))
      return core::Refuse(why, "light scale " + std::to_string(i) + " must be positive and finite");
  }
  if (!dark.empty() && (dark.type() != CV_32F || dark.size() != size || !dark.isContinuous()))
    return core::Refuse(why, "the dark frame must be a continuous float image of the stack's size");
  if (!mask.empty() && (mask.type() != CV_8U || mask.size() != size))
    return core::Refuse(why, "the mask must be an 8-bit image of the stack's size");
  if (!(noise.read_sigma >= 0.0) || !(noise.shot_gain >= 0.0)) return core::Refuse(why, "noise parameters must be >= 0");
  if (!(std::abs(view_direction.norm() - 1.0) < 1e-6)) return core::Refuse(why, "the view direction must be a unit vector");
  return true;
}

const char* PixelModelName(PixelModel model) {
  switch (model) {
    case PixelModel::kNone: return "none";
    case PixelModel::kLambertian: return "lambertian";
    case PixelModel::kTrimmed: return "trimmed";
    case PixelModel::kBlinnPhong: return "blinn_phong";
    case PixelModel::kIrls: return "irls";
    case PixelModel::kGgx: return "ggx";
    case PixelModel::kLowFrequency: return "low_frequency";
  }
  return "unknown";
}

const char* PixelFlagName(PixelFlag flag) {
  switch (flag) {
    case PixelFlag::kSolved: return "solved";
    case PixelFlag::kOutsideMask: return "outside_mask";
    case PixelFlag::kTooFewLights: return "too_few_lights";
    case PixelFlag::kIllConditioned: return "ill_conditioned";
    case PixelFlag::kRejectedByModel: return "rejected_by_model";
    case PixelFlag::kFilled: return "filled";
  }
  return "unknown";
}

}  // namespace photorig::solvers::ps
