#pragma once
// The `scene:` map the simulator renders: a rig's sim.scene and a recipe's
// sample.sim_scene.

#include "photorig/config/yaml_node.h"
#include "photorig/sim/scene.h"

namespace photorig::config {

// Parses a `scene:` map (a rig's sim.scene, a recipe's sample.sim_scene).
// Sizes the map leaves out are fractions of the frame width, so the scene is
// parsed for the camera that will see it. Files it names (depth maps, meshes,
// BRDF tables) are read now. Throws ConfigError.
sim::Scene ParseScene(const YamlNode& node, double frame_width_mm);

}  // namespace photorig::config
