#pragma once
// The daemon reads rigs through the configuration library (rigconfig/,
// photorig/config/); these are the names it uses unqualified.

#include "photorig/config/rig.h"
#include "photorig/config/sim.h"
#include "photorig/config/yaml_node.h"

namespace photorig::daemon {

using config::AxisConfig;
using config::CameraConfig;
using config::ColorChartPlacement;
using config::ConfigError;
using config::LedConfig;
using config::LightsConfig;
using config::LoadRigConfig;
using config::MotionConfig;
using config::RigConfig;
using config::SimConfig;
using config::TriggerConfig;
using config::YamlNode;

}  // namespace photorig::daemon
