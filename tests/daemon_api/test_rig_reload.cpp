// The daemon's rig is loaded again when its file (or the colour model it
// names) changes, and only then: an edit takes effect at the next dry-run or
// submit, and an untouched file is not parsed for every request.

#include "photorig/daemon/service/service.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <regex>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
using photorig::testing::ReadText;
using photorig::testing::SmallRecipeYaml;
using photorig::testing::SmallRigYaml;
using photorig::testing::TempDir;

// SmallRigYaml under another rig name.
std::string RigNamed(const std::string& name, std::string rig = SmallRigYaml()) {
  return std::regex_replace(rig, std::regex("rig: \\{name: small-dome\\}"), "rig: {name: " + name + "}");
}

// Writes `text` over `path` and gives it the modification time `modified`.
void Rewrite(const fs::path& path, const std::string& text, fs::file_time_type modified) {
  std::ofstream(path, std::ios::trunc) << text;
  fs::last_write_time(path, modified);
}

class RigReload : public ::testing::Test {
 protected:
  void SetUp() override {
    options_.data_root = (dir_.path() / "data").string();
    options_.rig_path = dir_.Write("rig.yaml", SmallRigYaml());
    options_.solve = false;
  }
  // The rig name a dry-run of the small recipe answers with, or its error.
  std::string DryRunRig(const RunService& service) const {
    const ServiceReply reply = service.DryRun("small.yaml", SmallRecipeYaml());
    return reply.http_status == 200 ? reply.body.value("rig", "") : "error " + std::to_string(reply.http_status);
  }

  TempDir dir_;
  ServiceOptions options_;
};

TEST_F(RigReload, AnUntouchedRigFileIsNotReadAgain) {
  RunService service(options_);
  ASSERT_EQ(DryRunRig(service), "small-dome");
  // Other text of the same size and modification time: a file read again would name the rig small-dume.
  const fs::file_time_type modified = fs::last_write_time(options_.rig_path);
  const std::string same_size = RigNamed("small-dume");
  ASSERT_EQ(same_size.size(), SmallRigYaml().size());
  Rewrite(options_.rig_path, same_size, modified);
  EXPECT_EQ(DryRunRig(service), "small-dome");
  EXPECT_EQ(service.Submit("small.yaml", SmallRecipeYaml()).http_status, 201);
}

TEST_F(RigReload, AnEditedRigFileTakesEffectAtTheNextDryRunAndSubmit) {
  RunService service(options_);
  ASSERT_EQ(DryRunRig(service), "small-dome");
  const fs::file_time_type modified = fs::last_write_time(options_.rig_path);

  // Same size, a later modification time.
  Rewrite(options_.rig_path, RigNamed("small-dume"), modified + std::chrono::seconds(1));
  EXPECT_EQ(DryRunRig(service), "small-dume");
  // Same modification time, another size.
  Rewrite(options_.rig_path, RigNamed("small-dome-2"), modified + std::chrono::seconds(1));
  EXPECT_EQ(DryRunRig(service), "small-dome-2");

  // A broken rig is reported at the next submit, and not kept: fixed, it loads again.
  Rewrite(options_.rig_path, "rig: {name: [\n", modified + std::chrono::seconds(2));
  const ServiceReply refused = service.Submit("small.yaml", SmallRecipeYaml());
  EXPECT_EQ(refused.http_status, 400);
  EXPECT_NE(refused.body.value("file", "").find("rig.yaml"), std::string::npos) << refused.body.dump();
  Rewrite(options_.rig_path, RigNamed("small-dome-3"), modified + std::chrono::seconds(3));
  EXPECT_EQ(service.Submit("small.yaml", SmallRecipeYaml()).http_status, 201);
  EXPECT_EQ(DryRunRig(service), "small-dome-3");
}

TEST_F(RigReload, AnEditedColourModelTakesEffectAtTheNextDryRun) {
  const fs::path model = dir_.Write(
      "model.yaml", ReadText(photorig::testing::SourceDir() + "/config/color/sim-dome-colour-nikon-5100-d65.yaml"));
  const std::string colour_rig = std::regex_replace(
      SmallRigYaml(), std::regex("exposure_us: 1000\\}"), "exposure_us: 1000, pixel_format: BayerRG12, color_model: model.yaml}");
  options_.rig_path = dir_.Write("rig.yaml", colour_rig);
  RunService service(options_);
  ASSERT_EQ(DryRunRig(service), "small-dome");
  // The rig file untouched, its colour model no longer one.
  Rewrite(model, "not a colour model\n", fs::last_write_time(model) + std::chrono::seconds(1));
  EXPECT_EQ(DryRunRig(service), "error 400");
}

}  // namespace
}  // namespace photorig::daemon
