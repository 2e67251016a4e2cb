// The photorig executable as a script sees it: every command's --json output
// is one document with the common fields, exit codes follow docs/cli.md, and
// the errors people meet most say what to do next.

#include "test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <thread>
#include <vector>

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using photorig::testing::Daemon;
using photorig::testing::ReadText;
using photorig::testing::SmallRigYaml;
using photorig::testing::SourceDir;
using photorig::testing::TempDir;
using Outcome = photorig::testing::CommandOutcome;
using photorig::testing::Photorig;

// The one JSON document a --json command printed, checked for the common
// fields against the exit code; null (and a test failure) when it is not one.
json Document(const Outcome& outcome, const std::string& command) {
  const json document = json::parse(outcome.out, nullptr, false);
  EXPECT_TRUE(document.is_object()) << "stdout: " << outcome.out << "\nstderr: " << outcome.err;
  if (!document.is_object()) return nullptr;
  EXPECT_EQ(document.value("command", ""), command);
  EXPECT_EQ(document.value("exit_code", -1), outcome.exit_code);
  EXPECT_EQ(document.value("ok", outcome.exit_code != 0), outcome.exit_code == 0);
  EXPECT_EQ(document.contains("error"), outcome.exit_code != 0) << outcome.out;
  if (document.contains("error")) {
    EXPECT_FALSE(document["error"].get<std::string>().empty());
  }
  return document;
}

// A small rig (4 LEDs, 32x32) with a recipe that captures and solves.
struct SmallRun {
  explicit SmallRun(const TempDir& dir)
      : rig(dir.Write("rig.yaml", SmallRigYaml())),
        recipe(dir.Write("recipe.yaml", photorig::testing::SmallRecipeYaml(rig) +
                                            "solve:\n  - photometric_stereo: {method: lambertian, integrator: none}\n")),
        run((dir.path() / "run").string()) {}
  std::string rig, recipe, run;
};

// An address nothing listens on: a port the kernel gave out, then closed.
std::string ClosedUrl() {
  static const std::string url = [] {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t length = sizeof(address);
    ::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address));
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length);
    ::close(fd);
    return "http://127.0.0.1:" + std::to_string(ntohs(address.sin_port));
  }();
  return url;
}

TEST(Cli, RunAndSolveReportTheirResultsAsJson) {
  TempDir dir;
  const SmallRun small(dir);
  const Outcome run = Photorig("run " + small.recipe + " --out " + small.run + " --json", dir);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json captured = Document(run, "run");
  EXPECT_EQ(captured["run_directory"], small.run);
  EXPECT_EQ(captured["capture"]["status"], "complete");
  EXPECT_EQ(captured["capture"]["frames_written"], 5);
  EXPECT_EQ(captured["photometric_stereo"]["termination"], "success");
  // Human text and the capture's progress go to stderr under --json... but
  // progress is silent there: the text is what remains.
  EXPECT_NE(run.err.find("capture: complete, 5/5 frames"), std::string::npos) << run.err;
  EXPECT_EQ(run.err.find("captured 5/5"), std::string::npos) << run.err;

  // Without --json the capture's progress shows on stderr, and stdout has the text.
  const Outcome text = Photorig("run " + small.recipe + " --out " + small.run + "-text --no-solve", dir);
  ASSERT_EQ(text.exit_code, 0) << text.err;
  EXPECT_NE(text.err.find("captured 5/5 (100%)"), std::string::npos) << text.err;
  EXPECT_NE(text.out.find("capture: complete"), std::string::npos) << text.out;

  const Outcome solve = Photorig("solve ps --run " + small.run + " --method auto --json", dir);
  ASSERT_EQ(solve.exit_code, 0) << solve.err;
  const json solved = Document(solve, "solve ps");
  EXPECT_EQ(solved["method"], "auto");
  EXPECT_EQ(solved["termination"], "success");
  EXPECT_EQ(solved["results_directory"], small.run + "/results/ps");
  EXPECT_GT(solved["pixels"]["solved"].get<int>(), 100);

  // The solver's progress, counted in pixels of the 32x32 image.
  const Outcome shown = Photorig("solve ps --run " + small.run + " --method auto", dir);
  ASSERT_EQ(shown.exit_code, 0) << shown.err;
  EXPECT_NE(shown.err.find("auto 1024/1024 (100%)"), std::string::npos) << shown.err;

  const Outcome exported =
      Photorig("export diligent --run " + small.run + " --out " + (dir.path() / "diligent").string() + " --json", dir);
  ASSERT_EQ(exported.exit_code, 0) << exported.err;
  EXPECT_EQ(Document(exported, "export diligent")["out"], (dir.path() / "diligent").string());

  const Outcome relit = Photorig("relight --run " + small.run + " --light 0,0,1 --out " +
                                     (dir.path() / "relit.tiff").string() + " --json",
                                 dir);
  ASSERT_EQ(relit.exit_code, 0) << relit.err;
  EXPECT_EQ(Document(relit, "relight")["width"], 32);

  // Lights located from the matte sphere's brightest points: four found;
  // a circle smaller than the sphere leaves every light unusable, a failed solve.
  const Outcome lights = Photorig("calibrate lights --run " + small.run + " --out " + (dir.path() / "lc").string() +
                                      " --json",
                                  dir);
  ASSERT_EQ(lights.exit_code, 0) << lights.err;
  const json calibrated = Document(lights, "calibrate lights");
  EXPECT_EQ(calibrated["lights"], 4);
  EXPECT_EQ(calibrated["sphere"]["source"], "highlights");
  const Outcome misplaced = Photorig("calibrate lights --run " + small.run + " --circle 16,16,12 --out " +
                                         (dir.path() / "lc2").string() + " --json",
                                     dir);
  EXPECT_EQ(misplaced.exit_code, 1) << misplaced.err;
  EXPECT_EQ(Document(misplaced, "calibrate lights")["unusable"], 4);

  const Outcome envmap = Photorig("envmap --ball " + small.run + "/frames/0001_led00.png --circle 16 16 12 --width 64 --out " +
                                      (dir.path() / "map.hdr").string() + " --json",
                                  dir);
  ASSERT_EQ(envmap.exit_code, 0) << envmap.err;
  const json map = Document(envmap, "envmap");
  EXPECT_EQ(map["width"], 64);
  EXPECT_GT(map["directions_seen_fraction"].get<double>(), 0.5);
}

