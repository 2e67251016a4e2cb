#pragma once
// The simulated rig's physical state: what object sits under the camera, where
// the LEDs are, how bright each one is right now. The simulated devices share
// one World, so a camera frame always shows the lights the controller set.

#include "photorig/sim/camera_model.h"
#include "photorig/sim/faults.h"
#include "photorig/sim/gonio.h"
#include "photorig/sim/renderer.h"
#include "photorig/sim/scene.h"
#include "photorig/sim/sensor.h"

#include <array>
#include <cstdint>
#include <string>
#include <functional>
#include <memory>
#include <mutex>
#include <vector>

namespace photorig::sim {

// A colour camera: a Bayer colour filter array over the sensor. Each pixel
// records one channel, R, G or B after the pattern; a channel's radiance is
// the scene rendered with that channel's albedo, so the spectral integral
// (reflectance x light spectrum x channel sensitivity) is done once per
// material by whoever builds the world (rigconfig: ColorSceneResponses).
// A gonioreflectometer's sample is given per channel instead (its albedo's
// high_channels, its material's rho_s_channels, a table's channels: the
// reflectance as the channel sees it against a grey standard), lit by the
// lamp at the channel's light_rgb; the reference target stays grey.
struct ColorCamera {
  std::string mosaic;  // "" = monochrome; else the top-left 2 x 2 block: RGGB, BGGR, GRBG, GBRG
  // Camera-channel albedo (R, G, B) of the albedo texture's `low` and `high`
  // materials, in units where a perfect white gives 1 in green. A texture
  // value between low and high mixes the two paints in proportion, which
  // mixes their responses linearly.
  Eigen::Vector3d low_rgb = Eigen::Vector3d::Ones();
  Eigen::Vector3d high_rgb = Eigen::Vector3d::Ones();
  // Response to the light itself (a perfect white), scaling specular lobes,
  // which reflect the light's colour.
  Eigen::Vector3d light_rgb = Eigen::Vector3d::Ones();
  // The paints' true albedo in linear sRGB (D65), for the ground truth.
  Eigen::Vector3d truth_low_srgb = Eigen::Vector3d::Ones();
  Eigen::Vector3d truth_high_srgb = Eigen::Vector3d::Ones();

  bool IsOn() const { return !mosaic.empty(); }
  bool IsValid(std::string* why) const;
};

// Per-pixel camera-channel albedo (CV_32FC3, R, G, B; NaN off the object) of
// a scene whose albedo texture is `albedo` (SurfaceMaps::albedo), mixed between
// `low` and `high` as ColorCamera describes.
cv::Mat MixAlbedo(const cv::Mat& albedo, double texture_low, double texture_high, const Eigen::Vector3d& low,
                  const Eigen::Vector3d& high);

// Keeps, at each pixel, the channel the pattern's filter passes (R, G, B planes in).
cv::Mat MosaicOf(const std::array<cv::Mat, 3>& rgb, const std::string& pattern);

struct WorldConfig {
  Scene scene;
  std::vector<Light> lights;  // one per controller channel
  CameraModel camera;
  SensorModel sensor;
  std::uint64_t seed = 1;
  CameraFaults camera_faults;
  LightFaults light_faults;
  // Light from the dome's walls and the room, added to every frame of a
  // light dome (not to gonioreflectometer or transmission frames).
  AmbientLight ambient;
  // The camera and lamps ride gonioreflectometer arms: frames come from
  // RenderGonioRadiance at the arms' current angles (sim/gonio.h).
  bool gonioreflectometer = false;
  std::optional<ReferenceTarget> reference_target;  // gonioreflectometers only
  ColorCamera color;  // off: a monochrome camera
};

class World {
 public:
  // Throws std::invalid_argument for an invalid scene or camera, and
  // std::runtime_error when a depth map or mesh cannot be read.
  explicit World(WorldConfig config);

  const WorldConfig& config() const { return config_; }
  const SurfaceMaps& surface() const { return surface_; }  // also the ground truth
  // A colour camera's ground truth: the paints' albedo in linear sRGB
  // (CV_32FC3, R, G, B; NaN off the object). Empty for a monochrome camera.
  cv::Mat TruthColorAlbedo() const;

  void SetLevels(std::vector<double> levels);
  std::vector<double> levels() const;
  // Gonioreflectometers: "light_arm", "camera_arm", "sample_rotation" or "sample_changer"
  // (std::invalid_argument otherwise), as the simulated axes report them.
  void SetArm(const std::string& axis, double position_deg);
  ArmAngles arms() const;
  // Radiance under the light the LEDs emit at their current levels (dimmed
  // by LightFaults::dim_channels) and the current arm angles.
  // A colour camera: the radiance each pixel's filter passes (one channel).
  cv::Mat RenderRadiance() const;

  // The wire from a trigger output to the camera's input line: an armed
  // camera connects a handler; a pulse with nothing connected is lost, as on
  // a real rig whose camera is not armed.
  void ConnectTriggerInput(std::function<void()> on_pulse);
  void DisconnectTriggerInput();
  // Returns false when no camera was listening.
  bool PulseTriggerInput();

 private:
  std::vector<double> EmittedLevels() const;
  // A gonioreflectometer's frame as one colour channel (0 R, 1 G, 2 B) sees
  // it, or a grey camera (-1): the sample, or the reference target while the
  // sample changer holds it.
  cv::Mat RenderGonioChannel(int channel, const std::vector<double>& emitted) const;
  cv::Mat RenderChannel(const SurfaceMaps& surface, const Brdf& brdf, const cv::Mat& sky_response,
                        const std::vector<double>& emitted) const;

  WorldConfig config_;
  SurfaceMaps surface_;
  std::unique_ptr<Brdf> brdf_;
  bool cast_shadows_ = false;
  cv::Mat sky_response_;  // RenderSkyResponse, when config_.ambient is on
  // A colour camera: the surface and sky response as each channel sees them.
  std::array<SurfaceMaps, 3> channel_surface_;
  std::array<std::unique_ptr<Brdf>, 3> channel_brdf_;  // a measured table's own channel; the others: brdf_'s model
  std::array<cv::Mat, 3> channel_sky_response_;
  mutable std::mutex mutex_;
  std::vector<double> levels_;
  ArmAngles arms_;
  std::mutex trigger_mutex_;  // held while a pulse is handled: the handler renders
  std::function<void()> trigger_input_;
};

}  // namespace photorig::sim
