#pragma once
// Internal to the configuration library: the parsers behind LoadRigConfig for
// the driver-specific parts of a rig. Each throws ConfigError naming
// file:line:column and the dotted key.

#include "photorig/config/device_config.h"
#include "photorig/config/yaml_node.h"

namespace photorig::config {

// Fails unless `driver` (a `driver:` value) names a driver of that kind that
// this build has; `kind` is "light", "camera", "trigger output" or "motion".
void CheckDriver(const YamlNode& driver, const char* kind);

// `lights` has its driver and LEDs; fills in the driver's settings from the
// `options:` of `lights_node`. `simulated`: the rig has a sim: section.
void ParseLightsOptions(const YamlNode& lights_node, bool simulated, LightsConfig* lights);
void ParseCameraOptions(const YamlNode& camera_node, bool simulated, CameraConfig* camera);
// camera.trigger.output, whose driver is set in `trigger`.
void ParseTriggerOutput(const YamlNode& output, TriggerConfig* trigger);
// The driver-specific keys of `motion:` (link, time_scale) and of its axes (base_address).
void ParseMotionDriver(const YamlNode& motion_node, MotionConfig* motion);

}  // namespace photorig::config
