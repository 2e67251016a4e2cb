#pragma once
// Capture recipes (config/recipes/*.yaml) and their compilation into the flat
// list of steps the sequencer executes.

#include "photorig/config/rig.h"
#include "photorig/config/solve_requests.h"
#include "photorig/drivers/light_controller.h"
#include "photorig/solvers/brdf/pose_plan.h"

#include <cstdint>
#include <memory>
#include <optional>
#include <string_view>
#include <string>
#include <utility>
#include <vector>

namespace photorig::config {

struct Recipe {
  std::string path;
  std::string name;
  std::string description;
  std::string sample_name;
  // sample.sim_scene: replaces a simulated rig's scene. Parsed for the rig the
  // recipe was loaded for, whose frame sizes the defaults.
  std::optional<sim::Scene> sim_scene;
  std::optional<double> exposure_us;    // overrides the rig camera's exposure
  std::optional<double> gain_db;

  // One entry of capture.steps. Every group takes `repeat: N` (default 1):
  // its whole step sequence is emitted N times in a row.
  struct Group {
    enum class Kind {
      kDark,     // dark: {count}
      kFlat,     // flat: {count, level, leds, exposure_us}: the listed LEDs (default all) lit together
      kEachLed,  // each_led: {leds, level, exposures_us}: one frame per LED per bracket exposure
      kPattern,  // pattern: {name, leds: [{id, level} | id], level, count, exposure_us}
      // poses: {list: [{light_arm_deg, camera_arm_deg, sample_rotation_deg, sample_changer_deg}] | grid: {...} |
      //         plan: {theta_h_deg, theta_d_deg, phi_d_deg: {min, max, steps} | angle, sample_rotation_deg, grazing_deg},
      //         level, exposures_us, count}: per pose, `count` frames at each bracket exposure.
      // A plan is made for the rig's arms when the recipe loads (solvers/brdf/pose_plan.h);
      // plan: {..., adaptive: {passes, added_poses, min_interval_deg, value_floor}} adds passes after it (AdaptivePlan).
      kPoses,
      // reference_target: {count, exposures_us, level}: frames of the rig's
      // reference target at its pose, for the radiometric calibration
      kReferenceTarget,
    };
    // The steps' keys, and a step's `group` ("pattern:<name>" for a pattern).
    static constexpr solvers::core::NameTable<Kind, 6> kKindNames = {{{Kind::kDark, "dark"},
                                                                     {Kind::kFlat, "flat"},
                                                                     {Kind::kEachLed, "each_led"},
                                                                     {Kind::kPattern, "pattern"},
                                                                     {Kind::kPoses, "poses"},
                                                                     {Kind::kReferenceTarget, "reference_target"}}};
    Kind kind = Kind::kDark;
    // kDark, kFlat, kPattern: frames per repetition; kPoses, kReferenceTarget:
    // frames per pose and exposure (repeats the solve merges and checks its noise model with)
    int count = 1;
    int repeat = 1;
    std::vector<int> led_ids;  // kFlat, kEachLed: empty = all LEDs
    double level = 1.0;        // kFlat, kEachLed, kPoses (every LED), kPattern (entries given as bare ids)
    // kEachLed, kPoses, kReferenceTarget: the HDR bracket; kDark: one set of
    // darks per exposure (dark current grows with it); kFlat, kPattern: at
    // most one. Empty = the capture's exposure.
    std::vector<double> exposures_us;
    std::string name;                  // kPattern: goes into the labels
    std::vector<std::pair<int, double>> pattern;  // kPattern: (LED id, level)
    std::vector<GonioPose> poses;                 // kPoses, in capture order
    // kPoses from a plan: the configurations refused and why, grazing poses,
    // too few poses for a model; dry-run lists them as warnings.
    std::vector<std::string> plan_notes;
    // kPoses from a plan with `adaptive:`: passes taken after the planned (coarse) poses.
    struct AdaptivePlan {
      int passes = 2;  // passes after the coarse one; a pass with nothing left to split ends the plan early
      // added_poses (16), min_interval_deg (0.5), value_floor (1e-3 1/sr): ProposeDenserPoses's options.
      solvers::brdf::AdaptiveOptions options;
      // The coarse plan's sample_rotation_deg and grazing_deg; `start` is set per pass.
      solvers::brdf::PosePlanOptions plan;
      std::optional<YamlNode> source;  // the `adaptive:` node
    };
    std::optional<AdaptivePlan> adaptive;
    std::optional<YamlNode> source;  // for errors found once the rig is known
  };
  std::vector<Group> groups;
  std::optional<PhotometricStereoRequest> photometric_stereo;
  std::optional<LightCalibrationRequest> light_calibration;
  std::optional<LedPositionRequest> led_positions;
  std::optional<TomographyRequest> tomography;
  std::optional<SvbrdfRequest> svbrdf;
  std::optional<BrdfRequest> brdf;
  // Where the solve stages run: the rig's `solve:` unless the recipe's
  // `solve: {executor: ..., stages: [...]}` overrides it (keys it leaves out
  // keep the rig's values).
  SolveExecutorConfig solve_executor;
  // `export: {nexus: true}`: the run and its solves are also written as
  // RUN/run.nxs when they end (docs/nexus.md). Default off.
  bool export_nexus = false;
};

struct CaptureStep {
  // kLight: exactly one LED lit (what photometric stereo consumes); kFlat: a
  // uniformly lit reference; kPattern: a named LED pattern; kPose: a
  // gonioreflectometer pose, arms moved before the frame.
  enum class Kind { kDark, kLight, kFlat, kPattern, kPose };
  int index = 0;
  Kind kind = Kind::kDark;
  std::string label;         // file stem, unique in the run: "0000_dark", "0001_led07", "0003_led02_e4000"
  std::string group;         // the recipe group it came from: "dark", "each_led", "flat", "pattern:<name>", "poses", "reference_target"
  Recipe::Group::Kind group_kind = Recipe::Group::Kind::kDark;  // that group's kind
  int repeat = 0;            // 0-based repetition of its group
  int led = -1;              // kLight: index into RigConfig::lights.leds; -1 otherwise
  // One level per rig LED, shared by the steps that light the LEDs alike (a
  // group's repetitions, one LED's steps): a plan of 100 000 steps on a
  // 96-LED dome held 77 MB in copies of a few patterns. Never null.
  std::shared_ptr<const drivers::LightPattern> pattern = std::make_shared<const drivers::LightPattern>();
  double exposure_us = 0.0;
  double gain_db = 0.0;
  std::optional<GonioPose> pose;  // kPose only
  // A pose of an adaptive plan: 0 for the coarse pass (and any other step), k
  // for the k-th added pass; `ends_pass` marks the last step of a pass, after
  // which the next pass is planned from the frames taken so far.
  int pass = 0;
  bool ends_pass = false;
};

// Bounds on what one recipe may expand to. Counts, repeats and YAML aliases
// multiply, so a few lines can ask for millions of frames; CompileSteps checks
// these while it expands, group by group, and stops at the first group that
// crosses one. The defaults are far beyond any real capture (a day of dome
// captures is a few thousand frames) and far below what exhausts the daemon.
struct CaptureLimits {
  int max_frames = 100000;
  std::uint64_t max_bytes = std::uint64_t{1} << 41;  // 2 TiB of uncompressed 16-bit frames
  double max_duration_s = 7 * 24 * 3600.0;           // exposures plus step_overhead_ms per frame
  double step_overhead_ms = 40.0;  // counted per frame towards max_duration_s (as PlanOptions counts it)

