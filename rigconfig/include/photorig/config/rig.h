#pragma once
// The rig description (config/rigs/*.yaml): which devices, where the lights
// are, what the camera is, and for simulated rigs what the simulator renders.
// Loading checks everything, each driver's own settings included, so a rig
// that loads builds its devices without configuration errors.

#include "photorig/config/device_config.h"
#include "photorig/config/sim_color.h"
#include "photorig/config/yaml_node.h"
#include "photorig/solvers/core/names.h"
#include "photorig/sim/world.h"

#include <cstdint>
#include <map>
#include <optional>
#include <string>

namespace photorig::config {

// The ranges a rig or recipe may give, checked at load. Beyond them a value
// is a typo, and a huge one would overflow the integer microseconds and
// nanoseconds the drivers convert it to.
inline constexpr double kMinExposureUs = 1.0;
inline constexpr double kMaxExposureUs = 1e8;  // 100 s
inline constexpr double kMinGainDb = -40.0;
inline constexpr double kMaxGainDb = 60.0;
inline constexpr double kMaxLedIntensity = 1000.0;  // relative to the nominal LED (1)

// Where a gonioreflectometer's three axes stand for one frame (degrees, axis
// zero = the arm on the sample normal / the sample's reference orientation).
struct GonioPose {
  double light_arm_deg = 0.0;
  double camera_arm_deg = 0.0;
  double sample_rotation_deg = 0.0;
  // A fourth axis only some rigs have: a sample changer (0: the sample in the
  // beam; elsewhere a tomograph's open beam of a flat field, or a
  // gonioreflectometer's reference target). Unset: not moved.
  std::optional<double> sample_changer_deg;
};

struct SimConfig {
  std::uint64_t seed = 1;
  // The simulated dome as built: each LED tilted off its nominal direction by
  // a seeded random angle of this RMS, so light calibration has something to find.
  double led_direction_error_deg = 0.0;
  // ... and its irradiance off the stated intensity by a seeded random factor
  // of this RMS relative error, in percent (sim/light_errors.h).
  double led_intensity_error_pct = 0.0;
  // The radius of a near LED's emitting disc (its diffuser): the size of the
  // highlight a mirror ball shows of it (sim::Light::emitter_radius_mm).
  double led_emitter_radius_mm = 1.5;
  // Light from the dome's walls and the room on every frame (sim/renderer.h).
  sim::AmbientLight ambient;
  sim::SensorModel sensor;
  sim::Scene scene;  // default scene; a recipe's sample.sim_scene replaces it
  SimColorConfig color;
  sim::CameraFaults camera_faults;
  sim::LightFaults light_faults;
  std::map<std::string, sim::AxisFaults> axis_faults;  // by axis id
};

// Thresholds of the checks every captured frame passes before it is stored
// (rig `health:`, docs/daemon.md "Capture health checks"). The defaults hold
// for any rig whose frames are healthy; loading range-checks each key.
struct HealthConfig {
  bool enabled = true;
  // A lit frame needs a pixel this many noise sigmas above the dark: the
  // brightest pixel, because a mirror sphere's highlight may be one pixel,
  // and 10 sigma because noise alone stays below 6 sigma on 10^7 pixels.
  // A dark frame whose mean rises this far above the earlier darks saw light.
  double lit_sigma = 10.0;
  // Clipped (full-scale) pixels a frame may have: the solvers drop clipped
  // samples per pixel, but a frame clipped this widely is overexposed.
  double max_clipped_fraction = 0.02;
  // The code at or above which a pixel counts as clipped; 0: the full-scale
  // code 2^bit_depth - 1. A sensor whose full well fills before its ADC does
  // clips lower (EMVA 1288 saturation capacity / conversion gain + black);
  // a simulated rig's default is its sensor's, less 3 read-noise sigmas,
  // since the simulated read noise is added after the full-well clip.
  double saturation_dn = 0.0;
  // An LED whose mean response is below this fraction of the median of its
  // nearest neighbours (by direction) is dead or dim; 0 turns the check off.
  double min_neighbour_ratio = 0.25;
  int neighbours = 4;
  // A frame of a pattern taken before (a repeat, another bracket exposure)
  // must be within this factor of that frame's response scaled by exposure.
  double max_brightness_ratio = 2.0;
};

// Where the daemon runs a run's photometric-stereo stage (rig `solve:`,
// docs/scaling.md): in its own process, or as a one-task Slurm batch on the
// cluster this host submits to, the run staying `solving` until the job ends.
enum class Executor { kLocal, kSlurm };
inline constexpr solvers::core::NameTable<Executor, 2> kExecutorNames = {
    {{Executor::kLocal, "local"}, {Executor::kSlurm, "slurm"}}};

struct SolveExecutorConfig {
  Executor executor = Executor::kLocal;
  // sbatch's requests; empty: the cluster's defaults.
  std::string partition;
  std::string time;  // e.g. "00:30:00"
  std::string mem;   // e.g. "4G"
  // The photorig executable on the nodes; empty: the one beside photorigd.
  std::string photorig;
  // How often the daemon asks Slurm about the job.
  int poll_ms = 2000;
};

// A reflectance standard of known diffuse albedo (a Spectralon-like
// target) the gonioreflectometer can bring under its arms: `photorig solve
// brdf` scales f_r from its frames, so values come out in 1/sr whatever the
// camera's stated response. `pose` is where its frames are taken; on a rig
// whose target sits in a sample changer slot (pose.sample_changer_deg), every
// recipe pose that names no changer position holds the sample (changer at 0).
struct ReferenceTargetConfig {
  double albedo = 0.99;  // Lambertian: f_r = albedo / pi
  GonioPose pose;
};

// A gonioreflectometer needs `motion:`.
enum class RigKind { kLightDome, kGonioreflectometer };
inline constexpr solvers::core::NameTable<RigKind, 2> kRigKindNames = {
    {{RigKind::kLightDome, "light_dome"}, {RigKind::kGonioreflectometer, "gonioreflectometer"}}};

struct RigConfig {
  std::string path;
  std::string name;
  RigKind kind = RigKind::kLightDome;
  LightsConfig lights;
  CameraConfig camera;
  std::optional<SimConfig> sim;  // present when any device is simulated
  std::optional<MotionConfig> motion;  // gonioreflectometers only
  std::optional<ReferenceTargetConfig> reference_target;  // gonioreflectometers only
  HealthConfig health;
  SolveExecutorConfig solve;

  bool IsSimulated() const { return sim.has_value(); }
};

// Throws ConfigError naming file:line:column and key.
RigConfig LoadRigConfig(const std::string& path);

// The frame width in mm of the rig's camera (width x pixel pitch).
double FrameWidthMm(const RigConfig& rig);

// The executor keys of a rig's or a recipe's `solve:` (executor, partition,
// time, mem, photorig, poll_ms), each absent key keeping its value in
// `solve`; the caller checks which keys the node may hold. Throws ConfigError.
SolveExecutorConfig ParseSolveExecutor(const YamlNode& node, SolveExecutorConfig solve);

}  // namespace photorig::config