TEST(Cli, ValidateAndDryRunDescribeTheRecipe) {
  TempDir dir;
  const SmallRun small(dir);
  const Outcome valid = Photorig("validate " + small.recipe + " --json", dir);
  ASSERT_EQ(valid.exit_code, 0) << valid.err;
  const json validated = Document(valid, "validate");
  EXPECT_EQ(validated["steps"], 5);
  EXPECT_EQ(validated["leds"], 4);
  EXPECT_EQ(validated["rig_name"], "small-dome");

  const Outcome dry = Photorig("dry-run " + small.recipe + " --json --out " + dir.path().string(), dir);
  ASSERT_EQ(dry.exit_code, 0) << dry.err;
  const json plan = Document(dry, "dry-run");
  EXPECT_EQ(plan["frames"], 5);
  EXPECT_GT(plan["free_bytes"].get<double>(), 0.0);

  const Outcome devices = Photorig("devices --no-details --json", dir);
  ASSERT_EQ(devices.exit_code, 0) << devices.err;
  EXPECT_TRUE(Document(devices, "devices")["cameras"].is_array());
}

TEST(Cli, UsageErrorsExitTwoInEveryCommand) {
  TempDir dir;
  const SmallRun small(dir);
  for (const std::string& arguments : std::vector<std::string>{
           "run", "solve ps --run " + small.run + " --method magic", "solve ps", "validate --no-such-flag x",
        "calibrate lights --circle 1,2", "relight --run " + dir.path().string() + " --out x.tiff",
        "envmap --ball nothing.png --circle 1 2 3 --out m.hdr", "apply-color --in nothing.png --out x",
        "calibrate color --out x", "dry-run", "export diligent --out x", "submit", "watch", "pause", "status a b"}) {
    const Outcome outcome = Photorig(arguments + " --json", dir);
    EXPECT_EQ(outcome.exit_code, 2) << arguments << "\n" << outcome.err;
    const json document = json::parse(outcome.out, nullptr, false);
    ASSERT_TRUE(document.is_object()) << arguments << ": " << outcome.out;
    EXPECT_FALSE(document["ok"].get<bool>()) << arguments;
    EXPECT_EQ(document["exit_code"], 2) << arguments;
    EXPECT_FALSE(document.value("error", "").empty()) << arguments;
  }
  // Without --json too, not CLI11's own codes.
  EXPECT_EQ(Photorig("solve ps --no-such-flag", dir).exit_code, 2);
  EXPECT_EQ(Photorig("no-such-command", dir).exit_code, 2);
}

TEST(Cli, ChoiceFlagsOfferTheSolversOwnNamesAndRefuseOthers) {
  TempDir dir;
  // Help lists each choice flag's names and default from the solver's name table.
  const Outcome ps = Photorig("solve ps --help", dir);
  EXPECT_NE((ps.out + ps.err).find("l2 | lambertian | robust | blinn-phong | auto | low-frequency (default auto)"),
            std::string::npos)
      << ps.out;
  EXPECT_NE((ps.out + ps.err).find("lanes | forward | reverse | symbolic | central-difference (default lanes)"),
            std::string::npos);
  const Outcome tomography = Photorig("solve tomography --help", dir);
  EXPECT_NE((tomography.out + tomography.err).find("sirt | art | cgls | sart (default sirt)"), std::string::npos)
      << tomography.out;
  // A name outside the table is a usage error that names it.
  for (const std::string& arguments :
       {std::string("solve ps --dataset ") + dir.path().string() + " --method phong",
        "solve tomography --projections " + dir.path().string() + " --projector cubic",
        std::string("calibrate color --sim-camera nikon-5100 --illuminant D60 --out x")}) {
    const Outcome outcome = Photorig(arguments + " --json", dir);
    EXPECT_EQ(outcome.exit_code, 2) << arguments << "\n" << outcome.err;
    const json document = json::parse(outcome.out, nullptr, false);
    ASSERT_TRUE(document.is_object()) << arguments << ": " << outcome.out;
    const std::string error = document.value("error", "");
    for (const char* name : {"phong", "cubic", "D60"}) {
      if (arguments.find(name) == std::string::npos) continue;
      EXPECT_NE(error.find(name), std::string::npos) << error;
    }
  }
}

