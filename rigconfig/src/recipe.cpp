#include "photorig/config/recipe.h"

#include "photorig/config/sim.h"
#include "photorig/solvers/brdf/fit.h"
#include "photorig/solvers/brdf/pose_plan.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>

namespace photorig::config {
using solvers::core::Refuse;
namespace fs = std::filesystem;

namespace {
Recipe ParseRecipe(const YamlNode& root, const std::string& path, const RigConfig& rig);

// A path a recipe gives, relative to the recipe file.
std::string RelativeToRecipe(const std::string& recipe_path, const std::string& path) {
  const fs::path p = path;
  return (p.is_absolute() ? p : fs::path(recipe_path).parent_path() / p).lexically_normal().string();
}

// Per-group bounds that keep parsing itself cheap (the duplicate checks are
// quadratic); the whole expansion is bounded by CaptureLimits.
constexpr int kMaxGridPoses = CaptureLimits{}.max_frames;
constexpr std::size_t kMaxBracketExposures = 64;
constexpr std::size_t kMaxPatternLeds = 1024;

int CountIn(const YamlNode& body, const char* key) {
  const int count = body.Int(key, 1);
  if (count < 1 || count > 1000) body[key].Fail("must be within [1, 1000]");
  return count;
}

double LevelIn(const YamlNode& node, const char* key, double fallback) {
  const double level = node.Double(key, fallback);
  if (!(level > 0.0 && level <= 1.0)) node[key].Fail("must be within (0, 1]");
  return level;
}

double ExposureIn(const YamlNode& node) { return node.AsDoubleIn(kMinExposureUs, kMaxExposureUs); }

// `exposures_us: [..]`: an HDR bracket of distinct exposures (absent: none).
std::vector<double> BracketIn(const YamlNode& body) {
  std::vector<double> exposures;
  if (auto bracket = body.Find("exposures_us")) {
    for (const YamlNode& item : bracket->Items()) {
      const double exposure_us = ExposureIn(item);
      for (double seen : exposures)
        if (seen == exposure_us) item.Fail("exposure listed twice in the bracket");
      exposures.push_back(exposure_us);
      if (exposures.size() > kMaxBracketExposures)
        item.Fail("a bracket has at most " + std::to_string(kMaxBracketExposures) + " exposures");
    }
    if (exposures.empty()) bracket->Fail("needs at least one exposure");
  }
  return exposures;
}

// `leds: all` (or absent) is every LED; otherwise a list of LED ids.
std::vector<int> LedIdsIn(const YamlNode& body) {
  if (auto leds = body.Find("leds"))
    if (!(leds->IsScalar() && leds->AsString() == "all")) return leds->AsIntList();
  return {};
}

// A pose grid or plan whose expansion is too large to build: a capture limit
// (the API's 413, as CompileSteps' limits), not malformed YAML.
[[noreturn]] void FailTooLarge(const YamlNode& node, const std::string& message) {
  throw CaptureLimitError(node.file(), node.line(), node.column(), node.key(), message);
}

// One axis of a pose grid: a single angle, a list of them, or evenly spaced
// ones {start, step, count} (a turntable's scan).
std::vector<double> AnglesIn(const YamlNode& grid, const char* key) {
  if (!grid.Has(key)) return {0.0};
  const YamlNode node = grid[key];
  if (node.IsScalar()) return {node.AsDouble()};
  if (node.IsMap()) {
    node.ExpectKeys({"start", "step", "count"});
    const double start = node["start"].AsDouble(), step = node["step"].AsDouble();
    const int count = node["count"].AsInt();
    if (count < 1) node["count"].Fail("must be within [1, " + std::to_string(kMaxGridPoses) + "]");
    if (count > kMaxGridPoses) FailTooLarge(node["count"], "must be within [1, " + std::to_string(kMaxGridPoses) + "]");
    if (!(step != 0.0) || !std::isfinite(step)) node["step"].Fail("must be a finite angle other than 0");
    std::vector<double> angles;
    for (int i = 0; i < count; ++i) angles.push_back(start + i * step);
    return angles;
  }
  std::vector<double> angles;
  for (const YamlNode& item : node.Items()) angles.push_back(item.AsDouble());
  if (angles.empty()) node.Fail("needs at least one angle");
  return angles;
}

// One angle of a plan's sampling spec: {min, max, steps}, or a single angle;
// absent, the spec's default stays.
void SamplingIn(const YamlNode& plan, const char* key, double* min, double* max, int* steps) {
  const auto node = plan.Find(key);
  if (!node) return;
  if (node->IsScalar()) {
    *min = *max = node->AsDouble();
    *steps = 1;
    return;
  }
  node->ExpectKeys({"min", "max", "steps"});
  *min = (*node)["min"].AsDouble();
  *max = (*node)["max"].AsDouble();
  *steps = (*node)["steps"].AsInt();
  if (*steps < 1 || *steps > 1000) (*node)["steps"].Fail("must be within [1, 1000]");
}

// `adaptive: {passes, added_poses, min_interval_deg, value_floor}` of a plan;
// absent keys keep AdaptivePlan's defaults.
Recipe::Group::AdaptivePlan AdaptivePlanIn(const YamlNode& node, const solvers::brdf::PosePlanOptions& plan) {
  node.ExpectKeys({"passes", "added_poses", "min_interval_deg", "value_floor"});
  Recipe::Group::AdaptivePlan adaptive;
  adaptive.source = node;
  adaptive.plan = plan;
  adaptive.passes = node.Int("passes", adaptive.passes);
  if (adaptive.passes < 1 || adaptive.passes > 100) node["passes"].Fail("must be within [1, 100]");
  solvers::brdf::AdaptiveOptions& options = adaptive.options;
  options.added_poses = node.Int("added_poses", options.added_poses);
  if (options.added_poses < 1 || options.added_poses > 1000) node["added_poses"].Fail("must be within [1, 1000]");
  options.min_interval_deg = node.DoubleIn("min_interval_deg", options.min_interval_deg, 1e-3, 90.0);
  options.value_floor = node.DoubleIn("value_floor", options.value_floor, 1e-9, 1e3);
  if (std::string why; !options.IsValid(&why)) node.Fail(why);
  return adaptive;
}

// `plan:` poses uniform in (theta_h, theta_d, phi_d), planned for the rig's
// arms when the recipe loads. Refused configurations go to `group` notes; a
// plan that reaches none is an error here.
std::vector<GonioPose> PlannedPosesIn(const YamlNode& plan, const RigConfig& rig, Recipe::Group* group) {
  namespace brdf = solvers::brdf;
  plan.ExpectKeys({"theta_h_deg", "theta_d_deg", "phi_d_deg", "sample_rotation_deg", "grazing_deg", "adaptive"});
  const std::optional<brdf::GonioArms> arms = rig.motion ? GonioArmsOf(*rig.motion) : std::nullopt;
  if (!arms) plan.Fail("a pose plan needs a rig with light_arm and camera_arm axes; rig '" + rig.name + "' has none");
  brdf::SamplingSpec spec;
  SamplingIn(plan, "theta_h_deg", &spec.theta_h_min_deg, &spec.theta_h_max_deg, &spec.theta_h_steps);
  SamplingIn(plan, "theta_d_deg", &spec.theta_d_min_deg, &spec.theta_d_max_deg, &spec.theta_d_steps);
  SamplingIn(plan, "phi_d_deg", &spec.phi_d_min_deg, &spec.phi_d_max_deg, &spec.phi_d_steps);
  if (std::string why; !spec.IsValid(&why)) plan.Fail(why);
  const double size = static_cast<double>(spec.theta_h_steps) * spec.theta_d_steps * spec.phi_d_steps;
  if (size > kMaxGridPoses) FailTooLarge(plan, "asks for more than " + std::to_string(kMaxGridPoses) + " configurations");
  brdf::PosePlanOptions options;
  options.sample_rotation_deg = plan.DoubleIn("sample_rotation_deg", 0.0, -180.0, 180.0);
  options.grazing_deg = plan.DoubleIn("grazing_deg", options.grazing_deg, 1.0, 90.0);
  if (auto adaptive = plan.Find("adaptive")) group->adaptive = AdaptivePlanIn(*adaptive, options);
  const brdf::PosePlan planned = brdf::PlanPoses(brdf::UniformHalfDiffGrid(spec), *arms, options);
  if (planned.termination == solvers::core::Termination::kInvalidOptions)
    plan.Fail("rig '" + rig.name + "' arms: " + planned.message);
  constexpr double kDeg = 180.0 / M_PI;
  for (const brdf::RefusedPose& r : planned.refused) {
    char text[96];
    std::snprintf(text, sizeof text, "theta_h %.2f theta_d %.2f phi_d %.2f deg refused: ", r.requested.theta_h * kDeg,
                  r.requested.theta_d * kDeg, r.requested.phi_d * kDeg);
    group->plan_notes.push_back(text + r.reason);
  }
  if (!planned.IsSolutionUsable()) {
    plan.Fail(planned.message + (planned.refused.empty() ? "" : " (first: " + group->plan_notes.front() + ")"));
  }
  if (planned.grazing > 0) {
    char text[160];
    std::snprintf(text, sizeof text, "%d of %zu planned poses are grazing (an arm beyond %g deg)", planned.grazing,
                  planned.poses.size(), options.grazing_deg);
    group->plan_notes.push_back(std::string(text) + ": the footprint stretches and the cosine-weighted signal is small there");
  }
  // Three values per pose (R, G, B); a grey camera repeats one.
  for (const brdf::Model model : brdf::SelectionOptions{}.candidates)
    if (static_cast<int>(planned.poses.size()) < brdf::ParameterCount(model)) {
      group->plan_notes.push_back(std::to_string(planned.poses.size()) + " planned poses: fewer than the " +
                                  std::to_string(brdf::ParameterCount(model)) + " parameters of " +
                                  brdf::ModelName(model) + " (a grey camera's channels repeat one value)");
      break;
    }
  std::vector<GonioPose> poses;
  for (const brdf::PlannedPose& p : planned.poses)
    poses.push_back({p.arms.light_arm_deg, p.arms.camera_arm_deg, p.arms.sample_rotation_deg, std::nullopt});
  return poses;
}

std::vector<GonioPose> PosesIn(const YamlNode& body, const RigConfig& rig, Recipe::Group* group) {
  if (body.Has("list") + body.Has("grid") + body.Has("plan") != 1) body.Fail("give exactly one of 'list', 'grid' or 'plan'");
  if (auto plan = body.Find("plan")) return PlannedPosesIn(*plan, rig, group);
  std::vector<GonioPose> poses;
  if (auto list = body.Find("list")) {
    for (const YamlNode& item : list->Items()) {
      item.ExpectKeys({"light_arm_deg", "camera_arm_deg", "sample_rotation_deg", "sample_changer_deg"});
      poses.push_back({item["light_arm_deg"].AsDouble(), item["camera_arm_deg"].AsDouble(),
                       item.Double("sample_rotation_deg", 0.0), std::nullopt});
      if (auto changer = item.Find("sample_changer_deg")) poses.back().sample_changer_deg = changer->AsDouble();
    }
    if (poses.empty()) list->Fail("needs at least one pose");
    return poses;
  }
  const YamlNode grid = body["grid"];
  grid.ExpectKeys({"light_arm_deg", "camera_arm_deg", "sample_rotation_deg", "sample_changer_deg"});
  std::optional<double> changer;  // one position for the whole grid
  if (auto node = grid.Find("sample_changer_deg")) changer = node->AsDouble();
  const std::vector<double> rotations = AnglesIn(grid, "sample_rotation_deg");
  const std::vector<double> lights = AnglesIn(grid, "light_arm_deg");
  const std::vector<double> cameras = AnglesIn(grid, "camera_arm_deg");
  // Refused from its dimensions, before a single pose is built.
  const double size = static_cast<double>(rotations.size()) * lights.size() * cameras.size();
  if (size > kMaxGridPoses)
    FailTooLarge(grid, "expands to " + std::to_string(rotations.size()) + " x " + std::to_string(lights.size()) + " x " +
              std::to_string(cameras.size()) + " poses, more than " + std::to_string(kMaxGridPoses));
  poses.reserve(static_cast<std::size_t>(size));
  for (double rotation : rotations)
    for (double light : lights)
      for (double camera : cameras) poses.push_back({light, camera, rotation, changer});
  return poses;
}

Recipe::Group ParseGroup(const YamlNode& step, const RigConfig& rig) {
  using Kind = Recipe::Group::Kind;
  const auto keys = step.Keys();
  if (keys.size() != 1) step.Fail("each step is a map with exactly one key: " + solvers::core::NamesInProse(Recipe::Group::kKindNames));
  Recipe::Group group;
  group.source = step;
  const std::string& kind = keys[0];
  const YamlNode body = step[kind];
  const std::optional<Kind> parsed = solvers::core::ParseName(Recipe::Group::kKindNames, kind);
  if (!parsed) step.Fail("unknown step '" + kind + "' (expected " + solvers::core::NamesInProse(Recipe::Group::kKindNames) + ")");
  group.kind = *parsed;
  if (group.kind == Kind::kDark) {
    body.ExpectKeys({"count", "exposures_us", "repeat"});
    group.count = CountIn(body, "count");
    group.exposures_us = BracketIn(body);
  } else if (group.kind == Kind::kFlat) {
    body.ExpectKeys({"count", "level", "leds", "exposure_us", "repeat"});
    group.count = CountIn(body, "count");
    group.level = LevelIn(body, "level", 1.0);
    group.led_ids = LedIdsIn(body);
    if (auto exposure = body.Find("exposure_us")) group.exposures_us = {ExposureIn(*exposure)};
  } else if (group.kind == Kind::kEachLed) {
    body.ExpectKeys({"leds", "level", "exposures_us", "repeat"});
    group.led_ids = LedIdsIn(body);
    group.level = LevelIn(body, "level", 1.0);
    group.exposures_us = BracketIn(body);
  } else if (group.kind == Kind::kPattern) {
    body.ExpectKeys({"name", "leds", "level", "count", "exposure_us", "repeat"});
    const YamlNode name = body["name"];
    group.name = name.AsString();
    if (group.name.empty() || group.name.find_first_not_of("abcdefghijklmnopqrstuvwxyz0123456789_-") != std::string::npos)
      name.Fail("must be non-empty lower-case letters, digits, '_' or '-' (it becomes part of file names)");
    group.level = LevelIn(body, "level", 1.0);
    group.count = CountIn(body, "count");
    if (auto exposure = body.Find("exposure_us")) group.exposures_us = {ExposureIn(*exposure)};
    for (const YamlNode& item : body["leds"].Items()) {
      std::pair<int, double> entry{0, group.level};
      if (item.IsMap()) {
        item.ExpectKeys({"id", "level"});
        entry = {item["id"].AsInt(), LevelIn(item, "level", group.level)};
      } else {
        entry.first = item.AsInt();
      }
      for (const auto& seen : group.pattern)
        if (seen.first == entry.first) item.Fail("LED id " + std::to_string(entry.first) + " listed twice");
      group.pattern.push_back(entry);
      if (group.pattern.size() > kMaxPatternLeds)
        item.Fail("a pattern lists at most " + std::to_string(kMaxPatternLeds) + " LEDs");
    }
    if (group.pattern.empty()) body["leds"].Fail("a pattern lights at least one LED");
  } else if (group.kind == Kind::kPoses) {
    body.ExpectKeys({"list", "grid", "plan", "level", "exposures_us", "count", "repeat"});
    group.level = LevelIn(body, "level", 1.0);
    group.exposures_us = BracketIn(body);
    group.count = CountIn(body, "count");
    group.poses = PosesIn(body, rig, &group);
  } else if (group.kind == Kind::kReferenceTarget) {
    body.ExpectKeys({"level", "exposures_us", "count", "repeat"});
    group.level = LevelIn(body, "level", 1.0);
    group.exposures_us = BracketIn(body);
    group.count = CountIn(body, "count");
  }
  group.repeat = body.Int("repeat", 1);
  if (group.repeat < 1 || group.repeat > 1000) body["repeat"].Fail("must be within [1, 1000]");
  if (group.adaptive && group.repeat > 1)
    body["repeat"].Fail("an adaptive plan cannot repeat: its passes follow the coarse poses once (give count for repeats)");
  return group;
}
}  // namespace

// The folder a recipe's paths stay in: the one given, else the recipe file's.
std::string PathRoot(const std::string& recipe_path, const std::string& directory) {
  if (!directory.empty()) return directory;
  const fs::path parent = fs::path(recipe_path).parent_path();
  return parent.empty() ? "." : parent.string();
}

Recipe LoadRecipe(const std::string& path, const RigConfig& rig) {
  return ParseRecipe(YamlNode::LoadFile(path).ConfinedTo(PathRoot(path, "")), path, rig);
}
Recipe LoadRecipeText(const std::string& text, const std::string& name, const RigConfig& rig,
                      const std::string& directory) {
  return ParseRecipe(YamlNode::LoadString(text, name).ConfinedTo(PathRoot(name, directory)), name, rig);
}

namespace {
// An adaptive plan measures the BRDF of the poses taken so far between its
// passes (daemon/brdf_measurement.h): darks at each of its exposures, two at
// one of them (the read noise), and the reference target must be taken before
// it. A recipe has at most one: every pose frame feeds the same measurement.
void CheckAdaptivePlan(const Recipe& recipe, const RigConfig& rig) {
  using Kind = Recipe::Group::Kind;
  const Recipe::Group* adaptive = nullptr;
  std::vector<double> dark_exposures_us, target_exposures_us;
  bool two_darks = false, target = false;
  const double default_us = recipe.exposure_us.value_or(rig.camera.exposure_us);
  for (const Recipe::Group& group : recipe.groups) {
    const std::vector<double> exposures_us = group.exposures_us.empty() ? std::vector<double>{default_us} : group.exposures_us;
    if (group.adaptive) {
      if (adaptive) group.adaptive->source->Fail("a recipe has at most one adaptive plan (the first is at line " +
                                                 std::to_string(adaptive->adaptive->source->line()) + ")");
      adaptive = &group;
      const YamlNode& at = *group.adaptive->source;
      const std::string move = "; an adaptive plan measures the poses taken so far between its passes, so put the "
                               "dark and reference_target steps before this poses step";
      if (!target) at.Fail("no reference_target step before the adaptive plan" + move);
      std::vector<double> needed_us = exposures_us;
      needed_us.insert(needed_us.end(), target_exposures_us.begin(), target_exposures_us.end());
      for (double exposure_us : needed_us)
        if (std::find(dark_exposures_us.begin(), dark_exposures_us.end(), exposure_us) == dark_exposures_us.end()) {
          char text[112];
          std::snprintf(text, sizeof text, "no dark frames at %.0f us (a pose or reference target exposure) before "
                        "the adaptive plan", exposure_us);
          at.Fail(text + move);
        }
      if (!two_darks) at.Fail("fewer than two dark frames at one exposure before the adaptive plan (they give the "
                              "read noise)" + move);
    }
    if (group.kind == Kind::kReferenceTarget) {
      target = true;
      target_exposures_us.insert(target_exposures_us.end(), exposures_us.begin(), exposures_us.end());
    }
    if (group.kind == Kind::kDark) {
      dark_exposures_us.insert(dark_exposures_us.end(), exposures_us.begin(), exposures_us.end());
      two_darks = two_darks || group.count * group.repeat >= 2;
    }
  }
}

Recipe ParseRecipe(const YamlNode& root, const std::string& path, const RigConfig& rig) {
  root.ExpectKeys({"recipe", "sample", "capture", "solve", "export"});
  Recipe recipe;
  recipe.path = path;

  const YamlNode header = root["recipe"];
  header.ExpectKeys({"name", "description", "rig"});
  recipe.name = header["name"].AsString();
  recipe.description = header.String("description", "");
  // `rig:` is read by RecipeRigPath, before the recipe; checked here too, since --rig may override it.
  if (auto rig_name = header.Find("rig")) rig_name->AsString();

  if (auto sample = root.Find("sample")) {
    sample->ExpectKeys({"name", "sim_scene"});
    recipe.sample_name = sample->String("name", "");
    if (auto scene = sample->Find("sim_scene")) recipe.sim_scene = config::ParseScene(*scene, config::FrameWidthMm(rig));
  }

  const YamlNode capture = root["capture"];
  capture.ExpectKeys({"exposure_us", "gain_db", "steps"});
  if (auto exposure = capture.Find("exposure_us")) recipe.exposure_us = ExposureIn(*exposure);
  if (auto gain = capture.Find("gain_db")) recipe.gain_db = gain->AsDoubleIn(kMinGainDb, kMaxGainDb);
  for (const YamlNode& step : capture["steps"].Items()) recipe.groups.push_back(ParseGroup(step, rig));
  if (recipe.groups.empty()) capture["steps"].Fail("a recipe needs at least one capture step");
  CheckAdaptivePlan(recipe, rig);

  recipe.solve_executor = rig.solve;
  if (auto solve = root.Find("solve")) {
    // A list of stages, or {executor, partition, time, mem, photorig, poll_ms, stages} to choose where they run.
    std::optional<YamlNode> stages = solve;
    if (solve->IsMap()) {
      solve->ExpectKeys({"executor", "partition", "time", "mem", "photorig", "poll_ms", "stages"});
      recipe.solve_executor = ParseSolveExecutor(*solve, rig.solve);
      stages = solve->Find("stages");
    }
    for (const YamlNode& stage : stages ? stages->Items() : std::vector<YamlNode>{}) {
      const auto keys = stage.Keys();
      if (keys.size() != 1) stage.Fail("each solve stage is a map with exactly one key");
      if (keys[0] == "photometric_stereo") recipe.photometric_stereo = ParsePhotometricStereoRequest(stage[keys[0]]);
      else if (keys[0] == "light_calibration") recipe.light_calibration = ParseLightCalibrationRequest(stage[keys[0]]);
      else if (keys[0] == "led_positions") recipe.led_positions = ParseLedPositionRequest(stage[keys[0]]);
      else if (keys[0] == "tomography") recipe.tomography = ParseTomographyRequest(stage[keys[0]]);
      else if (keys[0] == "svbrdf") recipe.svbrdf = ParseSvbrdfRequest(stage[keys[0]]);
      else if (keys[0] == "brdf") recipe.brdf = ParseBrdfRequest(stage[keys[0]]);
      else stage.Fail("unknown solver '" + keys[0] +
                      "' (expected photometric_stereo, light_calibration, led_positions, tomography, svbrdf or brdf)");
    }
  }
  if (auto exporting = root.Find("export")) {
    exporting->ExpectKeys({"nexus"});
    recipe.export_nexus = exporting->Bool("nexus", false);
  }
  return recipe;
}
}  // namespace

std::string RecipeRigPath(const std::string& recipe_path, const std::string& override_path) {
  if (!override_path.empty()) return override_path;
  const YamlNode root = YamlNode::LoadFile(recipe_path);
  if (auto rig = root["recipe"].Find("rig")) {
    const std::string path = RelativeToRecipe(recipe_path, rig->AsString());
    std::error_code error;
    if (!fs::exists(path, error)) {
      const fs::path folder = fs::path(recipe_path).parent_path();
      rig->Fail("rig file " + path + " not found (a relative rig path resolves from the recipe's folder, " +
                (folder.empty() ? std::string(".") : folder.string()) + "/, not from where photorig runs); fix it " +
                "or pass --rig FILE");
    }
    return path;
  }
  throw ConfigError(recipe_path, 0, 0, "recipe.rig", "the recipe names no rig; pass --rig FILE");
}

namespace {
// "_e2000": a bracketed frame's exposure in its label.
std::string ExposureSuffix(double exposure_us) {
  char suffix[32];
  std::snprintf(suffix, sizeof(suffix), "_e%.0f", exposure_us);
  return suffix;
}

// "0007_<name>": a step's label, from its index.
void Label(CaptureStep* step, int index, const std::string& name) {
  step->index = index;
  char label[128];
  std::snprintf(label, sizeof(label), "%04d_%s", index, name.c_str());
  step->label = label;
}

// The frames of a poses or reference_target group at `poses`: per pose,
// `count` at each exposure of the group's bracket (or the capture's
// exposure), every LED at the group's level; `emit` gets each with its name.
void PoseFrames(const Recipe::Group& group, const std::vector<GonioPose>& poses, const RigConfig& rig,
                double default_exposure_us, double gain_db,
                const std::function<void(CaptureStep, const std::string&)>& emit) {
  const bool target = group.kind == Recipe::Group::Kind::kReferenceTarget;
  CaptureStep base;
  base.kind = CaptureStep::Kind::kPose;
  base.group_kind = group.kind;
  base.group = solvers::core::NameOf(Recipe::Group::kKindNames, group.kind);
  base.pattern = std::make_shared<const drivers::LightPattern>(
      drivers::LightPattern{std::vector<double>(rig.lights.leds.size(), group.level)});
  base.gain_db = gain_db;
  const bool bracket = !group.exposures_us.empty();
  const std::vector<double> exposures = bracket ? group.exposures_us : std::vector<double>{default_exposure_us};
  for (GonioPose pose : poses) {
    // With the target in a changer slot, a pose that names no slot must still see the sample.
    if (!target && !pose.sample_changer_deg && rig.reference_target && rig.reference_target->pose.sample_changer_deg)
      pose.sample_changer_deg = 0.0;
    char name[96];
    std::snprintf(name, sizeof(name), "%s_l%+.1f_c%+.1f_r%+.1f", target ? "target" : "pose", pose.light_arm_deg,
                  pose.camera_arm_deg, pose.sample_rotation_deg);
    for (double exposure_us : exposures)
      for (int i = 0; i < group.count; ++i) {
        CaptureStep step = base;
        step.pose = pose;
        step.exposure_us = exposure_us;
        emit(std::move(step), bracket ? name + ExposureSuffix(exposure_us) : name);
      }
  }
}
}  // namespace

std::optional<solvers::brdf::GonioArms> GonioArmsOf(const MotionConfig& motion) {
  const AxisConfig* light = motion.axis("light_arm");
  const AxisConfig* camera = motion.axis("camera_arm");
  if (!light || !camera) return std::nullopt;
  solvers::brdf::GonioArms arms;
  arms.light_min_deg = light->limits.min_deg;
  arms.light_max_deg = light->limits.max_deg;
  arms.light_home_deg = light->limits.home_deg;
  arms.camera_min_deg = camera->limits.min_deg;
  arms.camera_max_deg = camera->limits.max_deg;
  arms.camera_home_deg = camera->limits.home_deg;
  arms.min_separation_deg = 0.0;
  for (const auto& c : motion.constraints)
    if ((c.axis_a == "light_arm" && c.axis_b == "camera_arm") || (c.axis_a == "camera_arm" && c.axis_b == "light_arm"))
      arms.min_separation_deg = std::max(arms.min_separation_deg, c.min_deg);
  return arms;
}

namespace {

constexpr solvers::core::NameTable<CaptureStep::Kind, 5> kCaptureStepKindNames = {{
    {CaptureStep::Kind::kDark, "dark"}, {CaptureStep::Kind::kLight, "light"}, {CaptureStep::Kind::kFlat, "flat"},
    {CaptureStep::Kind::kPattern, "pattern"}, {CaptureStep::Kind::kPose, "pose"},
}};

}  // namespace

const char* CaptureStepKindName(CaptureStep::Kind kind) { return solvers::core::NameOf(kCaptureStepKindNames, kind); }

std::optional<Recipe::Group::Kind> GroupKindOfLabel(std::string_view group) {
  constexpr std::string_view kPatternPrefix = "pattern:";
  if (group.substr(0, kPatternPrefix.size()) == kPatternPrefix) return Recipe::Group::Kind::kPattern;
  return solvers::core::ParseName(Recipe::Group::kKindNames, group);
}

std::optional<CaptureStep::Kind> CaptureStepKindFromName(const std::string& name) {
  return solvers::core::ParseName(kCaptureStepKindNames, name);
}

bool CaptureLimits::IsValid(std::string* why) const {
  if (max_frames < 1) return Refuse(why, "max_frames must be >= 1");
  if (max_bytes == 0) return Refuse(why, "max_bytes must be > 0");
  if (!(max_duration_s > 0)) return Refuse(why, "max_duration_s must be > 0");
  if (!(step_overhead_ms >= 0)) return Refuse(why, "step_overhead_ms must be >= 0");
  return true;
}

std::vector<CaptureStep> CompileSteps(const Recipe& recipe, const RigConfig& rig, const CaptureLimits& limits) {
  using Kind = Recipe::Group::Kind;
  if (std::string why; !limits.IsValid(&why)) throw ConfigError(recipe.path, 0, 0, "", "capture limits: " + why);
  std::vector<CaptureStep> steps;
  // What the steps so far add up to, and the bound each group is checked
  // against before its repetitions are built.
  const double bytes_per_frame = 2.0 * rig.camera.width * rig.camera.height + 4096;
  double total_bytes = 0.0, total_s = 0.0;
  auto over_limit = [&](const Recipe::Group& group, double frames, double bytes, double seconds) {
    auto whole = [](double value) { return std::to_string(static_cast<long long>(std::min(value, 1e18))); };
    auto fail = [&](const std::string& what) {
      throw CaptureLimitError(recipe.path, group.source ? group.source->line() : 0,
                              group.source ? group.source->column() : 0, group.source ? group.source->key() : "",
                              "the capture would " + what);
    };
    if (frames > limits.max_frames)
      fail("take more than " + std::to_string(limits.max_frames) + " frames (" + whole(frames) + " with this group)");
    if (bytes > static_cast<double>(limits.max_bytes))
      fail("store more than " + std::to_string(limits.max_bytes >> 30) + " GiB (" + whole(bytes / (1 << 30)) +
           " GiB with this group)");
    if (seconds > limits.max_duration_s)
      fail("last more than " + whole(limits.max_duration_s) + " s (" + whole(seconds) + " s with this group)");
  };
  const int channels = static_cast<int>(rig.lights.leds.size());
  const double default_exposure_us = recipe.exposure_us.value_or(rig.camera.exposure_us);
  const double gain = recipe.gain_db.value_or(rig.camera.gain_db);
  auto led_index = [&](const Recipe::Group& group, int id) {
    for (int i = 0; i < channels; ++i)
      if (rig.lights.leds[i].id == id) return i;
    group.source->Fail("LED id " + std::to_string(id) + " is not in rig '" + rig.name + "'");
  };
  auto led_indices = [&](const Recipe::Group& group) {
    std::vector<int> indices;
    if (group.led_ids.empty())
      for (int i = 0; i < channels; ++i) indices.push_back(i);
    for (int id : group.led_ids) indices.push_back(led_index(group, id));
    return indices;
  };
  // An adaptive plan's added passes, at their largest, count towards every limit after their group.
  double adaptive_frames = 0.0, adaptive_s = 0.0;
  for (const Recipe::Group& group : recipe.groups) {
    const double group_exposure_us = group.exposures_us.empty() ? default_exposure_us : group.exposures_us.front();
    std::vector<CaptureStep> once;  // one repetition; labels are made below
    std::vector<std::string> names;
    double once_s = 0.0;
    auto emit = [&](CaptureStep step, const std::string& name, double exposure_us) {
      once_s += (exposure_us / 1000.0 + limits.step_overhead_ms) / 1000.0;
      // One repetition alone can be long (an LED list with repeated ids): checked as it grows.
      over_limit(group, static_cast<double>(steps.size() + once.size() + 1),
                 total_bytes + bytes_per_frame * static_cast<double>(once.size() + 1), total_s + once_s);
      step.exposure_us = exposure_us;
      step.gain_db = gain;
      once.push_back(std::move(step));
      names.push_back(name);
    };
    CaptureStep base;
    base.group_kind = group.kind;
    drivers::LightPattern lit = drivers::LightPattern::AllOff(channels);  // a flat's or pattern's levels
    base.pattern = std::make_shared<const drivers::LightPattern>(lit);
    switch (group.kind) {
      case Kind::kDark:
        base.group = solvers::core::NameOf(Recipe::Group::kKindNames, Kind::kDark);
        for (double exposure_us : group.exposures_us.empty() ? std::vector<double>{default_exposure_us}
                                                             : group.exposures_us)
          for (int i = 0; i < group.count; ++i)
            emit(base, group.exposures_us.empty() ? "dark" : "dark" + ExposureSuffix(exposure_us), exposure_us);
        break;
      case Kind::kFlat:
        base.kind = CaptureStep::Kind::kFlat;
        base.group = solvers::core::NameOf(Recipe::Group::kKindNames, Kind::kFlat);
        for (int i : led_indices(group)) lit.levels[i] = group.level;
        base.pattern = std::make_shared<const drivers::LightPattern>(std::move(lit));
        for (int i = 0; i < group.count; ++i) emit(base, "flat", group_exposure_us);
        break;
      case Kind::kPattern: {
        base.kind = CaptureStep::Kind::kPattern;
        base.group = "pattern:" + group.name;
        for (const auto& [id, level] : group.pattern) lit.levels[led_index(group, id)] = level;
        base.pattern = std::make_shared<const drivers::LightPattern>(std::move(lit));
        for (int i = 0; i < group.count; ++i) emit(base, "pat_" + group.name, group_exposure_us);
        break;
      }
      case Kind::kEachLed: {
        base.kind = CaptureStep::Kind::kLight;
        base.group = solvers::core::NameOf(Recipe::Group::kKindNames, Kind::kEachLed);
        const bool bracket = !group.exposures_us.empty();
        const std::vector<double> exposures = bracket ? group.exposures_us : std::vector<double>{default_exposure_us};
        for (int i : led_indices(group)) {
          const auto single = std::make_shared<const drivers::LightPattern>(
              drivers::LightPattern::Single(channels, i, group.level));
          for (double exposure_us : exposures) {
            CaptureStep step = base;
            step.led = i;
            step.pattern = single;
            char name[48];
            std::snprintf(name, sizeof(name), "led%02d", rig.lights.leds[i].id);
            emit(std::move(step), bracket ? name + ExposureSuffix(exposure_us) : name, exposure_us);
          }
        }
        break;
      }
      case Kind::kPoses:
      case Kind::kReferenceTarget: {
        if (!rig.motion) group.source->Fail("poses need a rig with a motion: section; rig '" + rig.name + "' has none");
        const bool target = group.kind == Kind::kReferenceTarget;
        if (target && !rig.reference_target)
          group.source->Fail("rig '" + rig.name + "' names no reference_target to capture");
        PoseFrames(group, target ? std::vector<GonioPose>{rig.reference_target->pose} : group.poses, rig,
                   default_exposure_us, gain, [&](CaptureStep step, const std::string& name) {
                     const double exposure_us = step.exposure_us;
                     emit(std::move(step), name, exposure_us);
                   });
        if (group.adaptive) {
          // The largest the plan can grow: every pass adds all its poses.
          const auto& a = *group.adaptive;
          const double per_pose = static_cast<double>(group.count) *
                                  (group.exposures_us.empty() ? 1 : group.exposures_us.size());
          const double frames = per_pose * a.passes * a.options.added_poses;
          double exposures_s = 0.0;
          for (double exposure_us : group.exposures_us.empty() ? std::vector<double>{default_exposure_us}
                                                               : group.exposures_us)
            exposures_s += group.count * (exposure_us / 1000.0 + limits.step_overhead_ms) / 1000.0;
          adaptive_frames += frames;
          adaptive_s += exposures_s * a.passes * a.options.added_poses;
        }
        break;
      }
    }
    const double repeats = group.repeat;
    total_bytes += bytes_per_frame * static_cast<double>(once.size()) * repeats;
    total_s += once_s * repeats;
    over_limit(group, static_cast<double>(steps.size()) + static_cast<double>(once.size()) * repeats + adaptive_frames,
               total_bytes + bytes_per_frame * adaptive_frames, total_s + adaptive_s);
    // Grown by this group's size, at least by half: doubling would hold up to
    // twice the steps of a 100 000-frame plan, growing by each group alone
    // would move them all once per group.
    if (const std::size_t needed = steps.size() + once.size() * static_cast<std::size_t>(group.repeat);
        needed > steps.capacity())
      steps.reserve(std::max(needed, steps.capacity() + steps.capacity() / 2));
    for (int repeat = 0; repeat < group.repeat; ++repeat)
      for (std::size_t k = 0; k < once.size(); ++k) {
        CaptureStep step = once[k];
        step.repeat = repeat;
        Label(&step, static_cast<int>(steps.size()), names[k]);
        steps.push_back(std::move(step));
      }
    if (group.adaptive && !steps.empty()) steps.back().ends_pass = true;  // the coarse pass
  }
  return steps;
}

const Recipe::Group* AdaptivePlanGroup(const Recipe& recipe) {
  for (const Recipe::Group& group : recipe.groups)
    if (group.adaptive) return &group;
  return nullptr;
}

std::vector<CaptureStep> CompileAdaptivePass(const Recipe& recipe, const Recipe::Group& group, const RigConfig& rig,
                                             const std::vector<GonioPose>& poses, int first_index, int pass) {
  std::vector<CaptureStep> steps;
  PoseFrames(group, poses, rig, recipe.exposure_us.value_or(rig.camera.exposure_us),
             recipe.gain_db.value_or(rig.camera.gain_db), [&](CaptureStep step, const std::string& name) {
               step.pass = pass;
               Label(&step, first_index + static_cast<int>(steps.size()), name);
               steps.push_back(std::move(step));
             });
  if (!steps.empty()) steps.back().ends_pass = true;
  return steps;
}

}  // namespace photorig::config
