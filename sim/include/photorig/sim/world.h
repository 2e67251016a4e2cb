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

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <vector>

namespace photorig::sim {

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
};

class World {
 public:
  // Throws std::invalid_argument for an invalid scene or camera, and
  // std::runtime_error when a depth map or mesh cannot be read.
  explicit World(WorldConfig config);

  const WorldConfig& config() const { return config_; }
  const SurfaceMaps& surface() const { return surface_; }  // also the ground truth

  void SetLevels(std::vector<double> levels);
  std::vector<double> levels() const;
  // Gonioreflectometers: "light_arm", "camera_arm", "sample_rotation" or "sample_changer"
  // (std::invalid_argument otherwise), as the simulated axes report them.
  void SetArm(const std::string& axis, double position_deg);
  ArmAngles arms() const;
  // Radiance under the light the LEDs emit at their current levels (dimmed
  // by LightFaults::dim_channels) and the current arm angles.
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

  WorldConfig config_;
  SurfaceMaps surface_;
  std::unique_ptr<Brdf> brdf_;
  bool cast_shadows_ = false;
  cv::Mat sky_response_;  // RenderSkyResponse, when config_.ambient is on
  mutable std::mutex mutex_;
  std::vector<double> levels_;
  ArmAngles arms_;
  std::mutex trigger_mutex_;  // held while a pulse is handled: the handler renders
  std::function<void()> trigger_input_;
};

}  // namespace photorig::sim
