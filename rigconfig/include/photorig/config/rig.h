#pragma once
// The rig description (config/rigs/*.yaml): which devices, where the lights
// are, what the camera is, and for simulated rigs what the simulator renders.
// Loading checks everything, each driver's own settings included, so a rig
// that loads builds its devices without configuration errors.

#include "photorig/config/color_model.h"
#include "photorig/config/driver_options.h"
#include "photorig/config/yaml_node.h"
#include "photorig/solvers/core/names.h"
#include "photorig/drivers/camera.h"
#include "photorig/drivers/motion/goniometer.h"
#include "photorig/sim/world.h"

#include <Eigen/Core>

#include <array>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace photorig::config {

struct LedConfig {
  int id = 0;
  Eigen::Vector3d direction{0, 0, 1};  // unit, camera frame, towards the LED
  double intensity = 1.0;              // relative irradiance at the sample for drive level 1
  Eigen::Vector3d rgb_intensity{1, 1, 1};  // relative [r, g, b] output, as calibrated
  // Where the LED is, when the rig gives it (mm, camera frame). Solvers use
  // `direction` (towards it from the object origin); a simulated rig renders
  // it as a near LED aimed at the origin, with inverse-square falloff across
  // the object, the error a distant-light model makes on a small dome.
  std::optional<Eigen::Vector3d> position_mm;
};

struct LightsConfig {
  std::string driver;  // sim | modbus-tcp | modbus-rtu | gpio | usb-relay
  std::string id;
  std::vector<LedConfig> leds;
  // The driver's `options:`, parsed: the member for `driver` is set.
  std::optional<ModbusLightsOptions> modbus;  // modbus-tcp, modbus-rtu
#if PHOTORIG_HAVE_DRIVERS_GPIO
  std::optional<GpioLightsOptions> gpio;
#endif
  std::optional<UsbRelayOptions> usb_relay;
  // options.safety: {max_on_ms, max_duty, duty_window_ms, watchdog_ms,
  // channels: {<index>: {max_on_ms, max_duty}}}; simulated lights take it too (their only option).
  drivers::LightSafetyOptions safety;
};

// Where a 24-patch colour chart sits in the camera's image when the rig
// photographs one (camera.color_chart): the outer corners of the 6 x 4 grid of
// patch cells in pixels, top-left (dark-skin patch) first, then clockwise.
// Written as `box_px: [x, y, w, h]` or `corners_px: [[x, y], ...]` (four points).
struct ColorChartPlacement {
  std::array<Eigen::Vector2d, 4> corners_px;
};

// How frames are triggered. `hardware`: the camera is armed on its input
// `line` and the sequencer fires the rig's trigger output (a GPIO line, or the
// simulated rig's wire) once per frame instead of a software trigger.
struct TriggerConfig {
  drivers::TriggerMode mode = drivers::TriggerMode::kSoftware;
  std::string line = "Line1";  // the camera's trigger input (GenICam TriggerSource)
  int pulse_us = 100;
  std::string output_driver;   // hardware: "sim" | "gpio"
#if PHOTORIG_HAVE_DRIVERS_GPIO
  std::optional<drivers::GpioLine> gpio_line;  // output: {driver: gpio, chip, offset, active_low}
#endif
};

// The ranges a rig or recipe may give, checked at load. Beyond them a value
// is a typo, and a huge one would overflow the integer microseconds and
// nanoseconds the drivers convert it to.
inline constexpr double kMinExposureUs = 1.0;
inline constexpr double kMaxExposureUs = 1e8;  // 100 s
inline constexpr double kMinGainDb = -40.0;
inline constexpr double kMaxGainDb = 60.0;
inline constexpr double kMaxLedIntensity = 1000.0;  // relative to the nominal LED (1)

