#include "photorig/sim/world.h"

#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace photorig::sim {
namespace {

const WorldConfig& Validated(const WorldConfig& config) {
  std::string why;
  if (!config.camera.IsValid(&why)) throw std::invalid_argument("simulated camera: " + why);
  if (!config.scene.IsValid(&why)) throw std::invalid_argument("simulated scene: " + why);
  if (config.scene.shape == Scene::Shape::kMesh && config.camera.projection != CameraModel::Projection::kOrthographic)
    throw std::invalid_argument("simulated scene: meshes are rasterised orthographically only");
  if (config.gonioreflectometer && config.scene.shape != Scene::Shape::kPhantom) CheckGonioScene(config.scene);
  if (config.scene.shape == Scene::Shape::kPhantom &&
      (!config.gonioreflectometer || config.camera.projection != CameraModel::Projection::kOrthographic))
    throw std::invalid_argument("simulated scene: a phantom sits on a gonioreflectometer's turntable, seen orthographically");
  if (config.reference_target && !(config.gonioreflectometer && config.reference_target->albedo > 0.0 &&
                                   config.reference_target->albedo <= 1.0))
    throw std::invalid_argument("simulated reference target: a gonioreflectometer's, of albedo within (0, 1]");
  if (!config.ambient.IsValid(&why)) throw std::invalid_argument("simulated ambient light: " + why);
  if (!config.color.IsValid(&why)) throw std::invalid_argument("simulated colour camera: " + why);
  if (config.color.IsOn() && (config.scene.shape == Scene::Shape::kVolume || config.scene.shape == Scene::Shape::kPhantom))
    throw std::invalid_argument("simulated colour camera: transmission scenes are rendered in monochrome only");
  if (config.color.IsOn() && !config.gonioreflectometer &&
      (config.scene.albedo.high_channels || config.scene.material.rho_s_channels))
    throw std::invalid_argument("simulated colour camera: a light dome's colours are paints (albedo paints: [low, "
                                "high]); parameters per channel are a gonioreflectometer sample's");
  if (config.color.IsOn() && config.gonioreflectometer && !config.scene.albedo.paints.empty())
    throw std::invalid_argument("simulated colour camera: a gonioreflectometer sample's colour is its albedo per "
                                "channel (albedo high: [r, g, b]), not paints");
  return config;
}

}  // namespace

World::World(WorldConfig config)
    : config_(Validated(config)),
      surface_(SampleSurface(config_.scene, config_.camera)),
      brdf_(config_.scene.material.MakeBrdf()),
      // The sweep needs the heightfield on the pixel grid, i.e. an orthographic view.
      cast_shadows_(config_.scene.cast_shadows && config_.scene.IsHeightfield() && surface_.height_on_pixel_grid),
      levels_(config_.lights.size(), 0.0) {
  // The sky's shape is fixed, only its level follows the LEDs: one map serves every frame.
  if (config_.ambient.IsOn() && !config_.gonioreflectometer && config_.scene.shape != Scene::Shape::kVolume)
    sky_response_ = RenderSkyResponse(surface_, *brdf_, config_.ambient.samples, config_.seed);
  if (config_.color.IsOn()) {
    const ColorCamera& color = config_.color;
    const cv::Mat rgb = MixAlbedo(surface_.albedo, config_.scene.albedo.low, config_.scene.albedo.high, color.low_rgb,
                                  color.high_rgb);
    for (int c = 0; c < 3; ++c) {
      channel_brdf_[c] = config_.scene.material.MakeBrdf(c);
      SurfaceMaps& channel = channel_surface_[c];
      channel = surface_;
      channel.brdf_params = surface_.brdf_params.clone();
      for (int r = 0; r < rgb.rows; ++r) {
        const auto* albedo = rgb.ptr<cv::Vec3f>(r);
        auto* params = channel.brdf_params.ptr<cv::Vec4f>(r);
        for (int x = 0; x < rgb.cols; ++x) {
          if (std::isnan(albedo[x][c])) continue;
          params[x][0] = albedo[x][c];
          params[x][1] *= static_cast<float>(color.light_rgb[c]);  // the lobe reflects the light's colour
        }
      }
      channel.albedo = cv::Mat();  // the copy shares surface_'s buffer; extract into a new one
      cv::extractChannel(rgb, channel.albedo, c);
      if (!sky_response_.empty())
        channel_sky_response_[c] = RenderSkyResponse(channel, *channel_brdf_[c], config_.ambient.samples, config_.seed);
    }
  }
}

