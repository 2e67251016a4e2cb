// Bounds on what configuration may ask for: a recipe's expansion is limited
// while it is compiled, and every value a rig or recipe gives is range-checked
// at load with its position.

#include "photorig/config/recipe.h"
#include "photorig/config/rig.h"
#include "config_error_check.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <string>

namespace photorig::config {
namespace {

using photorig::testing::ExpectConfigErrorAt;
using photorig::testing::SmallRigYaml;
using photorig::testing::TempDir;

class Limits : public ::testing::Test {
 protected:
  void SetUp() override { rig_ = LoadRigConfig(dir_.Write("rig.yaml", SmallRigYaml())); }

  TempDir dir_;
  RigConfig rig_;
};

// Four lines that multiply to four million steps through one YAML anchor.
const char kAliasRecipe[] =
    "recipe: {name: amp}\n"
    "capture:\n"
    "  steps:\n"
    "    - &g {dark: {count: 1000, repeat: 1000}}\n"
    "    - *g\n"
    "    - *g\n"
    "    - *g\n";

TEST_F(Limits, AnAliasedRecipeIsRefusedWhileItExpands) {
  const Recipe recipe = LoadRecipeText(kAliasRecipe, "amp.yaml", rig_);
  try {
    CompileSteps(recipe, rig_);
    ADD_FAILURE() << "four million steps compiled";
  } catch (const CaptureLimitError& e) {
    // The first group alone is a million frames: it is the one named.
    EXPECT_EQ(e.file(), "amp.yaml");
    EXPECT_EQ(e.line(), 4) << e.what();
    EXPECT_NE(std::string(e.what()).find("take more than 100000 frames (1000000 with this group)"), std::string::npos)
        << e.what();
  }
}

TEST_F(Limits, EachLimitIsCheckedAndTheDefaultsAdmitALargeCapture) {
  const Recipe recipe = LoadRecipeText(
      "recipe: {name: big}\ncapture:\n  exposure_us: 1000\n  steps:\n    - dark: {count: 1000, repeat: 50}\n", "big.yaml",
      rig_);
  EXPECT_EQ(CompileSteps(recipe, rig_).size(), 50000u);

  CaptureLimits frames;
  frames.max_frames = 49999;
  EXPECT_THROW(CompileSteps(recipe, rig_, frames), CaptureLimitError);
  CaptureLimits bytes;
  bytes.max_bytes = 50000ull * (2 * 32 * 32 + 4096) - 1;
  EXPECT_THROW(CompileSteps(recipe, rig_, bytes), CaptureLimitError);
  CaptureLimits duration;
  duration.max_duration_s = 50000 * 0.041 - 1;  // 1 ms exposure and 40 ms overhead per frame
  EXPECT_THROW(CompileSteps(recipe, rig_, duration), CaptureLimitError);
  duration.max_duration_s = 50000 * 0.041 + 1;
  EXPECT_EQ(CompileSteps(recipe, rig_, duration).size(), 50000u);

  CaptureLimits invalid;
  invalid.max_frames = 0;
  std::string why;
  EXPECT_FALSE(invalid.IsValid(&why));
  EXPECT_THROW(CompileSteps(recipe, rig_, invalid), ConfigError);
}

TEST_F(Limits, ALongLedListIsStoppedBeforeItsRepetitions) {
  // One repetition of an each_led group can itself be long: ids may repeat.
  std::string leds;
  for (int i = 0; i < 2000; ++i) leds += i ? ", 0" : "0";
  const Recipe recipe = LoadRecipeText("recipe: {name: many}\ncapture:\n  steps:\n    - each_led: {leds: [" + leds +
                                           "], exposures_us: [1000, 2000, 4000, 8000], repeat: 100}\n",
                                       "many.yaml", rig_);
  CaptureLimits limits;
  limits.max_frames = 5000;
  EXPECT_THROW(CompileSteps(recipe, rig_, limits), CaptureLimitError);
}

TEST_F(Limits, APoseGridIsRefusedFromItsDimensions) {
  // 1000 x 1000 x 1000 poses: built first, this would take 24 GB.
  std::string angles = "[";
  for (int i = 0; i < 1000; ++i) angles += (i ? ", " : "") + std::to_string(i % 90);
  angles += "]";
  const std::string text = "recipe: {name: grid}\ncapture:\n  steps:\n    - poses:\n        grid: {light_arm_deg: " +
                           angles + ", camera_arm_deg: " + angles + ", sample_rotation_deg: " + angles + "}\n";
  ExpectConfigErrorAt([&] { LoadRecipeText(text, "grid.yaml", rig_); }, "grid.yaml", 5, 15,
                      "expands to 1000 x 1000 x 1000 poses, more than 100000", "capture.steps[0].poses.grid");
}

TEST_F(Limits, RecipeValuesOutOfRangeNameTheirPosition) {
  auto recipe = [](const std::string& capture) {
    return "recipe: {name: r}\ncapture:\n" + capture + "  steps:\n    - dark: {count: 1}\n";
  };
  ExpectConfigErrorAt([&] { LoadRecipeText(recipe("  exposure_us: 1e300\n"), "r.yaml", rig_); }, "r.yaml", 3, 16,
                      "must lie in [1, 1e+08]", "capture.exposure_us");
  ExpectConfigErrorAt([&] { LoadRecipeText(recipe("  exposure_us: 1e-300\n"), "r.yaml", rig_); }, "r.yaml", 3, 16,
                      "must lie in [1, 1e+08]", "capture.exposure_us");
  ExpectConfigErrorAt([&] { LoadRecipeText(recipe("  gain_db: -1e308\n"), "r.yaml", rig_); }, "r.yaml", 3, 12,
                      "must lie in [-40, 60]", "capture.gain_db");
  ExpectConfigErrorAt(
      [&] {
        LoadRecipeText("recipe: {name: r}\ncapture:\n  steps:\n    - flat: {exposure_us: 1e300}\n", "r.yaml", rig_);
      },
      "r.yaml", 4, 27, "must lie in [1, 1e+08]", "capture.steps[0].flat.exposure_us");
}

TEST_F(Limits, RecipeTextThatIsNotUtf8IsRefusedAtItsByte) {
  ExpectConfigErrorAt([&] { LoadRecipeText("recipe: {name: a\xff}\ncapture: {steps: [dark: {}]}\n", "r.yaml", rig_); },
                      "r.yaml", 1, 17, "not UTF-8");
  EXPECT_TRUE(IsValidUtf8("plain, \xc3\xa9t\xc3\xa9, \xe2\x82\xac, \xf0\x9f\x93\xb7"));
  std::size_t bad = 0;
  EXPECT_FALSE(IsValidUtf8("ab\xc0\xaf", &bad));  // overlong '/'
  EXPECT_EQ(bad, 2u);
  EXPECT_FALSE(IsValidUtf8("\xed\xa0\x80"));  // a surrogate
  EXPECT_FALSE(IsValidUtf8("\xe2\x82"));      // cut short
}

// A rig whose camera and first LED take the given extra keys.
std::string RigWith(const std::string& camera_extra, const std::string& led_extra, const std::string& sensor = "") {
  return "rig: {name: r}\n"
         "lights:\n  driver: sim\n  leds:\n    - {direction: [0, 0, 1]" + led_extra + "}\n"
         "camera:\n  driver: sim\n  width: 40\n  height: 30\n" + camera_extra +
         "sim:\n  seed: 1\n" + sensor;
}

TEST(RigValues, OutOfRangeValuesNameTheirPosition) {
  TempDir dir;
  auto expect = [&](const std::string& text, int line, int column, const std::string& key, const std::string& what) {
    const std::string path = dir.Write("rig.yaml", text);
    SCOPED_TRACE(text);
    ExpectConfigErrorAt([&] { LoadRigConfig(path); }, path, line, column, what, key);
  };
  expect(RigWith("  exposure_us: 1e300\n", ""), 10, 16, "camera.exposure_us", "must lie in [1, 1e+08]");
  expect(RigWith("  exposure_us: 1e-300\n", ""), 10, 16, "camera.exposure_us", "must lie in [1, 1e+08]");
  expect(RigWith("  gain_db: 1e308\n", ""), 10, 12, "camera.gain_db", "must lie in [-40, 60]");
  expect(RigWith("  gain_db: -1e308\n", ""), 10, 12, "camera.gain_db", "must lie in [-40, 60]");
  expect(RigWith("", ", intensity: 1e308"), 5, 41, "lights.leds[0].intensity", "must lie in (0, 1000]");
  expect(RigWith("", ", rgb_intensity: [1, 1e308, 1]"), 5, 45, "lights.leds[0].rgb_intensity", "in [0, 1000]");
  expect(RigWith("", "", "  sensor: {full_well_e: 1e300}\n"), 12, 25, "sim.sensor.full_well_e", "must lie in [1, 1e+09]");
}

TEST(RigValues, TimeScaleIsBounded) {
  TempDir dir;
  const std::string gonio = photorig::testing::ReadText(photorig::testing::SourceDir() + "/config/rigs/sim-gonio.yaml");
  ASSERT_NE(gonio.find("time_scale: 10 "), std::string::npos);
  for (const char* bad : {"time_scale: 0 ", "time_scale: 1e-300 ", "time_scale: 1e300 "}) {
    std::string text = gonio;
    text.replace(text.find("time_scale: 10 "), 15, bad);
    const std::string path = dir.Write("gonio.yaml", text);
    try {
      LoadRigConfig(path);
      ADD_FAILURE() << bad << " accepted";
    } catch (const ConfigError& e) {
      EXPECT_EQ(e.key(), "motion.time_scale") << e.what();
      EXPECT_GT(e.line(), 0);
    }
  }
}

TEST(RigValues, ARigPathThatIsADirectorySaysSo) {
  TempDir dir;
  try {
    LoadRigConfig(dir.path().string());
    ADD_FAILURE() << "a directory loaded as a rig";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.file(), dir.path().string());
    EXPECT_NE(std::string(e.what()).find("is a directory, not a file"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace photorig::config
