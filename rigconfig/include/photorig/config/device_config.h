#pragma once
// The device sections of a rig (lights:, camera:, motion:) as loaded, each
// driver's own settings parsed: what LoadRigConfig and the driver parsers
// (driver_options_parse.h) fill in.

#include "photorig/config/color_model.h"
#include "photorig/config/driver_options.h"
#include "photorig/drivers/camera.h"
#include "photorig/solvers/camera/camera.h"
#include "photorig/drivers/motion/goniometer.h"

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
  // Where the LED is, when the rig gives it (mm, camera frame): photometric
  // stereo then takes each pixel's own light vector and falloff from it
  // (solvers/ps/near_lights.h), and a simulated rig renders it as a near LED.
  // `direction` is towards it from the object origin.
  std::optional<Eigen::Vector3d> position_mm;
  // With position_mm: the unit direction the LED emits along (default: aimed
  // at the origin, as a dome's LEDs are mounted) and the exponent mu of its
  // radiance profile cos^mu of the angle to that axis (1: a Lambertian emitter).
  std::optional<Eigen::Vector3d> axis;
  double cos_exponent = 1.0;

  // The emission axis: `axis`, else towards the origin from position_mm.
  Eigen::Vector3d EmissionAxis() const { return axis ? *axis : Eigen::Vector3d(-position_mm->normalized()); }
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
  // Orthographic (pixel_pitch_mm) or pinhole (`pinhole:` OpenCV intrinsics,
  // distortion and distance above the sample plane; pixel_pitch_mm is then
  // the pixel's size on the sample plane at the image centre).
  solvers::camera::Projection projection = solvers::camera::Projection::kOrthographic;
  solvers::camera::PinholeLens pinhole;
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

  // The geometry the solvers take (solvers/camera/camera.h).
  solvers::camera::Camera Geometry() const {
    return {projection, width, height, pixel_pitch_mm, pinhole};
  }
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

}  // namespace photorig::config
