// NeXus export and solves repeated from their records, through the photorig
// executable: a run of each kind (a dome with photometric stereo, a
// gonioreflectometer with its BRDF, a tomograph with its volume) is exported
// and checked by check_nexus.py (h5py: the structure NXDL asks for, the frames
// against the PNGs, each solve's outputs against its results folder; then the
// NeXus C tools' nxdir and nxsummary as an independent reader), and each
// solve is repeated with `solve --from` from its report.json and from the
// NeXus file's NXprocess, giving the same output files byte for byte.

#include "test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <regex>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using photorig::testing::Photorig;
using photorig::testing::ReadText;
using photorig::testing::SourceDir;
using photorig::testing::TempDir;

// check_nexus.py's verdict on `file` against `run`: its exit code, its findings in *output.
int CheckNexus(const fs::path& file, const fs::path& run, std::string* output) {
  const fs::path log = file.string() + ".check";
  const std::string command = "/usr/bin/python3 " + SourceDir() + "/tests/daemon/check_nexus.py " + file.string() +
                              " " + run.string() + " > " + log.string() + " 2>&1";
  const int status = std::system(command.c_str());
  *output = ReadText(log);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// Exports `run` to RUN/run.nxs and checks the file; returns the command's document.
json ExportAndCheck(const TempDir& dir, const fs::path& run, const std::vector<std::string>& processes) {
  const photorig::testing::CommandOutcome exported = Photorig("export nexus --run " + run.string() + " --json", dir);
  EXPECT_EQ(exported.exit_code, 0) << exported.err;
  const json document = json::parse(exported.out, nullptr, false);
  EXPECT_EQ(document.value("out", ""), (run / "run.nxs").string()) << exported.out;
  EXPECT_EQ(document.value("processes", json()), json(processes));
  std::string findings;
  EXPECT_EQ(CheckNexus(run / "run.nxs", run, &findings), 0) << findings;
  return document;
}

// Repeats the solve recorded at `from` into `out` and expects each of
// `files` there to equal its original in `results` byte for byte.
void ExpectSolvedAgainAlike(const TempDir& dir, const std::string& from, const fs::path& results, const fs::path& out,
                            const std::vector<std::string>& files) {
  const photorig::testing::CommandOutcome again = Photorig("solve --from " + from + " --out " + out.string() + " --json", dir);
  ASSERT_EQ(again.exit_code, 0) << again.err;
  const json document = json::parse(again.out, nullptr, false);
  EXPECT_EQ(document.value("command", ""), "solve");
  EXPECT_EQ(document.value("results_directory", ""), out.string());
  for (const std::string& file : files) {
    ASSERT_TRUE(fs::exists(results / file)) << file;
    EXPECT_TRUE(ReadText(out / file) == ReadText(results / file)) << from << ": " << file << " differs";
  }
  const json original = json::parse(ReadText(results / "report.json")), repeated = json::parse(ReadText(out / "report.json"));
  EXPECT_EQ(repeated["provenance"]["options"], original["provenance"]["options"]);
  EXPECT_EQ(repeated["provenance"]["inputs"], original["provenance"]["inputs"]);
}

// A shipped rig with its simulated motion sped up (the tests are about the files, not the moves).
std::string FastRig(const TempDir& dir, const std::string& shipped) {
  return dir.Write("rig.yaml", std::regex_replace(ReadText(SourceDir() + "/config/rigs/" + shipped),
                                                  std::regex("time_scale: [0-9.]+"), "time_scale: 1000"));
}

TEST(Nexus, ADomeRunExportsAndItsPhotometricStereoIsSolvedAgainBitForBit) {
  TempDir dir;
  const std::string rig = dir.Write("rig.yaml", photorig::testing::SmallRigYaml());
  const std::string recipe = dir.Write(
      "recipe.yaml", photorig::testing::SmallRecipeYaml(rig) +
                         "solve:\n  - photometric_stereo: {method: auto, shadow_threshold_sigma: 2.5, integrator: poisson}\n");
  const fs::path run = dir.path() / "run";
  // Written at capture time, with the solve the recipe asks for ...
  const photorig::testing::CommandOutcome captured = Photorig("run " + recipe + " --out " + run.string() + " --nexus --json", dir);
  ASSERT_EQ(captured.exit_code, 0) << captured.err;
  EXPECT_EQ(json::parse(captured.out)["nexus"]["processes"], json({"ps"}));
  std::string findings;
  EXPECT_EQ(CheckNexus(run / "run.nxs", run, &findings), 0) << findings;
  // ... and exported again later.
  const json exported = ExportAndCheck(dir, run, {"ps"});
  EXPECT_EQ(exported["frames"], 5);

  const json report = json::parse(ReadText(run / "results/ps/report.json"));
  EXPECT_EQ(report["provenance"]["options"]["request"]["shadow_threshold_sigma"], 2.5);
  EXPECT_EQ(report["provenance"]["inputs"]["frames"], 5);
  const std::vector<std::string> outputs = {"normals.tiff", "albedo.tiff", "confidence.tiff", "depth.tiff", "mesh.ply"};
  ExpectSolvedAgainAlike(dir, (run / "results/ps/report.json").string(), run / "results/ps", dir.path() / "again", outputs);
  ExpectSolvedAgainAlike(dir, (run / "run.nxs").string() + "::/entry/ps", run / "results/ps", dir.path() / "again-nx",
                         outputs);

  // Another run's frames are refused, naming what differs and what to do.
  const std::string other = dir.Write("other.yaml", photorig::testing::SmallRecipeYaml(rig, 2));
  ASSERT_EQ(Photorig("run " + other + " --out " + (dir.path() / "other").string(), dir).exit_code, 0);
  const photorig::testing::CommandOutcome refused = Photorig(
      "solve --from " + (run / "results/ps").string() + " --run " + (dir.path() / "other").string() + " --out " +
          (dir.path() / "wrong").string(),
      dir);
  EXPECT_EQ(refused.exit_code, 2);
  EXPECT_NE(refused.err.find("is not the run the result was solved from"), std::string::npos) << refused.err;
  EXPECT_NE(refused.err.find("give --run with the run it was solved from"), std::string::npos) << refused.err;
  EXPECT_FALSE(fs::exists(dir.path() / "wrong"));
}

TEST(Nexus, AFrameThatDoesNotMatchItsChecksumIsNamedAndNoFileIsLeft) {
  TempDir dir;
  const std::string rig = dir.Write("rig.yaml", photorig::testing::SmallRigYaml());
  const fs::path run = dir.path() / "run";
  ASSERT_EQ(Photorig("run " + dir.Write("r.yaml", photorig::testing::SmallRecipeYaml(rig)) + " --out " + run.string(), dir)
                .exit_code,
            0);
  fs::copy_file(run / "frames/0001_led00.png", run / "frames/0002_led01.png", fs::copy_options::overwrite_existing);
  const photorig::testing::CommandOutcome exported =
      Photorig("export nexus --run " + run.string() + " --out " + (dir.path() / "x.nxs").string(), dir);
  EXPECT_EQ(exported.exit_code, 2);
  EXPECT_NE(exported.err.find("0002_led01.png"), std::string::npos) << exported.err;
  EXPECT_FALSE(fs::exists(dir.path() / "x.nxs"));
  EXPECT_FALSE(fs::exists(dir.path() / "x.nxs.partial"));
}

TEST(Nexus, AGonioreflectometerRunExportsAndItsBrdfIsSolvedAgainIdentically) {
  TempDir dir;
  const std::string rig = FastRig(dir, "sim-gonio.yaml");
  const std::string recipe = dir.Write(
      "brdf.yaml", std::regex_replace(ReadText(SourceDir() + "/config/recipes/brdf-gonio.yaml"),
                                      std::regex("theta_d_deg: \\{min: 10, max: 60, steps: 6\\}"),
                                      "theta_d_deg: {min: 10, max: 50, steps: 3}"));
  const fs::path run = dir.path() / "run";
  ASSERT_EQ(Photorig("run " + recipe + " --rig " + rig + " --out " + run.string(), dir).exit_code, 0);
  ExportAndCheck(dir, run, {"brdf"});
  ExpectSolvedAgainAlike(dir, (run / "results/brdf").string(), run / "results/brdf", dir.path() / "again",
                         {"samples.csv"});
  ExpectSolvedAgainAlike(dir, (run / "run.nxs").string() + "::/entry/brdf", run / "results/brdf",
                         dir.path() / "again-nx", {"samples.csv"});
  const json original = json::parse(ReadText(run / "results/brdf/report.json"));
  const json repeated = json::parse(ReadText(dir.path() / "again/report.json"));
  ASSERT_TRUE(original.contains("chosen"));
  EXPECT_EQ(repeated["chosen"], original["chosen"]);
  // Every model's parameters, to the last bit; only the fits' wall-clock timings differ.
  auto without_timings = [](json candidates) {
    for (json& candidate : candidates) candidate.erase("timings_ms");
    return candidates;
  };
  EXPECT_EQ(without_timings(repeated["candidates"]), without_timings(original["candidates"]));
}

TEST(Nexus, ATomographyRunExportsAndItsVolumeIsSolvedAgainBitForBit) {
  TempDir dir;
  const std::string rig = FastRig(dir, "sim-tomography.yaml");
  // The shipped scan with half its views (33 over 0..180 deg, both ends included).
  std::string recipe = ReadText(SourceDir() + "/config/recipes/tomography.yaml");
  recipe = std::regex_replace(recipe, std::regex("count: 64"), "count: 33");
  recipe = std::regex_replace(recipe, std::regex("step: 2.8125"), "step: 5.625");
  recipe += "export: {nexus: true}\n";  // the file at capture time, asked for by the recipe
  const fs::path run = dir.path() / "run";
  ASSERT_EQ(Photorig("run " + dir.Write("tomo.yaml", recipe) + " --rig " + rig + " --out " + run.string(), dir).exit_code,
            0);
  std::string findings;
  EXPECT_EQ(CheckNexus(run / "run.nxs", run, &findings), 0) << findings;
  ExportAndCheck(dir, run, {"tomography"});
  ExpectSolvedAgainAlike(dir, (run / "results/tomography/report.json").string(), run / "results/tomography",
                         dir.path() / "again", {"volume.nrrd", "geometry.json"});
  ExpectSolvedAgainAlike(dir, (run / "run.nxs").string() + "::/entry/tomography", run / "results/tomography",
                         dir.path() / "again-nx", {"volume.nrrd"});
}

}  // namespace