  bool IsValid(std::string* why) const;
};

// A recipe that compiles but expands beyond CaptureLimits: the position is the
// group that crossed the limit.
class CaptureLimitError : public ConfigError {
 public:
  using ConfigError::ConfigError;
};

// The recipe's poses group with an adaptive plan (a recipe has at most one); null without.
const Recipe::Group* AdaptivePlanGroup(const Recipe& recipe);

// The steps of one added pass of `group`'s adaptive plan: `count` frames of
// each pose at each exposure of its bracket, as CompileSteps makes a poses
// group's, numbered from `first_index`, each marked with `pass`, the last one
// ending the pass.
std::vector<CaptureStep> CompileAdaptivePass(const Recipe& recipe, const Recipe::Group& group, const RigConfig& rig,
                                             const std::vector<GonioPose>& poses, int first_index, int pass);

// A gonioreflectometer's light and camera arms as the pose planner sees them
// (limits, homes, the separation between them); nothing when the rig lacks
// either axis.
std::optional<solvers::brdf::GonioArms> GonioArmsOf(const MotionConfig& motion);

// The kind of the group a stored step names (CaptureStep::group): its
// Group::kKindNames name, "pattern:<name>" for a pattern; nullopt for other text.
std::optional<Recipe::Group::Kind> GroupKindOfLabel(std::string_view group);

// "dark" | "light" | "flat" | "pattern" | "pose": the kind as journals and manifests spell it.
const char* CaptureStepKindName(CaptureStep::Kind kind);
// The kind a name of CaptureStepKindName stands for (a stored frame's "kind"); nullopt for any other text.
std::optional<CaptureStep::Kind> CaptureStepKindFromName(const std::string& name);

// Reads a recipe for the rig it will run on. Throws ConfigError naming
// file:line:column and key. Every path the recipe names (sample.sim_scene.path,
// light_calibration's silhouette and out_rig, led_positions' out_rig) is relative to the recipe's
// folder and must stay inside it.
Recipe LoadRecipe(const std::string& path, const RigConfig& rig);
// The same from text received over the API; errors name `name` as the file.
// Its paths stay inside `directory` (default: the folder of `name`): the
// daemon passes the folder it stores recipes in, where the run will read it.
Recipe LoadRecipeText(const std::string& text, const std::string& name, const RigConfig& rig,
                      const std::string& directory = "");
// The rig file a recipe runs on: `override_path` when given, else the
// recipe's `recipe.rig` (relative to the recipe file). Throws ConfigError
// when neither names one.
std::string RecipeRigPath(const std::string& recipe_path, const std::string& override_path);
// Throws ConfigError (naming the recipe) when the recipe asks for LEDs the rig
// lacks, for poses on a rig without motion, or for a reference target the rig
// does not name; CaptureLimitError when it
// expands beyond `limits` (checked before the steps are built; an adaptive
// plan counts as its largest: every pass adding all its poses).
std::vector<CaptureStep> CompileSteps(const Recipe& recipe, const RigConfig& rig, const CaptureLimits& limits = {});

}  // namespace photorig::config
