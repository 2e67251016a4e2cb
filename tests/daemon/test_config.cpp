#include "photorig/config/recipe.h"
#include "photorig/config/solve_requests.h"
#include "photorig/config/rig.h"
#include "photorig/config/sim.h"
#include "photorig/config/yaml_node.h"
#include "photorig/daemon/capture/internal/rig_devices.h"
#include "photorig/daemon/service/run.h"
#include "photorig/sim/brdf.h"
#include "photorig/solvers/brdf/merl.h"
#include "photorig/solvers/brdf/models.h"
#include "config_error_check.h"
#include "test_support.h"

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <regex>

namespace photorig::daemon {
namespace {

using photorig::testing::SourceDir;
using photorig::testing::TempDir;

const char* kRig = R"(rig:
  name: tiny
lights:
  driver: sim
  leds:
    - {direction: [0, 0, 1]}
    - {direction: [0.5, 0, 0.8], intensity: 0.9}
    - {position_mm: [0, 300, 400]}
camera:
  driver: sim
  width: 32
  height: 24
sim:
  seed: 3
)";

// The message must carry file:line:column and the dotted key.
void ExpectConfigError(const std::string& path, const std::string& text, int line, int column,
                       const std::string& key, const std::string& fragment) {
  SCOPED_TRACE(text);
  photorig::testing::ExpectConfigErrorAt([&] { config::LoadRigConfig(path); }, path, line, column, fragment, key);
}

// ExpectConfigError for kRig with its first `from` replaced by `to`, written to `name` in `dir`.
void ExpectEditedRigError(const TempDir& dir, const std::string& name, const std::string& from, const std::string& to,
                          int line, int column, const std::string& key, const std::string& fragment) {
  std::string text = kRig;
  text.replace(text.find(from), from.size(), to);
  ExpectConfigError(dir.Write(name, text), text, line, column, key, fragment);
}

TEST(RigConfig, LoadsTheShippedSimulatedDome) {
  const config::RigConfig rig = config::LoadRigConfig(SourceDir() + "/config/rigs/sim-dome.yaml");
  EXPECT_EQ(rig.name, "sim-dome");
  EXPECT_GE(rig.lights.leds.size(), 24u);
  EXPECT_LE(rig.lights.leds.size(), 96u);
  for (const config::LedConfig& led : rig.lights.leds) {
    EXPECT_NEAR(led.direction.norm(), 1.0, 1e-12);
    EXPECT_GT(led.direction.z(), 0.0);
  }
  ASSERT_TRUE(rig.IsSimulated());
  EXPECT_DOUBLE_EQ(rig.camera.dn_per_radiance_per_us, rig.sim->sensor.response_e_per_us / rig.sim->sensor.e_per_dn);
}

// The photometric-stereo chart solves with every 8th, 4th and 2nd LED of this
// dome: each subset must reach from the low rings to the high ones and all
// the way round, or its light matrix would be poorly conditioned (each is
// about 1.16).
TEST(RigConfig, TheNinetySixLedDomeAndItsSubsetsAreWellSpread) {
  const config::RigConfig rig = config::LoadRigConfig(SourceDir() + "/config/rigs/sim-dome-96.yaml");
  EXPECT_EQ(rig.name, "sim-dome-96");
  ASSERT_EQ(rig.lights.leds.size(), 96u);
  for (std::size_t step : {8u, 4u, 2u, 1u}) {
    Eigen::Matrix3d gram = Eigen::Matrix3d::Zero();
    double lowest = 1.0, highest = 0.0;
    for (std::size_t i = 0; i < rig.lights.leds.size(); i += step) {
      const Eigen::Vector3d& w = rig.lights.leds[i].direction;
      EXPECT_NEAR(w.norm(), 1.0, 1e-6);
      gram += w * w.transpose();
      lowest = std::min(lowest, w.z());
      highest = std::max(highest, w.z());
    }
    const Eigen::Vector3d eigenvalues = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(gram).eigenvalues();
    EXPECT_LT(std::sqrt(eigenvalues(2) / eigenvalues(0)), 2.0) << "every " << step << "th LED";
    EXPECT_LT(lowest, std::sin(25 * M_PI / 180)) << "every " << step << "th LED";
    EXPECT_GT(highest, std::sin(65 * M_PI / 180)) << "every " << step << "th LED";
  }
}

TEST(RigConfig, PositionsBecomeDirections) {
  TempDir dir;
  const config::RigConfig rig = config::LoadRigConfig(dir.Write("rig.yaml", kRig));
  EXPECT_NEAR(rig.lights.leds[2].direction.y(), 0.6, 1e-12);
  EXPECT_NEAR(rig.lights.leds[2].direction.z(), 0.8, 1e-12);
  EXPECT_DOUBLE_EQ(rig.lights.leds[1].intensity, 0.9);
  EXPECT_EQ(rig.lights.leds[1].id, 1);
}

TEST(RigConfig, SimulatedNearLedsAndABuiltDomeDifferFromTheDrawing) {
  TempDir dir;
  // Many LEDs on a ring, a seeded error of 2 degrees RMS.
  std::string text = "rig: {name: ring}\nlights:\n  driver: sim\n  leds:\n";
  for (int i = 0; i < 200; ++i)
    text += "    - {direction: [" + std::to_string(std::cos(i * 0.1)) + ", " + std::to_string(std::sin(i * 0.1)) +
            ", 1.5]}\n";
  text += "    - {position_mm: [0, 60, 80]}\n";
  text += "camera: {driver: sim, width: 16, height: 16}\nsim:\n  seed: 5\n  led_direction_error_deg: 2\n";
  const config::RigConfig rig = config::LoadRigConfig(dir.Write("ring.yaml", text));
  ASSERT_TRUE(rig.lights.leds.back().position_mm.has_value());
  EXPECT_NEAR(rig.lights.leds.back().direction.dot(Eigen::Vector3d(0, 0.6, 0.8)), 1.0, 1e-12);
  const RigDevices devices = MakeRigDevices(rig, nullptr);
  const auto& lights = devices.world->config().lights;
  ASSERT_EQ(lights.size(), rig.lights.leds.size());
  double sum_squares = 0.0;
  for (std::size_t i = 0; i + 1 < lights.size(); ++i) {
    const double angle = std::acos(std::min(1.0, lights[i].direction.dot(rig.lights.leds[i].direction)));
    sum_squares += angle * angle;
    EXPECT_FALSE(lights[i].position_mm.has_value());
  }
  EXPECT_NEAR(std::sqrt(sum_squares / 200) * 180.0 / M_PI, 2.0, 0.3);
  // The near LED keeps its distance and stays aimed at the object origin.
  const sim::Light& near = lights.back();
  ASSERT_TRUE(near.position_mm.has_value());
  EXPECT_NEAR(near.position_mm->norm(), 100.0, 1e-9);
  EXPECT_NEAR(near.axis.dot(-near.position_mm->normalized()), 1.0, 1e-12);
  // Same seed, same dome.
  const RigDevices again = MakeRigDevices(rig, nullptr);
  EXPECT_EQ(again.world->config().lights[7].direction, lights[7].direction);
}

// What a real capture has and the simulated rig lacks reaches the simulated
// world from the rig file: LED intensity errors (5 % RMS over 200 LEDs: the
// sample RMS has a standard error of 0.25 %, the test allows five), ambient
// light and the camera's response curve; a curve out of range fails at its key.
TEST(RigConfig, SimulatedIntensityErrorsAmbientLightAndResponseCurveReachTheWorld) {
  TempDir dir;
  std::string text = "rig: {name: ring}\nlights:\n  driver: sim\n  leds:\n";
  for (int i = 0; i < 200; ++i)
    text += "    - {direction: [" + std::to_string(std::cos(i * 0.1)) + ", " + std::to_string(std::sin(i * 0.1)) +
            ", 1.5], intensity: " + std::to_string(1.0 + i / 400.0) + "}\n";
  text += "camera: {driver: sim, width: 16, height: 16}\nsim:\n  seed: 5\n  led_intensity_error_pct: 5\n"
          "  ambient: {dome_fraction: 0.02, stray_irradiance: 0.1}\n  sensor: {response_gamma: 1.1}\n";
  const config::RigConfig rig = config::LoadRigConfig(dir.Write("ring.yaml", text));
  const RigDevices devices = MakeRigDevices(rig, nullptr);
  const sim::WorldConfig& world = devices.world->config();
  EXPECT_DOUBLE_EQ(world.ambient.dome_fraction, 0.02);
  EXPECT_DOUBLE_EQ(world.ambient.stray_irradiance, 0.1);
  EXPECT_DOUBLE_EQ(world.sensor.response_gamma, 1.1);
  double sum_squares = 0.0;
  for (std::size_t i = 0; i < world.lights.size(); ++i) {
    EXPECT_EQ(world.lights[i].direction, rig.lights.leds[i].direction);  // no direction error asked for
    const double relative = world.lights[i].irradiance / rig.lights.leds[i].intensity - 1.0;
    sum_squares += relative * relative;
  }
  EXPECT_NEAR(std::sqrt(sum_squares / world.lights.size()), 0.05, 0.0125);

  const std::string bad = "rig: {name: r}\nlights:\n  driver: sim\n  leds:\n    - {direction: [0, 0, 1]}\n"
                          "camera: {driver: sim, width: 16, height: 16}\nsim:\n  sensor: {response_gamma: 0}\n";
  ExpectConfigError(dir.Write("bad.yaml", bad), bad, 8, 28, "sim.sensor.response_gamma", "must lie in [0.2, 5]");
}

TEST(RigConfig, SyntaxErrorNamesFileLineAndColumn) {
  TempDir dir;
  const std::string text = "rig:\n  name: [unclosed\nlights: {}\n";
  const std::string path = dir.Write("bad.yaml", text);
  try {
    config::LoadRigConfig(path);
    FAIL();
  } catch (const config::ConfigError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_GE(e.line(), 2) << e.what();
    EXPECT_GT(e.column(), 0) << e.what();
    EXPECT_NE(std::string(e.what()).find("YAML syntax error"), std::string::npos) << e.what();
  }
}

TEST(RigConfig, WrongVectorLengthNamesTheKey) {
  TempDir dir;
  std::string text = kRig;
  text.replace(text.find("[0.5, 0, 0.8]"), 13, "[0.5, 0.8]");
  ExpectConfigError(dir.Write("rig.yaml", text), text, 7, 19, "lights.leds[1].direction", "expected a list of 3 numbers");
}

// Simulated lights take the safety limits (a simulated backlight rated for
// continuous light) and nothing else.
TEST(RigConfig, SimulatedLightsTakeSafetyLimitsOnly) {
  TempDir dir;
  std::string text = kRig;
  text.replace(text.find("  driver: sim\n  leds:"), 14, "  driver: sim\n  options: {safety: {max_duty: 1.0, max_on_ms: 0}}\n");
  const config::RigConfig rig = config::LoadRigConfig(dir.Write("rig.yaml", text));
  EXPECT_DOUBLE_EQ(rig.lights.safety.defaults.max_duty, 1.0);
  EXPECT_DOUBLE_EQ(rig.lights.safety.defaults.max_on_ms, 0.0);
  EXPECT_DOUBLE_EQ(config::LoadRigConfig(dir.Write("plain.yaml", kRig)).lights.safety.defaults.max_duty, 0.5);

  std::string serial = kRig;
  serial.replace(serial.find("  driver: sim\n  leds:"), 14, "  driver: sim\n  options: {serial: A1}\n");
  ExpectConfigError(dir.Write("serial.yaml", serial), serial, 5, 13, "lights.options.serial", "unknown key 'serial'");
}

TEST(RigConfig, UnknownKeyIsReportedWhereItIs) {
  TempDir dir;
  std::string text = kRig;
  text.replace(text.find("  height: 24"), 12, "  heigth: 24");
  ExpectConfigError(dir.Write("rig.yaml", text), text, 12, 3, "camera.heigth", "unknown key 'heigth'");
}

TEST(RigConfig, AKeyThatIsNotANameIsAConfigErrorWhereItIs) {
  TempDir dir;
  // YAML allows a list, a map or nothing as a key; yaml-cpp's bad conversion used to escape the loader.
  const std::string rig = kRig;
  const int line = static_cast<int>(std::count(rig.begin(), rig.end(), '\n')) + 1;
  for (const std::string key : {"? [a, b]\n: 1\n", "? {d: 1}\n: 1\n", "? \n: 1\n"}) {
    const std::string text = rig + key;
    const bool empty = key == "? \n: 1\n";  // an empty key has no text of its own: the parser marks the line after
    ExpectConfigError(dir.Write("rig.yaml", text), text, empty ? line + 1 : line, empty ? 1 : 3, "",
                      "expected a name as a key");
  }
}

// yaml-cpp keeps both of a repeated key and answers with the first: the
// second, often the later edit, was ignored without a word.
TEST(RigConfig, AKeyGivenTwiceInOneMapIsAnErrorAtTheSecond) {
  TempDir dir;
  ExpectEditedRigError(dir, "a.yaml", "  height: 24\n", "  height: 24\n  width: 64\n", 13, 3, "camera",
                       "key 'width' is given twice in one map (first on line 11)");
  ExpectEditedRigError(dir, "b.yaml", "intensity: 0.9}", "intensity: 0.9, direction: [0, 0, 1]}", 7, 50,
                       "lights.leds[1]", "key 'direction' is given twice");
  // The same key in different maps, and an alias used many times, are no repeats.
  const std::string aliases = std::string(kRig) + "extra: {a: &x {k: 1}, b: *x, c: [*x, *x]}\n";
  EXPECT_NO_THROW(config::YamlNode::LoadString(aliases, "c.yaml"));
  // Nested aliases are checked as written, not as expanded (2^40 nodes here).
  std::string nested = "l0: &a0 [1, 1]\n";
  for (int i = 1; i <= 40; ++i)
    nested += "l" + std::to_string(i) + ": &a" + std::to_string(i) + " [*a" + std::to_string(i - 1) + ", *a" +
              std::to_string(i - 1) + "]\n";
  EXPECT_NO_THROW(config::YamlNode::LoadString(nested, "d.yaml"));
  photorig::testing::ExpectConfigErrorAt([&] { config::YamlNode::LoadString(nested + "l3: 0\n", "e.yaml"); }, "e.yaml",
                                         42, 1, "key 'l3' is given twice in one map (first on line 4)");
}

TEST(RigConfig, MissingKeyAndBadNumberAreExplained) {
  TempDir dir;
  ExpectEditedRigError(dir, "a.yaml", "  width: 32\n", "", 10, 3, "camera", "missing required key 'width'");
  ExpectEditedRigError(dir, "b.yaml", "intensity: 0.9", "intensity: lots", 7, 45, "lights.leds[1].intensity",
                       "expected a number, got 'lots'");
}

TEST(RigConfig, LightsBelowTheSampleAreRejected) {
  TempDir dir;
  std::string text = kRig;
  text.replace(text.find("[0, 0, 1]"), 9, "[0, 1, -0.2]");
  ExpectConfigError(dir.Write("rig.yaml", text), text, 6, 19, "lights.leds[0].direction", "below the sample plane");
}

TEST(Recipe, ShippedRecipeCompilesToOneDarkAndOneFramePerLed) {
  const std::string path = SourceDir() + "/config/recipes/ps-sphere.yaml";
  const config::RigConfig rig = config::LoadRigConfig(config::RecipeRigPath(path, ""));
  const config::Recipe recipe = config::LoadRecipe(path, rig);
  const auto steps = config::CompileSteps(recipe, rig);
  ASSERT_EQ(steps.size(), rig.lights.leds.size() + 1);
  EXPECT_EQ(steps[0].kind, config::CaptureStep::Kind::kDark);
  EXPECT_TRUE(steps[0].pattern->IsDark());
  for (std::size_t i = 1; i < steps.size(); ++i) {
    EXPECT_EQ(steps[i].led, static_cast<int>(i - 1));
    EXPECT_EQ(steps[i].pattern->levels[i - 1], 1.0);
    EXPECT_EQ(steps[i].index, static_cast<int>(i));
  }
  ASSERT_TRUE(recipe.photometric_stereo.has_value());
  EXPECT_EQ(recipe.photometric_stereo->method, solvers::ps::Method::kLambertian);
}

TEST(Recipe, UnknownLedAndUnknownStepAreErrorsWithPositions) {
  TempDir dir;
  const std::string rig_path = dir.Write("rig.yaml", kRig);
  const std::string recipe_path = dir.Write("r.yaml", R"(recipe:
  name: r
  rig: rig.yaml
capture:
  steps:
    - each_led: {leds: [0, 7]}
)");
  ASSERT_EQ(config::RecipeRigPath(recipe_path, ""), rig_path);
  const config::RigConfig rig = config::LoadRigConfig(rig_path);
  const config::Recipe recipe = config::LoadRecipe(recipe_path, rig);
  try {
    config::CompileSteps(recipe, rig);
    FAIL();
  } catch (const config::ConfigError& e) {
    EXPECT_EQ(e.line(), 6) << e.what();
    EXPECT_NE(std::string(e.what()).find("LED id 7 is not in rig 'tiny'"), std::string::npos) << e.what();
  }
  const std::string bad = dir.Write("s.yaml", "recipe: {name: s}\ncapture:\n  steps:\n    - flash: {}\n");
  try {
    config::LoadRecipe(bad, rig);
    FAIL();
  } catch (const config::ConfigError& e) {
    EXPECT_EQ(e.line(), 4) << e.what();
    EXPECT_NE(std::string(e.what()).find("unknown step 'flash'"), std::string::npos) << e.what();
  }
}

// A recipe's sim_scene is parsed once, when the recipe is loaded for its rig:
// sizes it leaves out come from that rig's frame, and a mistake in it fails
// the load, with its position, before any device exists.
TEST(Recipe, SimSceneIsParsedAtLoadForTheRigsFrame) {
  TempDir dir;
  const config::RigConfig rig = config::LoadRigConfig(dir.Write("rig.yaml", kRig));
  auto recipe_with = [](const std::string& scene) {
    return "recipe: {name: s, rig: rig.yaml}\nsample:\n  sim_scene: " + scene +
           "\ncapture:\n  steps:\n    - dark: {count: 1}\n";
  };
  const config::Recipe recipe = config::LoadRecipe(dir.Write("r.yaml", recipe_with("{shape: sphere}")), rig);
  ASSERT_TRUE(recipe.sim_scene.has_value());
  EXPECT_DOUBLE_EQ(recipe.sim_scene->sphere_radius_mm, 0.45 * 32 * 0.1);  // the rig's 32 pixels of 0.1 mm

  const std::string typo = dir.Write("typo.yaml", recipe_with("{shape: sphere, albedo: {pattern: checker, hi: 0.9}}"));
  photorig::testing::ExpectConfigErrorAt([&] { config::LoadRecipe(typo, rig); }, typo, 3, 57, "unknown key 'hi'",
                                         "sample.sim_scene.albedo.hi");
  const std::string shape = dir.Write("shape.yaml", recipe_with("{shape: torus}"));
  photorig::testing::ExpectConfigErrorAt([&] { config::LoadRecipe(shape, rig); }, shape, 3, 22, "unknown shape 'torus'",
                                         "sample.sim_scene.shape");
}

// A measured material: the table file is read when the recipe is loaded, so
// the simulator renders exactly what the file holds; a file its reader
// refuses is a configuration error at the key, naming the file.
TEST(Recipe, SimSceneReadsAMeasuredTableAsItsMaterial) {
  TempDir dir;
  const config::RigConfig rig = config::LoadRigConfig(dir.Write("rig.yaml", kRig));
  const auto white = solvers::brdf::MerlTable::FromFunction(
      [](const solvers::brdf::DirectionPair&) { return std::optional<Eigen::Vector3d>(Eigen::Vector3d(0.1, 0.2, 0.3)); });
  ASSERT_TRUE(solvers::brdf::WriteMerl((dir.path() / "grey.binary").string(), white).IsSolutionUsable());
  const auto recipe_with = [](const std::string& table) {
    return "recipe: {name: s, rig: rig.yaml}\nsample:\n  sim_scene: {shape: sphere, brdf: {model: tabulated, table: " +
           table + "}}\ncapture:\n  steps:\n    - dark: {count: 1}\n";
  };
  const config::Recipe recipe = config::LoadRecipe(dir.Write("r.yaml", recipe_with("grey.binary")), rig);
  ASSERT_TRUE(recipe.sim_scene.has_value());
  const Eigen::Vector3d n = Eigen::Vector3d::UnitZ(), wi = Eigen::Vector3d(0.3, 0.1, 0.9).normalized(),
                        wo = Eigen::Vector3d(-0.2, 0.4, 0.8).normalized();
  EXPECT_NEAR(recipe.sim_scene->material.MakeBrdf()->Eval(n, wi, wo, {}), 0.2, 1e-9);  // the channels' mean
  EXPECT_NEAR(recipe.sim_scene->material.MakeBrdf(2)->Eval(n, wi, wo, {}), 0.3, 1e-9);

  std::filesystem::resize_file(dir.path() / "grey.binary", 1000);
  const std::string truncated = dir.Write("short.yaml", recipe_with("grey.binary"));
  photorig::testing::ExpectConfigErrorAt([&] { config::LoadRecipe(truncated, rig); }, truncated, 3, 62, "grey.binary",
                                         "sample.sim_scene.brdf.table");
  const std::string missing = dir.Write("missing.yaml", "recipe: {name: s, rig: rig.yaml}\nsample:\n  sim_scene: "
                                                        "{shape: sphere, brdf: {model: tabulated}}\ncapture:\n"
                                                        "  steps:\n    - dark: {count: 1}\n");
  photorig::testing::ExpectConfigErrorAt([&] { config::LoadRecipe(missing, rig); }, missing, 3, 36, "needs a table",
                                         "sample.sim_scene.brdf");
}

// A gonioreflectometer sample for a colour camera: albedo and rho_s per
// camera channel (a grey camera sees their mean), and Cook-Torrance as the
// fit defines it; a list where it cannot apply is an error at its position.
TEST(Recipe, SimSceneTakesParametersPerChannel) {
  TempDir dir;
  const config::RigConfig rig = config::LoadRigConfig(dir.Write("rig.yaml", kRig));
  const auto line_with = [](const std::string& scene) { return "  sim_scene: " + scene; };
  const auto recipe_with = [&](const std::string& scene) {
    return "recipe: {name: s, rig: rig.yaml}\nsample:\n" + line_with(scene) + "\ncapture:\n  steps:\n    - dark: {count: 1}\n";
  };
  const config::Recipe recipe = config::LoadRecipe(
      dir.Write("r.yaml", recipe_with("{shape: sample_plane, albedo: {pattern: uniform, high: [0.1, 0.2, 0.3]}, brdf: "
                                      "{model: cook_torrance, rho_s: [0.05, 0.06, 0.07], roughness: 0.2, f0: 0.6}}")),
      rig);
  ASSERT_TRUE(recipe.sim_scene.has_value());
  const sim::Scene& scene = *recipe.sim_scene;
  ASSERT_TRUE(scene.albedo.high_channels.has_value());
  EXPECT_EQ(*scene.albedo.high_channels, Eigen::Vector3d(0.1, 0.2, 0.3));
  EXPECT_DOUBLE_EQ(scene.albedo.high, 0.2);
  ASSERT_TRUE(scene.material.rho_s_channels.has_value());
  EXPECT_EQ(*scene.material.rho_s_channels, Eigen::Vector3d(0.05, 0.06, 0.07));
  EXPECT_DOUBLE_EQ(scene.material.rho_s, 0.06);
  // The simulator's Cook-Torrance is the fit's (solvers/brdf/models.h), channel by channel.
  solvers::brdf::ModelParams truth;
  truth.model = solvers::brdf::Model::kCookTorrance;
  truth.diffuse = {0.1, 0.2, 0.3};
  truth.specular = {0.05, 0.06, 0.07};
  truth.shape = 0.2;
  truth.fresnel_f0 = 0.6;
  const Eigen::Vector3d n = Eigen::Vector3d::UnitZ(), wi = Eigen::Vector3d(0.3, 0.1, 0.9).normalized(),
                        wo = Eigen::Vector3d(-0.25, -0.05, 0.9).normalized();
  const Eigen::Vector3d expected = solvers::brdf::Evaluate(truth, wi, wo);
  for (int c = 0; c < 3; ++c) {
    sim::BrdfParams params;
    params.rho_d = static_cast<float>(truth.diffuse[c]);
    params.rho_s = static_cast<float>(truth.specular[c]);
    params.shininess = static_cast<float>(scene.material.LobeShape());
    params.f0 = static_cast<float>(scene.material.f0);
    EXPECT_NEAR(scene.material.MakeBrdf(c)->Eval(n, wi, wo, params), expected[c], 1e-6 * expected[c]) << c;
  }

  const std::string checker = "{shape: sample_plane, albedo: {pattern: checker, high: [0.1, 0.2, 0.3]}}";
  const std::string checker_path = dir.Write("checker.yaml", recipe_with(checker));
  photorig::testing::ExpectConfigErrorAt([&] { config::LoadRecipe(checker_path, rig); }, checker_path, 3,
                                         static_cast<int>(line_with(checker).find('[')) + 1, "needs pattern: uniform",
                                         "sample.sim_scene.albedo.high");
  const std::string two = "{shape: sample_plane, brdf: {model: cook_torrance, rho_s: [0.1, 0.2]}}";
  const std::string two_path = dir.Write("two.yaml", recipe_with(two));
  photorig::testing::ExpectConfigErrorAt([&] { config::LoadRecipe(two_path, rig); }, two_path, 3,
                                         static_cast<int>(line_with(two).find('[')) + 1, "a list of 3 numbers",
                                         "sample.sim_scene.brdf.rho_s");
  const std::string ggx = "{shape: sample_plane, brdf: {model: ggx, rho_s: [0.1, 0.2, 0.3]}}";
  const std::string ggx_path = dir.Write("ggx.yaml", recipe_with(ggx));
  photorig::testing::ExpectConfigErrorAt([&] { config::LoadRecipe(ggx_path, rig); }, ggx_path, 3,
                                         static_cast<int>(line_with(ggx).find("{model")) + 1,
                                         "rho_s per channel needs the blinn_phong or cook_torrance model",
                                         "sample.sim_scene.brdf");
}

// Where the solve stages run: the rig's `solve:` unless the recipe's own
// `solve: {executor, ..., stages}` says otherwise, key by key.
TEST(Recipe, SolveExecutorComesFromTheRigUnlessTheRecipeChoosesOne) {
  TempDir dir;
  const config::RigConfig rig = config::LoadRigConfig(dir.Write("rig.yaml", std::string(kRig) + "solve: {partition: lab, time: \"00:10:00\"}\n"));
  const std::string head = "recipe: {name: s, rig: rig.yaml}\ncapture:\n  steps:\n    - dark: {count: 1}\n";
  const config::Recipe listed = config::LoadRecipe(dir.Write("list.yaml", head + "solve:\n  - photometric_stereo: {}\n"), rig);
  EXPECT_EQ(listed.solve_executor.executor, config::Executor::kLocal);
  EXPECT_EQ(listed.solve_executor.partition, "lab");
  EXPECT_TRUE(listed.photometric_stereo.has_value());

  const config::Recipe chosen = config::LoadRecipe(
      dir.Write("map.yaml", head + "solve:\n  executor: slurm\n  time: \"01:00:00\"\n  stages:\n"
                                   "    - photometric_stereo: {method: robust}\n"),
      rig);
  EXPECT_EQ(chosen.solve_executor.executor, config::Executor::kSlurm);
  EXPECT_EQ(chosen.solve_executor.partition, "lab");  // left out: the rig's
  EXPECT_EQ(chosen.solve_executor.time, "01:00:00");
  ASSERT_TRUE(chosen.photometric_stereo.has_value());

  const std::string typo = dir.Write("typo.yaml", head + "solve:\n  executor: slurm\n  stage: []\n");
  photorig::testing::ExpectConfigErrorAt([&] { config::LoadRecipe(typo, rig); }, typo, 7, 3, "unknown key 'stage'", "solve.stage");
  const std::string bad = dir.Write("bad.yaml", head + "solve: {executor: mpi}\n");
  photorig::testing::ExpectConfigErrorAt([&] { config::LoadRecipe(bad, rig); }, bad, 5, 19, "is no executor (expected local or slurm)",
                                         "solve.executor");
}

}  // namespace
}  // namespace photorig::daemon