TEST(Cli, MissingRigFileNamesTheRecipeLineAndWherePathsResolveFrom) {
  TempDir dir;
  const std::string recipe = dir.Write("recipes/lost.yaml", photorig::testing::SmallRecipeYaml("../rigs/gone.yaml"));
  for (const char* command : {"validate", "run", "dry-run"}) {
    const Outcome outcome = Photorig(std::string(command) + " " + recipe + " --json", dir);
    EXPECT_EQ(outcome.exit_code, 2) << command;
    const json document = Document(outcome, command);
    const std::string error = document.value("error", "");
    EXPECT_NE(error.find(recipe + ":3:"), std::string::npos) << error;
    EXPECT_NE(error.find("recipe.rig: rig file " + (dir.path() / "rigs/gone.yaml").string() + " not found"),
              std::string::npos)
        << error;
    EXPECT_NE(error.find("resolves from the recipe's folder, " + (dir.path() / "recipes").string()), std::string::npos)
        << error;
  }
}

TEST(Cli, RelightWithoutAPhotometricStereoResultSaysToSolveFirst) {
  TempDir dir;
  const SmallRun small(dir);
  ASSERT_EQ(Photorig("run " + small.recipe + " --out " + small.run + " --no-solve", dir).exit_code, 0);
  const Outcome outcome =
      Photorig("relight --run " + small.run + " --light 0,0,1 --out " + (dir.path() / "r.tiff").string(), dir);
  EXPECT_EQ(outcome.exit_code, 2);
  EXPECT_NE(outcome.err.find("run `photorig solve ps --run " + small.run + "` first"), std::string::npos) << outcome.err;
  EXPECT_EQ(outcome.err.find("OpenCV"), std::string::npos) << outcome.err;
}

TEST(Cli, ColourCalibrationOfARawChartWithoutBayerAsksForIt) {
  TempDir dir;
  const std::string rendered = (dir.path() / "rendered").string();
  const Outcome render =
      Photorig("calibrate color --sim-camera nikon-5100 --bayer RGGB --models linear --out " + rendered + " --json", dir);
  ASSERT_EQ(render.exit_code, 0) << render.err;
  const json calibrated = Document(render, "calibrate color");
  EXPECT_EQ(calibrated["model"], rendered + "/model.json");
  EXPECT_TRUE(calibrated["report"].is_object());

  const std::string chart = rendered + "/chart.png", dark = rendered + "/dark.png";
  const Outcome raw = Photorig("calibrate color --image " + chart + " --dark " + dark + " --models linear --out " +
                                   (dir.path() / "raw").string() + " --json",
                               dir);
  EXPECT_EQ(raw.exit_code, 2);
  const std::string error = Document(raw, "calibrate color").value("error", "");
  EXPECT_NE(error.find(chart + " looks like a raw Bayer mosaic"), std::string::npos) << error;
  EXPECT_NE(error.find("pass --bayer"), std::string::npos) << error;

  const Outcome demosaiced = Photorig("calibrate color --image " + chart + " --dark " + dark + " --bayer RGGB " +
                                          "--models linear --out " + (dir.path() / "ok").string(),
                                      dir);
  EXPECT_EQ(demosaiced.exit_code, 0) << demosaiced.err;
  // One candidate: the fit on all 24 patches and one per left-out patch.
  EXPECT_NE(demosaiced.err.find("colour fits 25/25 (100%)"), std::string::npos) << demosaiced.err;

  const Outcome applied = Photorig("apply-color --model " + rendered + "/model.json --in " + chart + " --dark " + dark +
                                       " --bayer RGGB --out " + (dir.path() / "applied").string() + " --json",
                                   dir);
  ASSERT_EQ(applied.exit_code, 0) << applied.err;
  EXPECT_EQ(Document(applied, "apply-color")["outputs"].size(), 1u);

  // An input that cannot be read is named and skipped; the good one after it
  // is still converted, and the command fails naming what it skipped.
  const std::string torn = dir.Write("torn.png", "not an image");
  const std::string mixed_out = (dir.path() / "mixed").string();
  const Outcome mixed = Photorig("apply-color --model " + rendered + "/model.json --in " + torn + " " + chart +
                                     " --dark " + dark + " --bayer RGGB --out " + mixed_out + " --json",
                                 dir);
  EXPECT_EQ(mixed.exit_code, 2);
  const json mixed_document = Document(mixed, "apply-color");
  ASSERT_EQ(mixed_document["outputs"].size(), 1u) << mixed_document.dump();
  EXPECT_EQ(mixed_document["outputs"][0]["input"], chart);
  EXPECT_TRUE(std::filesystem::exists(mixed_out + "/chart_srgb.png"));
  ASSERT_EQ(mixed_document["failed"].size(), 1u);
  EXPECT_EQ(mixed_document["failed"][0]["input"], torn);
  EXPECT_NE(mixed_document.value("error", "").find("1 of 2 inputs not converted (" + torn + ")"), std::string::npos)
      << mixed_document.dump();
  // Two inputs of one name would write the same outputs: refused before any is written.
  std::filesystem::create_directories(dir.path() / "copy");
  std::filesystem::copy_file(chart, dir.path() / "copy" / "chart.png");
  const std::string twins_out = (dir.path() / "twins").string();
  const Outcome twins = Photorig("apply-color --model " + rendered + "/model.json --in " + chart + " " +
                                     (dir.path() / "copy" / "chart.png").string() + " --bayer RGGB --out " + twins_out,
                                 dir);
  EXPECT_EQ(twins.exit_code, 2);
  EXPECT_NE(twins.err.find("would both write " + twins_out + "/chart_*"), std::string::npos) << twins.err;
  EXPECT_FALSE(std::filesystem::exists(twins_out));
}

