#pragma once
// The rig description (config/rigs/*.yaml): which devices, where the lights
// are, what the camera is, and for simulated rigs what the simulator renders.

#include "photorig/daemon/yaml_node.h"
#include "photorig/sim/world.h"

#include <Eigen/Core>

#include <optional>
#include <string>
#include <vector>

namespace photorig::daemon {

struct LedConfig {
  int id = 0;
  Eigen::Vector3d direction{0, 0, 1};  // unit, camera frame, towards the LED
  double intensity = 1.0;              // relative irradiance at the sample for drive level 1
  int channel = 0;                     // controller output driving this LED (default: its index)
  Eigen::Vector3d rgb_intensity{1, 1, 1};  // relative [r, g, b] output, as calibrated
};

struct LightsConfig {
  std::string driver;  // a name from daemon/device_factory.h, e.g. "sim"
  std::string id;
  std::vector<LedConfig> leds;
  std::optional<YamlNode> options;  // driver-specific settings, parsed by the driver's factory
};

struct CameraConfig {
  std::string driver;  // a name from daemon/device_factory.h, e.g. "sim"
  std::string id;
  std::optional<YamlNode> options;  // driver-specific settings, parsed by the driver's factory
  std::string projection = "orthographic";
  int width = 0;
  int height = 0;
  double pixel_pitch_mm = 0.1;
  int bit_depth = 12;
  double exposure_us = 10000.0;
  double gain_db = 0.0;
  // Radiometric calibration: DN above black per unit radiance per microsecond
  // at 0 dB. Makes albedo absolute; 1.0 (uncalibrated) gives relative albedo.
  double dn_per_radiance_per_us = 1.0;
  // Conversion gain at 0 dB (electrons per DN, from the camera's EMVA 1288
  // sheet): sets the photon-noise model. 0 = unknown, then estimated from data.
  double e_per_dn = 0.0;
};

struct SimConfig {
  std::uint64_t seed = 1;
  sim::SensorModel sensor;
  sim::Scene scene;  // default scene; a recipe's sample.sim_scene replaces it
  sim::CameraFaults camera_faults;
  sim::LightFaults light_faults;
};

struct RigConfig {
  std::string path;
  std::string name;
  LightsConfig lights;
  CameraConfig camera;
  std::optional<SimConfig> sim;  // present when any device is simulated

  bool IsSimulated() const { return sim.has_value(); }
};

// Throws ConfigError naming file:line:column and key.
RigConfig LoadRigConfig(const std::string& path);
// Parses a `scene:` map (shared by rigs and recipes).
sim::Scene ParseScene(const YamlNode& node, double frame_width_mm);

}  // namespace photorig::daemon