struct CameraConfig {
  std::string driver;  // sim | aravis | v4l2
  std::string id;
  // The driver's `options:`, parsed: the member for `driver` is set.
#if PHOTORIG_HAVE_DRIVERS_ARAVIS
  std::optional<AravisOptions> aravis;
#endif
#if PHOTORIG_HAVE_DRIVERS_V4L2
  std::optional<drivers::V4l2CameraOptions> v4l2;  // options: {device, buffer_count}
#endif
  std::string projection = "orthographic";
  int width = 0;
  int height = 0;
  double pixel_pitch_mm = 0.1;
  int bit_depth = 12;
  double exposure_us = 10000.0;
  double gain_db = 0.0;
  TriggerConfig trigger;
  // Radiometric calibration: DN above black per unit radiance per microsecond
  // at 0 dB. Makes albedo absolute; 1.0 (uncalibrated) gives relative albedo.
  double dn_per_radiance_per_us = 1.0;
  // Conversion gain at 0 dB (electrons per DN, from the camera's EMVA 1288
  // sheet): sets the photon-noise model. 0 = unknown, then estimated from data.
  double e_per_dn = 0.0;
  // Fixed chart position for colour calibration, used when detection fails.
  std::optional<ColorChartPlacement> color_chart;
  // GenICam pixel format asked of the camera: Mono8/10/12/16,
  // Bayer{RG,GR,GB,BG}{8,10,12,16}; "" = Mono<bit_depth>. A Bayer format makes
  // the camera a colour one: frames are stored as the raw mosaic and `mosaic`
  // names its top-left 2 x 2 block (drivers::MosaicOfPixelFormat).
  std::string pixel_format;
  std::string mosaic = "mono";
  // camera.color_model: the colour model of this camera (photorig calibrate
  // color), loaded and checked when the rig loads; applied when colour runs
  // are solved.
  std::optional<LoadedColorModel> color_model;
};

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

// A gonioreflectometer's axes (kind: gonioreflectometer). Axis ids
// light_arm, camera_arm and sample_rotation are what recipe poses move.
struct AxisConfig {
  std::string id;
  drivers::AxisLimits limits;
  int base_address = 0;  // modbus-tcp: the drive's first register
};

struct MotionConfig {
  std::string driver;  // "sim" or "modbus-tcp"
  drivers::MotionProfile profile;  // every move of every axis
  drivers::SettleOptions settle;
  std::vector<AxisConfig> axes;
  std::vector<drivers::SeparationConstraint> constraints;
  drivers::ModbusLinkOptions link;  // modbus-tcp: `link:`, the bus every drive is on
  sim::SimAxisOptions sim_axis;     // sim: `time_scale:` (faults come from sim.faults.motion)

  const AxisConfig* axis(const std::string& id) const;
  // Empty when every axis stays within its soft limits and every separation
  // constraint holds at `positions_deg`; otherwise what is violated.
  std::string CheckPose(const std::map<std::string, double>& positions_deg) const;
};

// The simulated colour camera (sim.color), used when camera.pixel_format is a
// Bayer format: whose measured sensitivities its channels have and the
// spectrum of the dome's LEDs (a CIE illuminant).
struct SimColorConfig {
  std::string camera = "nikon-5100";  // solvers::color::CameraNames()
  solvers::color::Illuminant illuminant = solvers::color::Illuminant::kD65;
};

struct SimConfig {
  std::uint64_t seed = 1;
  // The simulated dome as built: each LED tilted off its nominal direction by
  // a seeded random angle of this RMS, so light calibration has something to find.
  double led_direction_error_deg = 0.0;
  // ... and its irradiance off the stated intensity by a seeded random factor
  // of this RMS relative error, in percent (sim/light_errors.h).
  double led_intensity_error_pct = 0.0;
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

// The executor keys of a rig's or a recipe's `solve:` (executor, partition,
// time, mem, photorig, poll_ms), each absent key keeping its value in
// `solve`; the caller checks which keys the node may hold. Throws ConfigError.
SolveExecutorConfig ParseSolveExecutor(const YamlNode& node, SolveExecutorConfig solve);

}  // namespace photorig::config