TEST(Cli, AnUnreachableDaemonExitsThreeAndSaysHowToStartIt) {
  TempDir dir;
  for (const std::string& command : std::vector<std::string>{"status", "status run-1", "watch run-1", "pause run-1", "resume run-1",
                                    "abort run-1"}) {
    const Outcome outcome = Photorig(command + " --url " + ClosedUrl() + " --json", dir);
    EXPECT_EQ(outcome.exit_code, 3) << command;
    const std::string name = command.substr(0, command.find(' '));
    const std::string error = Document(outcome, name).value("error", "");
    EXPECT_NE(error.find("photorigd is not reachable at " + ClosedUrl() + "; start it with `photorigd --rig"),
              std::string::npos)
        << error;
  }
  const std::string recipe = dir.Write("recipe.yaml", photorig::testing::SmallRecipeYaml());
  const Outcome submit = Photorig("submit " + recipe + " --url " + ClosedUrl(), dir);
  EXPECT_EQ(submit.exit_code, 3);
  EXPECT_NE(submit.err.find("submit: photorigd is not reachable at " + ClosedUrl()), std::string::npos) << submit.err;
}

TEST(Cli, ALightControllerThatCannotBeReachedExitsThree) {
  TempDir dir;
  // The simulated dome's Modbus controller, pointed at a port nothing serves.
  std::string rig = ReadText(photorig::testing::SourceDir() + "/config/rigs/sim-dome-modbus.yaml");
  rig = std::regex_replace(rig, std::regex("host: sim .*"), "host: 127.0.0.1");
  const std::string port = ClosedUrl().substr(ClosedUrl().rfind(':') + 1);
  rig = std::regex_replace(rig, std::regex("port: 0 .*"), "port: " + port);
  const std::string rig_path = dir.Write("dead-modbus.yaml", rig);
  const Outcome outcome = Photorig("run " + photorig::testing::SourceDir() + "/config/recipes/ps-sphere.yaml --rig " +
                                       rig_path + " --out " + (dir.path() / "run").string() + " --json",
                                   dir);
  EXPECT_EQ(outcome.exit_code, 3) << outcome.err;
  const json document = Document(outcome, "run");
  EXPECT_EQ(document["capture"]["status"], "failed");
  EXPECT_NE(document.value("error", "").find("light controller modbus-dome (tcp 127.0.0.1:" + port), std::string::npos)
      << document.dump();
}

TEST(Cli, SubmitWatchJsonExitsZeroForARunThatEndsDone) {
  TempDir dir;
  const std::string rig = dir.Write("rig.yaml", SmallRigYaml());
  const std::string recipe = dir.Write("recipe.yaml", photorig::testing::SmallRecipeYaml());
  const Daemon daemon(dir.path() / "data", rig, dir.path() / "photorigd.log");
  const std::string url = daemon.WaitReady();
  ASSERT_FALSE(url.empty()) << ReadText(dir.path() / "photorigd.log");

  const Outcome submitted = Photorig("submit " + recipe + " --watch --json --url " + url, dir);
  EXPECT_EQ(submitted.exit_code, 0) << submitted.err;
  const json watched = Document(submitted, "submit");
  EXPECT_EQ(watched["state"], "done");
  EXPECT_EQ(watched["stop"]["frames"], 5);
  const std::string id = watched.value("id", "");
  ASSERT_FALSE(id.empty());

  const Outcome status = Photorig("status " + id + " --json --url " + url, dir);
  ASSERT_EQ(status.exit_code, 0) << status.err;
  EXPECT_EQ(Document(status, "status")["state"], "done");
  const Outcome listed = Photorig("status --json --url " + url, dir);
  ASSERT_EQ(listed.exit_code, 0) << listed.err;
  EXPECT_EQ(Document(listed, "status")["runs"].size(), 1u);

  // A finished run watched again ends at once, with how it ended.
  const Outcome again = Photorig("watch " + id + " --json --url " + url, dir);
  EXPECT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(Document(again, "watch")["state"], "done");

  // Requests the daemon refuses are the caller's mistake: 2.
  const Outcome unknown = Photorig("watch no-such-run --json --url " + url, dir);
  EXPECT_EQ(unknown.exit_code, 2);
  EXPECT_EQ(Document(unknown, "watch")["http_status"], 404);
  const Outcome bad = Photorig("submit " + dir.Write("bad.yaml", "recipe: {name: bad}\n") + " --json --url " + url, dir);
  EXPECT_EQ(bad.exit_code, 2);
  Document(bad, "submit");
}