cv::Mat World::TruthColorAlbedo() const {
  if (!config_.color.IsOn()) return {};
  return MixAlbedo(surface_.albedo, config_.scene.albedo.low, config_.scene.albedo.high, config_.color.truth_low_srgb,
                   config_.color.truth_high_srgb);
}

bool ColorCamera::IsValid(std::string* why) const {
  if (mosaic.empty()) return true;
  if (mosaic != "RGGB" && mosaic != "BGGR" && mosaic != "GRBG" && mosaic != "GBRG") {
    *why = "unknown Bayer pattern '" + mosaic + "' (known: RGGB, BGGR, GRBG, GBRG)";
    return false;
  }
  for (const Eigen::Vector3d* v : {&low_rgb, &high_rgb, &light_rgb})
    if (!(v->minCoeff() >= 0.0 && v->maxCoeff() <= 10.0)) {
      *why = "channel responses must lie in [0, 10]";
      return false;
    }
  return true;
}

cv::Mat MixAlbedo(const cv::Mat& albedo, double texture_low, double texture_high, const Eigen::Vector3d& low,
                  const Eigen::Vector3d& high) {
  cv::Mat rgb(albedo.size(), CV_32FC3);
  const double span = texture_high - texture_low;
  for (int r = 0; r < albedo.rows; ++r) {
    const float* a = albedo.ptr<float>(r);
    auto* out = rgb.ptr<cv::Vec3f>(r);
    for (int c = 0; c < albedo.cols; ++c) {
      if (std::isnan(a[c])) {
        out[c] = cv::Vec3f::all(std::numeric_limits<float>::quiet_NaN());
        continue;
      }
      const double t = span > 0.0 ? std::clamp((a[c] - texture_low) / span, 0.0, 1.0) : 1.0;
      const Eigen::Vector3d mixed = (1.0 - t) * low + t * high;
      out[c] = cv::Vec3f(static_cast<float>(mixed[0]), static_cast<float>(mixed[1]), static_cast<float>(mixed[2]));
    }
  }
  return rgb;
}

cv::Mat MosaicOf(const std::array<cv::Mat, 3>& rgb, const std::string& pattern) {
  // Channel of each site of the 2 x 2 block, row-major.
  const auto channel_of = [](char filter) { return filter == 'R' ? 0 : filter == 'G' ? 1 : 2; };
  cv::Mat out(rgb[0].size(), CV_32F);
  for (int r = 0; r < out.rows; ++r) {
    float* o = out.ptr<float>(r);
    for (int c = 0; c < out.cols; ++c) o[c] = rgb[channel_of(pattern[(r % 2) * 2 + c % 2])].at<float>(r, c);
  }
  return out;
}

void World::SetLevels(std::vector<double> levels) {
  std::lock_guard lock(mutex_);
  levels_ = std::move(levels);
}

std::vector<double> World::levels() const {
  std::lock_guard lock(mutex_);
  return levels_;
}

void World::SetArm(const std::string& axis, double position_deg) {
  std::lock_guard lock(mutex_);
  if (axis == "light_arm") arms_.light_arm_deg = position_deg;
  else if (axis == "camera_arm") arms_.camera_arm_deg = position_deg;
  else if (axis == "sample_rotation") arms_.sample_rotation_deg = position_deg;
  else if (axis == "sample_changer") arms_.sample_changer_deg = position_deg;
  else throw std::invalid_argument("simulated gonioreflectometer has no axis '" + axis + "'");
}

ArmAngles World::arms() const {
  std::lock_guard lock(mutex_);
  return arms_;
}

void World::ConnectTriggerInput(std::function<void()> on_pulse) {
  std::lock_guard lock(trigger_mutex_);
  trigger_input_ = std::move(on_pulse);
}

void World::DisconnectTriggerInput() {
  std::lock_guard lock(trigger_mutex_);
  trigger_input_ = nullptr;
}

bool World::PulseTriggerInput() {
  std::lock_guard lock(trigger_mutex_);
  if (!trigger_input_) return false;
  trigger_input_();
  return true;
}

