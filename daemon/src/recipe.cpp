#include "photorig/daemon/recipe.h"

#include "photorig/daemon/yaml_node.h"

#include <cstdio>
#include <filesystem>

namespace photorig::daemon {
namespace fs = std::filesystem;

namespace {
Recipe ParseRecipe(const YamlNode& root, const std::string& path);
}  // namespace

Recipe LoadRecipe(const std::string& path) { return ParseRecipe(YamlNode::LoadFile(path), path); }
Recipe LoadRecipeText(const std::string& text, const std::string& name) {
  return ParseRecipe(YamlNode::LoadString(text, name), name);
}

namespace {
Recipe ParseRecipe(const YamlNode& root, const std::string& path) {
  root.ExpectKeys({"recipe", "sample", "capture", "solve"});
  Recipe recipe;
  recipe.path = path;

  const YamlNode header = root["recipe"];
  header.ExpectKeys({"name", "description", "rig"});
  recipe.name = header["name"].AsString();
  recipe.description = header.String("description", "");
  if (auto rig = header.Find("rig")) {
    const fs::path rig_path = rig->AsString();
    recipe.rig_path = (rig_path.is_absolute() ? rig_path : fs::path(path).parent_path() / rig_path).lexically_normal();
  }

  if (auto sample = root.Find("sample")) {
    sample->ExpectKeys({"name", "sim_scene"});
    recipe.sample_name = sample->String("name", "");
    if (auto scene = sample->Find("sim_scene")) {
      ParseScene(*scene, 1.0);  // report errors now, before any device is touched
      recipe.sim_scene = scene;
    }
  }

  const YamlNode capture = root["capture"];
  capture.ExpectKeys({"exposure_us", "gain_db", "steps"});
  if (auto exposure = capture.Find("exposure_us")) {
    recipe.exposure_us = exposure->AsDouble();
    if (!(*recipe.exposure_us > 0)) exposure->Fail("must be > 0");
  }
  if (auto gain = capture.Find("gain_db")) recipe.gain_db = gain->AsDouble();
  for (const YamlNode& step : capture["steps"].Items()) {
    const auto keys = step.Keys();
    if (keys.size() != 1) step.Fail("each step is a map with exactly one key: dark or each_led");
    Recipe::Group group;
    group.source = step;
    const YamlNode body = step[keys[0]];
    if (keys[0] == "dark") {
      group.kind = Recipe::Group::Kind::kDark;
      body.ExpectKeys({"count"});
      group.count = body.Int("count", 1);
      if (group.count < 1 || group.count > 1000) body["count"].Fail("must be within [1, 1000]");
    } else if (keys[0] == "each_led") {
      group.kind = Recipe::Group::Kind::kEachLed;
      body.ExpectKeys({"leds", "level"});
      if (auto leds = body.Find("leds")) {
        if (!(leds->IsScalar() && leds->AsString() == "all")) group.led_ids = leds->AsIntList();
      }
      group.level = body.Double("level", 1.0);
      if (!(group.level > 0.0 && group.level <= 1.0)) body["level"].Fail("must be within (0, 1]");
    } else {
      step.Fail("unknown step '" + keys[0] + "' (expected dark or each_led)");
    }
    recipe.groups.push_back(group);
  }
  if (recipe.groups.empty()) capture["steps"].Fail("a recipe needs at least one capture step");

  if (auto solve = root.Find("solve")) {
    for (const YamlNode& stage : solve->Items()) {
      const auto keys = stage.Keys();
      if (keys.size() != 1) stage.Fail("each solve stage is a map with exactly one key");
      if (keys[0] != "photometric_stereo") stage.Fail("unknown solver '" + keys[0] + "' (expected photometric_stereo)");
      recipe.photometric_stereo = ParsePhotometricStereoRequest(stage[keys[0]]);
    }
  }
  return recipe;
}
}  // namespace

std::string ResolveRigPath(const Recipe& recipe, const std::string& override_path) {
  if (!override_path.empty()) return override_path;
  if (recipe.rig_path.empty())
    throw ConfigError(recipe.path, 0, 0, "recipe.rig", "the recipe names no rig; pass --rig FILE");
  return recipe.rig_path;
}

std::vector<CaptureStep> CompileSteps(const Recipe& recipe, const RigConfig& rig) {
  std::vector<CaptureStep> steps;
  const int channels = static_cast<int>(rig.lights.leds.size());
  const double exposure = recipe.exposure_us.value_or(rig.camera.exposure_us);
  const double gain = recipe.gain_db.value_or(rig.camera.gain_db);
  auto add = [&](CaptureStep step, const std::string& name) {
    step.index = static_cast<int>(steps.size());
    char label[64];
    std::snprintf(label, sizeof(label), "%04d_%s", step.index, name.c_str());
    step.label = label;
    step.exposure_us = exposure;
    step.gain_db = gain;
    steps.push_back(std::move(step));
  };
  for (const Recipe::Group& group : recipe.groups) {
    if (group.kind == Recipe::Group::Kind::kDark) {
      for (int i = 0; i < group.count; ++i) {
        CaptureStep step;
        step.kind = CaptureStep::Kind::kDark;
        step.pattern = drivers::LightPattern::AllOff(channels);
        add(std::move(step), "dark");
      }
      continue;
    }
    std::vector<int> indices;
    if (group.led_ids.empty()) {
      for (int i = 0; i < channels; ++i) indices.push_back(i);
    } else {
      for (int id : group.led_ids) {
        int found = -1;
        for (int i = 0; i < channels; ++i)
          if (rig.lights.leds[i].id == id) found = i;
        if (found < 0) group.source->Fail("LED id " + std::to_string(id) + " is not in rig '" + rig.name + "'");
        indices.push_back(found);
      }
    }
    for (int i : indices) {
      CaptureStep step;
      step.kind = CaptureStep::Kind::kLight;
      step.led = i;
      step.pattern = drivers::LightPattern::Single(channels, i, group.level);
      char name[32];
      std::snprintf(name, sizeof(name), "led%02d", rig.lights.leds[i].id);
      add(std::move(step), name);
    }
  }
  return steps;
}

}  // namespace photorig::daemon