// The README demo's dome with LEDs 5 and 40 dark and LED 17 at a tenth of its light.
std::string FaultyDomeRig(const TempDir& dir) {
  const std::string rig = std::regex_replace(ReadText(SourceDir() + "/config/rigs/sim-dome.yaml"), std::regex("\nsim:\n"),
                                             "\nsim:\n  faults: {lights: {dim_channels: {5: 0.0, 17: 0.1, 40: 0.0}}}\n");
  return dir.Write("faulty-dome.yaml", rig);
}

// A run's manifest rewritten to say its capture ended `status` for `reason`,
// as a run stopped part-way (aborted, a device fault) stores it.
void MarkCapture(const std::string& run, const std::string& status, const std::string& reason) {
  const fs::path path = fs::path(run) / "manifest.json";
  json manifest = json::parse(ReadText(path));
  manifest["status"] = status;
  manifest["status_reason"] = reason;
  manifest["stop"]["status"] = status;
  manifest["stop"]["reason"] = reason;
  std::ofstream(path) << manifest.dump(2);
}

bool Contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TEST(Cli, AFailedCaptureIsNotSolvedUnlessAskedAndThenEveryOutputSaysSo) {
  TempDir dir;
  const std::string run = (dir.path() / "faulty").string();
  const Outcome captured = Photorig("run " + SourceDir() + "/config/recipes/ps-sphere.yaml --rig " + FaultyDomeRig(dir) +
                                        " --out " + run + " --json",
                                    dir);
  ASSERT_EQ(captured.exit_code, 1) << captured.err;
  ASSERT_EQ(Document(captured, "run")["capture"]["status"], "failed");
  EXPECT_FALSE(fs::exists(fs::path(run) / "results"));

  // Refused: the verdict, each reason, and what to do.
  const Outcome refused = Photorig("solve ps --run " + run + " --json", dir);
  EXPECT_EQ(refused.exit_code, 1) << refused.err;
  const std::string error = Document(refused, "solve ps").value("error", "");
  EXPECT_TRUE(Contains(error, run + ": the capture failed (47 of 49 frames)")) << error;
  EXPECT_TRUE(Contains(error, "\n  - LEDs 5, 40 did not light")) << error;
  EXPECT_TRUE(Contains(error, "\n  - LED 17 dead or dim")) << error;
  EXPECT_TRUE(Contains(error, "capture again; or, to look at it anyway, solve with --accept-failed-capture")) << error;
  EXPECT_FALSE(fs::exists(fs::path(run) / "results"));
  for (const std::string& family : std::vector<std::string>{"svbrdf", "tomography", "brdf"}) {
    const Outcome other = Photorig("solve " + family + " --run " + run + " --json", dir);
    EXPECT_EQ(other.exit_code, 1) << family << ": " << other.err;
    EXPECT_TRUE(Contains(Document(other, "solve " + family).value("error", ""), "the capture failed")) << family;
  }
  EXPECT_FALSE(fs::exists(fs::path(run) / "results"));

  // Accepted: solved, and the document, report.json and text all say from what.
  const Outcome accepted = Photorig("solve ps --run " + run + " --accept-failed-capture --json", dir);
  ASSERT_EQ(accepted.exit_code, 0) << accepted.err;
  const json solved = Document(accepted, "solve ps");
  const json& capture = solved["capture"];
  EXPECT_EQ(capture["status"], "failed");
  EXPECT_EQ(capture["accepted_failed_capture"], true);
  ASSERT_EQ(capture["reasons"].size(), 2u) << capture.dump();
  EXPECT_TRUE(Contains(capture["reasons"][0].get<std::string>(), "LEDs 5, 40 did not light")) << capture.dump();
  EXPECT_TRUE(Contains(capture["reasons"][1].get<std::string>(), "LED 17 dead or dim")) << capture.dump();
  EXPECT_EQ(json::parse(ReadText(fs::path(run) / "results/ps/report.json"))["capture"], capture);
  EXPECT_TRUE(Contains(accepted.err, "warning: solved from a failed capture (--accept-failed-capture)")) << accepted.err;
  EXPECT_TRUE(Contains(accepted.err, "  - LEDs 5, 40 did not light")) << accepted.err;

  // A batch counts the run failed beside a good one, whose report says its capture was complete.
  const SmallRun good(dir);
  ASSERT_EQ(Photorig("run " + good.recipe + " --out " + good.run + " --no-solve", dir).exit_code, 0);
  const Outcome batch = Photorig("batch solve --runs " + run + "," + good.run + " --local 2 --method lambertian --batch " +
                                     (dir.path() / "batch").string() + " --json",
                                 dir);
  EXPECT_EQ(batch.exit_code, 1) << batch.err;
  const json counted = Document(batch, "batch solve");
  EXPECT_EQ(counted["counts"].value("failed", 0), 1) << counted.dump(2);
  EXPECT_EQ(counted["counts"].value("completed", 0), 1) << counted.dump(2);
  EXPECT_EQ(counted["tasks"][0]["state"], "failed");
  EXPECT_TRUE(Contains(counted["tasks"][0].value("error", ""), "the capture failed")) << counted.dump(2);
  EXPECT_EQ(counted["tasks"][1]["report"]["capture"]["status"], "complete");
}

