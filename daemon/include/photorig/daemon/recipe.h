#pragma once
// Capture recipes (config/recipes/*.yaml) and their compilation into the flat
// list of steps the sequencer executes.

#include "photorig/daemon/ps_request.h"
#include "photorig/daemon/rig_config.h"
#include "photorig/daemon/yaml_node.h"
#include "photorig/drivers/light_controller.h"

#include <optional>
#include <string>
#include <vector>

namespace photorig::daemon {


struct Recipe {
  std::string path;
  std::string name;
  std::string description;
  std::string rig_path;  // resolved relative to the recipe file
  std::string sample_name;
  // Replaces the simulated rig's scene. Kept as YAML because sizes default to
  // the camera's field of view, which only the rig knows.
  std::optional<YamlNode> sim_scene;
  std::optional<double> exposure_us;    // overrides the rig camera's exposure
  std::optional<double> gain_db;

  struct Group {
    enum class Kind { kDark, kEachLed };
    Kind kind = Kind::kDark;
    int count = 1;             // kDark: number of frames
    std::vector<int> led_ids;  // kEachLed: empty = all LEDs
    double level = 1.0;        // kEachLed: drive level
    std::optional<YamlNode> source;  // for errors found once the rig is known
  };
  std::vector<Group> groups;
  std::optional<PhotometricStereoRequest> photometric_stereo;
};

struct CaptureStep {
  enum class Kind { kDark, kLight };
  int index = 0;
  Kind kind = Kind::kDark;
  std::string label;         // file stem: "0000_dark", "0001_led07"
  int led = -1;              // index into RigConfig::lights.leds; -1 for darks
  drivers::LightPattern pattern;
  double exposure_us = 0.0;
  double gain_db = 0.0;
};

// Throws ConfigError naming file:line:column and key.
Recipe LoadRecipe(const std::string& path);
// The same from text received over the API; errors name `name` as the file.
Recipe LoadRecipeText(const std::string& text, const std::string& name);
std::string ResolveRigPath(const Recipe& recipe, const std::string& override_path);
// Throws ConfigError (naming the recipe) when the recipe asks for LEDs the rig lacks.
std::vector<CaptureStep> CompileSteps(const Recipe& recipe, const RigConfig& rig);

}  // namespace photorig::daemon
