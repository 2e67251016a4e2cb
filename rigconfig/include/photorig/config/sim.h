#pragma once
// What the simulator is told by a rig's `sim:` section and a recipe's
// `sample.sim_scene:`: the scene, and the World both describe. The simulator
// tools read rigs through these, not through the daemon.

#include "photorig/config/rig.h"
#include "photorig/config/yaml_node.h"
#include "photorig/sim/scene.h"
#include "photorig/sim/world.h"

namespace photorig::config {

// Parses a `scene:` map (a rig's sim.scene, a recipe's sample.sim_scene).
// Sizes the map leaves out are fractions of the frame width, so the scene is
// parsed for the camera that will see it. Files it names (depth maps, meshes,
// BRDF tables) are read now. Throws ConfigError.
sim::Scene ParseScene(const YamlNode& node, double frame_width_mm);

// The frame width in mm of the rig's camera (width x pixel pitch).
double FrameWidthMm(const RigConfig& rig);

// The simulated World of a rig with a `sim:` section, showing `scene`: LEDs
// where the rig puts them (tilted by sim.led_direction_error_deg), the
// camera's frame, the sensor and the injected faults.
sim::WorldConfig MakeWorldConfig(const RigConfig& rig, const sim::Scene& scene);

// Index (0..23) of a ColorChecker patch by its name, case-insensitive; -1 if none.
int ColorCheckerPatch(const std::string& name);
// Rec. 709 / sRGB luminance weights: Y = w . (R, G, B) linear.
Eigen::Vector3d LuminanceOfLinearSrgb();
// The colour camera's per-channel responses to the texture's two paints and
// to the light (sim::ColorCamera), integrated over wavelength:
//   rho_c = sum R(l) E(l) S_c(l) / sum E(l) S_g(l)
// (reflectance R, the LEDs' spectrum E = the named illuminant, the camera's
// measured sensitivity S_c), and the paints' true linear sRGB albedo (XYZ
// under E, adapted to D65 by Bradford). Without paints both are white.
sim::ColorCamera ColorSceneResponses(const SimColorConfig& color, const sim::AlbedoTexture& albedo);

}  // namespace photorig::config