TEST(Cli, AnAbortedCaptureIsRefusedByEverySolve) {
  TempDir dir;
  const SmallRun small(dir);
  ASSERT_EQ(Photorig("run " + small.recipe + " --out " + small.run + " --no-solve", dir).exit_code, 0);
  MarkCapture(small.run, "aborted", "aborted by request after 3 of 5 steps");
  for (const std::string& family : std::vector<std::string>{"ps", "svbrdf", "tomography", "brdf"}) {
    const Outcome refused = Photorig("solve " + family + " --run " + small.run + " --json", dir);
    EXPECT_EQ(refused.exit_code, 1) << family << ": " << refused.err;
    const std::string error = Document(refused, "solve " + family).value("error", "");
    EXPECT_TRUE(Contains(error, "the capture was aborted (5 of 5 frames)")) << error;
    EXPECT_TRUE(Contains(error, "\n  - aborted by request after 3 of 5 steps")) << error;
  }
  EXPECT_FALSE(fs::exists(fs::path(small.run) / "results"));
  const Outcome accepted = Photorig("solve svbrdf --run " + small.run + " --accept-failed-capture --held-out -1 --no-gltf --json", dir);
  EXPECT_EQ(Document(accepted, "solve svbrdf")["capture"]["status"], "aborted") << accepted.err;
  EXPECT_EQ(json::parse(ReadText(fs::path(small.run) / "results/svbrdf/report.json"))["capture"]["accepted_failed_capture"], true);
}

TEST(Cli, TheDaemonsRunRecordGivesTheCapturesVerdictWithItsResults) {
  TempDir dir;
  const std::string rig = dir.Write("rig.yaml", SmallRigYaml("{lights: {dim_channels: {2: 0.0}}}"));
  const std::string recipe = dir.Write("recipe.yaml", photorig::testing::SmallRecipeYaml());
  const Daemon daemon(dir.path() / "data", rig, dir.path() / "photorigd.log");
  const std::string url = daemon.WaitReady();
  ASSERT_FALSE(url.empty()) << ReadText(dir.path() / "photorigd.log");
  const Outcome submitted = Photorig("submit " + recipe + " --watch --json --url " + url, dir);
  EXPECT_EQ(submitted.exit_code, 1) << submitted.err;
  const std::string id = Document(submitted, "submit").value("id", "");
  ASSERT_FALSE(id.empty());
  EXPECT_FALSE(Document(Photorig("status " + id + " --json --url " + url, dir), "status").contains("results"));

  const std::string run = (dir.path() / "data" / "runs" / id).string();
  ASSERT_EQ(Photorig("solve ps --run " + run + " --accept-failed-capture --method lambertian", dir).exit_code, 0);
  const json record = Document(Photorig("status " + id + " --json --url " + url, dir), "status");
  const json& capture = record["results"]["capture"];
  EXPECT_EQ(capture["status"], "failed") << record.dump(2);
  EXPECT_EQ(capture["accepted_failed_capture"], true);
  ASSERT_EQ(capture["reasons"].size(), 1u);
  EXPECT_TRUE(Contains(capture["reasons"][0].get<std::string>(), "LED 2 did not light")) << capture.dump();
  const json listed = Document(Photorig("status --json --url " + url, dir), "status");
  EXPECT_EQ(listed["runs"][0]["results"]["capture"], capture);
}

TEST(Cli, AFolderThatIsNoRunAndAnOccupiedOutAreUsageErrors) {
  TempDir dir;
  const Outcome empty = Photorig("solve ps --run " + dir.path().string() + " --json", dir);
  EXPECT_EQ(empty.exit_code, 2) << empty.err;
  EXPECT_TRUE(Contains(Document(empty, "solve ps").value("error", ""), dir.path().string() + " is not a run directory: it has no manifest.json"));

  const SmallRun small(dir);
  dir.Write("run/notes.txt", "not a run\n");
  const Outcome occupied = Photorig("run " + small.recipe + " --out " + small.run + " --json", dir);
  EXPECT_EQ(occupied.exit_code, 2) << occupied.err;
  EXPECT_TRUE(Contains(Document(occupied, "run").value("error", ""), small.run + " already exists and is not empty"));
  EXPECT_EQ(ReadText(fs::path(small.run) / "notes.txt"), "not a run\n");
  EXPECT_EQ(std::distance(fs::directory_iterator(small.run), fs::directory_iterator()), 1);
}