namespace photorig::daemon {
namespace {

std::string TriggeredRig(const std::string& trigger) {
  return std::regex_replace(photorig::testing::SmallRigYaml(), std::regex("exposure_us: 1000\\}"),
                            "exposure_us: 1000, trigger: " + trigger + "}");
}

TEST(HardwareTriggerConfig, MistakesAreNamedWhereTheyAre) {
  TempDir dir;
  ExpectConfigError(dir.Write("a.yaml", TriggeredRig("{mode: hardware}")), TriggeredRig("{mode: hardware}"), 10, 125,
                    "camera.trigger", "output");
  const std::string unknown = TriggeredRig("{mode: hardware, output: {driver: relay}}");
  ExpectConfigError(dir.Write("b.yaml", unknown), unknown, 10, 159, "camera.trigger.output.driver", "unknown trigger output");
  const std::string soft = TriggeredRig("{mode: software, output: {driver: sim}}");
  ExpectConfigError(dir.Write("c.yaml", soft), soft, 10, 150, "camera.trigger.output", "needs mode: hardware");
}

TEST(HardwareTriggerConfig, SimWireRunsAndAMissingGpioChipFailsByName) {
  TempDir dir;
  RunRequest request;
  request.rig_path = dir.Write("sim.yaml", TriggeredRig("{mode: hardware, output: {driver: sim}}"));
  request.recipe_path = dir.Write("r.yaml", photorig::testing::SmallRecipeYaml());
  request.output_directory = (dir.path() / "sim-run").string();
  request.solve = false;
  const RunOutcome wired = ExecuteRun(request);
  EXPECT_EQ(wired.capture.status, CaptureStatus::kComplete) << wired.capture.reason;
  EXPECT_EQ(wired.capture.frames_written, 5);

  request.rig_path = dir.Write("gpio.yaml", TriggeredRig("{mode: hardware, output: {driver: gpio, chip: gpiochip77, offset: 3}}"));
#if !PHOTORIG_HAVE_DRIVERS_GPIO
  // Without the module the rig does not load at all.
  EXPECT_THROW(ExecuteRun(request), config::ConfigError);
#else
  request.output_directory = (dir.path() / "gpio-run").string();
  request.retry.initial_backoff_ms = 1;
  request.retry.max_backoff_ms = 2;
  const RunOutcome missing = ExecuteRun(request);
  EXPECT_EQ(missing.capture.status, CaptureStatus::kFailed);
  EXPECT_NE(missing.capture.reason.find("gpiochip77"), std::string::npos) << missing.capture.reason;
  EXPECT_EQ(missing.capture.frames_written, 0);
#endif
}

}  // namespace
}  // namespace photorig::daemon