std::vector<double> World::EmittedLevels() const {
  std::vector<double> emitted = levels();
  for (const auto& [channel, fraction] : config_.light_faults.dim_channels)
    if (channel >= 0 && channel < static_cast<int>(emitted.size())) emitted[channel] *= fraction;
  return emitted;
}

cv::Mat World::RenderRadiance() const {
  const std::vector<double> emitted = EmittedLevels();
  if (config_.scene.shape == Scene::Shape::kPhantom)
    return RenderPhantomTransmission(config_.scene, config_.camera, config_.lights, emitted, arms());
  if (config_.gonioreflectometer) {
    if (!config_.color.IsOn()) return RenderGonioChannel(-1, emitted);
    std::array<cv::Mat, 3> channels;
    for (int c = 0; c < 3; ++c) channels[c] = RenderGonioChannel(c, emitted);
    return MosaicOf(channels, config_.color.mosaic);
  }
  // The backlight belongs to the scene, not to the dome: it is always on.
  if (config_.scene.shape == Scene::Shape::kVolume)
    return RenderTransmission(surface_.line_integrals, config_.scene.backlight_radiance);
  if (!config_.color.IsOn()) return RenderChannel(surface_, *brdf_, sky_response_, emitted);
  std::array<cv::Mat, 3> channels;
  for (int c = 0; c < 3; ++c) {
    channels[c] = RenderChannel(channel_surface_[c], *channel_brdf_[c], channel_sky_response_[c], emitted);
    // A table's channel is the reflectance as that channel sees it against a
    // grey standard; the channel's response to the light scales all of it,
    // as it scales a parametric lobe (and is inside a paint's albedo).
    if (config_.scene.material.model == Brdf::Model::kTabulated) channels[c] *= config_.color.light_rgb[c];
  }
  return MosaicOf(channels, config_.color.mosaic);
}

cv::Mat World::RenderGonioChannel(int channel, const std::vector<double>& emitted) const {
  const ArmAngles at = arms();
  // A colour camera's channel sees the lamp through its own filter: the
  // channel's response to the light scales the irradiance, and the sample
  // reflects with its parameters for that channel.
  std::vector<Light> lights = config_.lights;
  if (channel >= 0)
    for (Light& light : lights) light.irradiance *= config_.color.light_rgb[channel];
  if (config_.reference_target &&
      std::abs(at.sample_changer_deg - config_.reference_target->sample_changer_deg) <= 0.5) {
    Scene target = config_.scene;  // a spectrally flat (grey) Lambertian standard
    target.albedo = AlbedoTexture{};
    target.albedo.pattern = AlbedoTexture::Pattern::kUniform;
    target.albedo.high = config_.reference_target->albedo;
    target.material = Material{};
    return RenderGonioRadiance(target, *target.material.MakeBrdf(), config_.camera, lights, emitted, at);
  }
  if (channel < 0) return RenderGonioRadiance(config_.scene, *brdf_, config_.camera, lights, emitted, at);
  Scene sample = config_.scene;
  if (sample.albedo.high_channels) sample.albedo.low = sample.albedo.high = (*sample.albedo.high_channels)[channel];
  if (sample.material.rho_s_channels) sample.material.rho_s = (*sample.material.rho_s_channels)[channel];
  return RenderGonioRadiance(sample, *channel_brdf_[channel], config_.camera, lights, emitted, at);
}

cv::Mat World::RenderChannel(const SurfaceMaps& surface, const Brdf& brdf, const cv::Mat& sky_response,
                             const std::vector<double>& emitted) const {
  cv::Mat radiance = sim::RenderRadiance(surface, brdf, cast_shadows_, config_.lights, emitted);
  if (config_.scene.interreflection_samples > 0)
    radiance += RenderOneBounce(surface, brdf, radiance, config_.scene.interreflection_samples, config_.seed);
  if (!sky_response.empty()) {
    double sky_irradiance = config_.ambient.stray_irradiance;
    for (std::size_t k = 0; k < emitted.size() && k < config_.lights.size(); ++k)
      sky_irradiance += config_.ambient.dome_fraction * emitted[k] * config_.lights[k].irradiance;
    radiance += sky_response * sky_irradiance;
  }
  return radiance;
}

}  // namespace photorig::sim