// photorigd without --data-root keeps its queue and runs in the user's data
// directory, not in ./runs where `photorig run` puts its own.
TEST(Cli, PhotorigdWithoutADataRootUsesTheUsersDataDirectory) {
  TempDir dir;
  const fs::path home = dir.path() / "home", work = dir.path() / "work", log = dir.path() / "photorigd.log";
  fs::create_directories(home);
  fs::create_directories(work);
  const std::string rig = dir.Write("rig.yaml", SmallRigYaml());
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::setenv("HOME", home.c_str(), 1);
    ::unsetenv("XDG_DATA_HOME");
    ::unsetenv("STATE_DIRECTORY");
    if (::chdir(work.c_str()) != 0 || !std::freopen(log.c_str(), "w", stdout) || !std::freopen(log.c_str(), "a", stderr))
      _exit(126);
    const std::string bin = std::string(PHOTORIG_BIN_DIR) + "/photorigd";
    ::execl(bin.c_str(), bin.c_str(), "--rig", rig.c_str(), "--port", "0", "--web-root", "none",
            static_cast<char*>(nullptr));
    _exit(127);
  }
  const fs::path expected = home / ".local/share/photorig";
  bool ready = false;
  for (int i = 0; i < 1000 && !ready; ++i) {
    ready = Contains(ReadText(log), "event=ready");
    if (!ready) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ::kill(pid, SIGTERM);
  ::waitpid(pid, nullptr, 0);
  ASSERT_TRUE(ready) << ReadText(log);
  EXPECT_TRUE(Contains(ReadText(log), "data_root=" + expected.string())) << ReadText(log);
  EXPECT_TRUE(fs::exists(expected / "queue.sqlite"));
  EXPECT_TRUE(fs::is_empty(work)) << "photorigd wrote into its working directory";
}

// A damaged frame is named once, by photorig, without OpenCV's own warnings,
// and is an input error (exit 2) for every command that reads the run.
TEST(Cli, AnUnreadableFrameIsNamedWithoutTheLibrarysWarnings) {
  TempDir dir;
  const SmallRun small(dir);
  ASSERT_EQ(Photorig("run " + small.recipe + " --out " + small.run + " --no-solve", dir).exit_code, 0);
  const fs::path frame = fs::path(small.run) / "frames" / "0002_led01.png";
  fs::resize_file(frame, 40);
  const std::vector<std::string> commands = {"solve ps --run " + small.run,
                                             "export nexus --run " + small.run + " --out " + (dir.path() / "run.nxs").string()};
  for (const std::string& command : commands) {
    const Outcome outcome = Photorig(command, dir);
    EXPECT_EQ(outcome.exit_code, 2) << command;
    EXPECT_TRUE(Contains(outcome.err, "cannot read image " + frame.string())) << outcome.err;
    EXPECT_TRUE(Contains(outcome.err, "capture the run again")) << outcome.err;
    EXPECT_FALSE(Contains(outcome.err, "WARN")) << outcome.err;
    EXPECT_FALSE(Contains(outcome.err, "imread_")) << outcome.err;
  }
}

// A manifest cut short is named with where it ends, in the project's words
// rather than the JSON library's, and exits 2 whichever command reads it.
TEST(Cli, ACorruptManifestExitsTwoNamingTheFile) {
  TempDir dir;
  const SmallRun small(dir);
  ASSERT_EQ(Photorig("run " + small.recipe + " --out " + small.run + " --no-solve", dir).exit_code, 0);
  const fs::path manifest = fs::path(small.run) / "manifest.json";
  fs::resize_file(manifest, fs::file_size(manifest) / 2);
  const std::vector<std::pair<std::string, std::string>> commands = {
      {"solve ps", "ps"}, {"solve brdf", "brdf"}, {"export diligent", "diligent"}};
  for (const auto& [command, folder] : commands) {
    const std::string out = (dir.path() / folder).string();
    const Outcome outcome = Photorig(command + " --run " + small.run + " --out " + out + " --json", dir);
    EXPECT_EQ(outcome.exit_code, 2) << command << outcome.err;
    EXPECT_TRUE(Contains(outcome.err, manifest.string() + ": corrupt manifest")) << outcome.err;
    EXPECT_TRUE(Contains(outcome.err, "capture the run again")) << outcome.err;
    EXPECT_FALSE(Contains(outcome.err, "json.exception")) << outcome.err;
    Document(outcome, command);
  }
}

// A colour model given for a monochrome run is refused, not ignored with a
// report that names it.
TEST(Cli, AColourModelForAMonochromeRunIsRefused) {
  TempDir dir;
  const SmallRun small(dir);
  ASSERT_EQ(Photorig("run " + small.recipe + " --out " + small.run + " --no-solve", dir).exit_code, 0);
  const std::string model = dir.Write("model.yaml", "this: [is not\n");
  const Outcome solve = Photorig("solve ps --run " + small.run + " --color-model " + model, dir);
  EXPECT_EQ(solve.exit_code, 2) << solve.err;
  EXPECT_TRUE(Contains(solve.err, "monochrome run")) << solve.err;
  EXPECT_FALSE(fs::exists(fs::path(small.run) / "results" / "ps" / "report.json"));
}

// photorigd exits 2 on a flag it does not know and on a rig that is missing,
// as photorig does, not with the argument parser's own codes.
TEST(Cli, PhotorigdExitsTwoOnBadFlagsAndAMissingRig) {
  TempDir dir;
  const std::string bin = std::string(PHOTORIG_BIN_DIR) + "/photorigd";
  auto exit_code = [&](const std::string& arguments) {
    const std::string command = bin + " " + arguments + " > " + (dir.path() / "log").string() + " 2>&1 < /dev/null";
    const int status = std::system(command.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  };
  EXPECT_EQ(exit_code("--bogus"), 2) << ReadText(dir.path() / "log");
  EXPECT_EQ(exit_code("--data-root " + dir.path().string() + " --rig " + (dir.path() / "nope.yaml").string()), 2)
      << ReadText(dir.path() / "log");
  EXPECT_EQ(exit_code("--help"), 0) << ReadText(dir.path() / "log");
}

// Each of these is refused before any work, exit 2, with a message that
// names what is wrong: not as an unreachable daemon, not after a solve.
TEST(Cli, CommandsCheckTheirInputsBeforeWorkingAndNameWhatIsWrong) {
  TempDir dir;
  const SmallRun small(dir);
  ASSERT_EQ(Photorig("run " + small.recipe + " --out " + small.run + " --no-solve", dir).exit_code, 0);
  const std::string broken = dir.Write("broken.yaml", "recipe: {name: x\ncapture: [\n");
  const std::string ball = (dir.path() / "ball.png").string();
  ASSERT_TRUE(cv::imwrite(ball, cv::Mat(16, 16, CV_16U, cv::Scalar(100))));
  dir.Write("occupied/notes.txt", "keep\n");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"bogus", "unknown command 'bogus'"},
      {"status abc --url not-a-url", "'not-a-url' is not an address"},
      {"submit " + broken + " --url " + ClosedUrl(), broken + ":"},
      {"envmap --ball " + ball + " --circle 8 8 6 --out " + (dir.path() / "map.png").string(), "name a .hdr, .exr or .tiff"},
      {"relight --run " + dir.path().string() + " --light 0,0,1 --out " + (dir.path() / "r.tiff").string(),
       "is not a run directory"},
      {"solve brdf --run " + small.run, "not a gonioreflectometer run"},
      {"solve svbrdf --run " + small.run + " --held-out 99", "99 exceeds the 4 lights"},
      {"solve ps --run " + small.run + " --out " + (dir.path() / "occupied").string(), "holds files that are not"}};
  for (const auto& [arguments, said] : cases) {
    const Outcome outcome = Photorig(arguments, dir);
    EXPECT_EQ(outcome.exit_code, 2) << arguments << "\n" << outcome.err;
    EXPECT_TRUE(Contains(outcome.err, said)) << arguments << "\n" << outcome.err;
    EXPECT_FALSE(Contains(outcome.err, "not reachable")) << arguments << "\n" << outcome.err;
    EXPECT_FALSE(Contains(outcome.err, "100%")) << arguments << ": refused only after the work\n" << outcome.err;
  }
  EXPECT_EQ(ReadText(dir.path() / "occupied" / "notes.txt"), "keep\n");
  // A file where the results would go is not exchanged for them.
  const std::string file = dir.Write("results.txt", "keep\n");
  const Outcome onto_file = Photorig("solve ps --run " + small.run + " --out " + file, dir);
  EXPECT_EQ(onto_file.exit_code, 2) << onto_file.err;
  EXPECT_TRUE(Contains(onto_file.err, "is a file, not a folder")) << onto_file.err;
  EXPECT_EQ(ReadText(file), "keep\n");
}

// A calibration that fails prints no summary of outputs it did not write.
TEST(Cli, AFailedLightCalibrationPrintsNoSummaryOfOutputs) {
  TempDir dir;
  std::string images;
  for (int i = 0; i < 3; ++i) {
    const std::string image = (dir.path() / ("dark" + std::to_string(i) + ".png")).string();
    ASSERT_TRUE(cv::imwrite(image, cv::Mat(32, 32, CV_16U, cv::Scalar(0))));
    images += " " + image;
  }
  const fs::path out = dir.path() / "lights";
  const Outcome outcome = Photorig("calibrate lights --images" + images + " --out " + out.string(), dir);
  EXPECT_NE(outcome.exit_code, 0) << outcome.err;
  EXPECT_FALSE(Contains(outcome.out, "outputs in")) << outcome.out;
  EXPECT_FALSE(fs::exists(out)) << "nothing is written when the sphere is not found";
}

// Help names what a flag takes, not the parser's internals.
TEST(Cli, HelpShowsNamesForChoicesAndPlainFlags) {
  TempDir dir;
  const Outcome brdf = Photorig("solve brdf --help", dir), ps = Photorig("solve ps --help", dir);
  EXPECT_TRUE(Contains(brdf.out, "--calibration NAME")) << brdf.out;
  EXPECT_FALSE(Contains(ps.out, "{false}")) << ps.out;
  EXPECT_TRUE(Contains(ps.out, "--no-fill")) << ps.out;
}

}  // namespace
