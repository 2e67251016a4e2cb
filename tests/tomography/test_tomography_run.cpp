// The tomography path through the rig: config/recipes/tomography.yaml run on
// the simulated tomograph by the real executable (capture, the recipe's
// tomography stage), `photorig solve tomography` on the run and on a folder of
// projections, and the input it refuses.

#include "../daemon/test_support.h"
#include "simulated_scan.h"
#include "photorig/daemon/pipelines/tomography_pipeline.h"
#include "photorig/sim/phantom.h"
#include "photorig/solvers/tomography/nrrd.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using photorig::testing::ReadText;
using photorig::testing::SourceDir;
using photorig::testing::TempDir;
using Outcome = photorig::testing::CommandOutcome;
using photorig::testing::Photorig;

json Document(const Outcome& outcome) {
  const json document = json::parse(outcome.out, nullptr, false);
  EXPECT_TRUE(document.is_object()) << "stdout: " << outcome.out << "\nstderr: " << outcome.err;
  if (document.is_object()) {
    EXPECT_EQ(document.value("exit_code", -1), outcome.exit_code);
    EXPECT_EQ(document.value("ok", outcome.exit_code != 0), outcome.exit_code == 0);
  }
  return document;
}

// SIRT's stopped error on this 64^2 x 8 scan is about 0.2 (measured 0.19 to
// 0.21 across seeds): the central slices of the 3D phantom are thin, low
// contrast features a 0.5 mm grid resolves only in part. 0.3 fails a
// reconstruction that lost them, a mirrored geometry or a wrong sign.
constexpr double kErrorBound = 0.3;
// The recipe's SART with TV: 0.127 measured.
constexpr double kRecipeErrorBound = 0.15;

#if PHOTORIG_HAVE_OPENVDB
// OpenVDB (and what it pulls in) is loaded only when a solve writes
// volume.vdb (daemon/src/io/vdb_module_abi.h): the libraries the dynamic
// loader maps for the program at start name none of it. The recipe's test
// below checks the volume is written all the same.
TEST(TomographyRun, TheProgramStartsWithoutOpenVdb) {
  TempDir dir;
  const std::string listing = (dir.path() / "libraries").string();
  const std::string command = "LD_TRACE_LOADED_OBJECTS=1 " + std::string(PHOTORIG_BIN_DIR) + "/photorig > " + listing;
  ASSERT_EQ(std::system(command.c_str()), 0);
  const std::string libraries = ReadText(listing);
  EXPECT_NE(libraries.find("libopencv_core"), std::string::npos) << libraries;  // the listing is the program's
  EXPECT_EQ(libraries.find("openvdb"), std::string::npos) << libraries;
}
#endif

TEST(TomographyRun, TheRecipeCapturesAndReconstructsThePhantomThroughTheExecutable) {
  TempDir dir;
  const std::string run = (dir.path() / "run").string();
  const Outcome outcome =
      Photorig("run " + SourceDir() + "/config/recipes/tomography.yaml --out " + run + " --json", dir);
  ASSERT_EQ(outcome.exit_code, 0) << outcome.err;
  const json document = Document(outcome);
  ASSERT_TRUE(document.contains("tomography")) << outcome.out;
  const json& stage = document["tomography"];
  EXPECT_TRUE(stage["trusted"].get<bool>()) << stage.dump(2);
  EXPECT_LE(stage["relative_error_vs_truth"].get<double>(), kRecipeErrorBound) << stage.dump(2);

  // The run holds the geometry: 64 projections at the turntable's angles, 4 flats, 4 darks.
  const TomographyInput input = LoadTomographyRun(run);
  EXPECT_EQ(input.projections.size(), 64u);
  EXPECT_EQ(input.flats.size(), 4u);
  EXPECT_EQ(input.darks.size(), 4u);
  EXPECT_NEAR(input.geometry.angles_rad[1] * 180.0 / M_PI, 2.8125, 1e-9);
  EXPECT_EQ(input.geometry.detector_cols, 64);
  EXPECT_DOUBLE_EQ(input.geometry.pixel_mm, 0.5);
  ASSERT_NE(input.phantom, nullptr);

  const fs::path results = fs::path(run) / "results" / "tomography";
  for (const char* file : {"volume.nrrd", "report.json", "geometry.json", "slice_z.png", "slice_y.png", "truth_z.png"})
    EXPECT_TRUE(fs::exists(results / file)) << file;
#if PHOTORIG_HAVE_OPENVDB
  EXPECT_TRUE(fs::exists(results / "volume.vdb"));  // its contents: test_vdb_volume.cpp
#endif
  solvers::tomography::VolumeGrid grid;
  Eigen::VectorXf sigma;
  ASSERT_TRUE(solvers::tomography::ReadNrrd((results / "volume.nrrd").string(), &grid, &sigma).IsSolutionUsable());
  EXPECT_EQ(grid.nx, 64);
  EXPECT_EQ(grid.nz, 8);
  const json report = json::parse(ReadText(results / "report.json"));
  // SART with TV, stopped at its balance (TV holds the residual above the
  // target), the centre found by the held-out search (a 0..180 scan without
  // its end view) at the simulated axis, 0.
  EXPECT_EQ(report["method"], "sart");
  EXPECT_GT(report["tv_strength"].get<double>(), 0.0);
  EXPECT_EQ(report["stop_reason"], "stagnation");
  EXPECT_EQ(report["centre_of_rotation"]["method"], "held-out-search");
  EXPECT_NEAR(report["centre_of_rotation"]["offset_px"].get<double>(), 0.0, 0.25);

  // Solved again from the stored frames by the command as docs/cli.md shows
  // it: the same figures.
  const Outcome again = Photorig("solve tomography --run " + run + " --method sart --tv --out " +
                                     (dir.path() / "again").string() + " --json",
                                 dir);
  ASSERT_EQ(again.exit_code, 0) << again.err;
  const json solved = Document(again);
  EXPECT_EQ(solved["command"], "solve tomography");
  EXPECT_EQ(solved["iterations"], report["iterations"]);
  EXPECT_NEAR(solved["relative_error_vs_truth"].get<double>(), report["relative_error_vs_truth"].get<double>(), 1e-6);
  EXPECT_EQ(solved["capture"], (json{{"status", "complete"}, {"reasons", json::array()}, {"accepted_failed_capture", false}}));

  // Its truth is the phantom, nothing of a lit surface.
  std::set<std::string> truth;
  for (const auto& entry : fs::directory_iterator(fs::path(run) / "ground_truth")) truth.insert(entry.path().filename());
  EXPECT_EQ(truth, std::set<std::string>{"phantom.json"});
  // Photometric stereo refuses it, naming the solver that reads it, and writes nothing.
  const Outcome ps = Photorig("solve ps --run " + run + " --json", dir);
  EXPECT_EQ(ps.exit_code, 2) << ps.err;
  EXPECT_NE(Document(ps).value("error", "").find("a tomography run: solve it with `photorig solve tomography --run " + run),
            std::string::npos)
      << ps.out;
  EXPECT_FALSE(fs::exists(fs::path(run) / "results" / "ps"));

  // SIRT, the command's default, stopped by the discrepancy rule: trusted,
  // but worse than the recipe's SART with TV, by the phantom and by the
  // held-out residual alike; its progress ends where it stopped, not at the limit.
  const Outcome sirt = Photorig("solve tomography --run " + run + " --out " + (dir.path() / "sirt").string(), dir);
  ASSERT_EQ(sirt.exit_code, 0) << sirt.out << sirt.err;
  const json sirt_report = json::parse(ReadText(dir.path() / "sirt" / "report.json"));
  EXPECT_EQ(sirt_report["stop_reason"], "discrepancy");
  EXPECT_LE(sirt_report["residual"].get<double>(), sirt_report["discrepancy_target"].get<double>());
  EXPECT_GT(sirt_report["relative_error_vs_truth"].get<double>(), report["relative_error_vs_truth"].get<double>());
  EXPECT_GT(sirt_report["held_out"]["relative_residual"].get<double>(), report["held_out"]["relative_residual"].get<double>());
  const std::string stopped = "sirt stopped at " + std::to_string(sirt_report["iterations"].get<int>()) + "/300 (";
  EXPECT_NE(sirt.err.find(stopped), std::string::npos) << sirt.err;

  // The iteration limit first: not trusted, and the message names the flag.
  const Outcome limited = Photorig("solve tomography --run " + run + " --max-iterations 5 --out " +
                                       (dir.path() / "limited").string() + " --json",
                                   dir);
  EXPECT_EQ(limited.exit_code, 1);
  EXPECT_NE(Document(limited).value("error", "").find("raise --max-iterations"), std::string::npos)
      << limited.out;
}

TEST(TomographyRun, EveryMethodReconstructsAFolderOfProjectionsWithinTheBound) {
  TempDir dir;
  const std::string folder = (dir.path() / "scan").string();
  WriteProjectionFolder(SimulatedScan(), folder);
  for (const char* method : {"sirt", "art", "cgls"}) {
    const Outcome outcome = Photorig(std::string("solve tomography --projections ") + folder + " --method " + method +
                                         " --out " + (dir.path() / method).string() + " --json",
                                     dir);
    ASSERT_EQ(outcome.exit_code, 0) << method << ": " << outcome.err;
    const json document = Document(outcome);
    EXPECT_EQ(document["method"], method);
    EXPECT_EQ(document["stop_reason"], "discrepancy") << method;
    EXPECT_LT(document["relative_error_vs_truth"].get<double>(), kErrorBound) << method;
  }
}

// A scan as a beamline gives it: 16-bit TIFFs, the angles in a file, the
// views over 360 degrees in shuffled order with one repeated, and the axis
// 3 px off the detector's centre, where geometry.json does not say (a whole
// pixel: at a half-pixel offset the opposite views interlace, sampling finer
// than the 0.5 mm voxels hold, and the residual stays 1.5 x above the noise
// level, flagged inconsistent at the true centre too). The
// centre is found from the data within a quarter pixel, the volume within 5 %
// of the error at the true centre, and the held-out residual reported.
TEST(TomographyRun, TiffsWithAnAnglesFileAreSolvedAtTheCentreFoundInTheData) {
  TempDir dir;
  constexpr double kOffsetPx = -3.0;
  TomographyInput input = SimulatedScan(64, solvers::tomography::Beam::kParallel, kOffsetPx * 0.5, 360.0);
  std::vector<std::size_t> order(input.projections.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = (i * 37) % order.size();  // 37 is prime to 64
  order.push_back(order[5]);
  TomographyInput shuffled = input;
  shuffled.projections.clear();
  shuffled.geometry.angles_rad.clear();
  for (std::size_t i : order) {
    shuffled.projections.push_back(input.projections[i]);
    shuffled.geometry.angles_rad.push_back(input.geometry.angles_rad[i]);
  }
  const fs::path folder = dir.path() / "scan";
  WriteProjectionFolder(shuffled, folder.string());
  for (const char* sub : {"projections", "flats", "darks"})
    for (const auto& entry : fs::directory_iterator(folder / sub)) {
      fs::path tiff = entry.path();
      cv::imwrite(tiff.replace_extension(".tif").string(), cv::imread(entry.path().string(), cv::IMREAD_UNCHANGED));
      fs::remove(entry.path());
    }
  json geometry = json::parse(ReadText(folder / "geometry.json"));
  std::ofstream angles(folder / "angles.txt");
  angles << "# degrees\n";
  for (const json& deg : geometry["angles_deg"]) angles << deg.get<double>() << "\n";
  angles.close();
  geometry.erase("angles_deg");
  std::ofstream(folder / "geometry.json") << geometry.dump();

  // SART with TV: SIRT's residual stays above the noise level after 300 iterations on this scan.
  const std::string solve = "solve tomography --method sart --tv --projections " + folder.string();
  const Outcome found = Photorig(solve + " --out " +
                                     (dir.path() / "found").string() + " --json",
                                 dir);
  ASSERT_EQ(found.exit_code, 0) << found.out << found.err;
  const json document = Document(found);
  EXPECT_EQ(document["geometry"]["views"], 65);
  const json& centre = document["centre_of_rotation"];
  EXPECT_EQ(centre["source"], "estimated");
  EXPECT_EQ(centre["method"], "opposing-views");
  EXPECT_NEAR(centre["offset_px"].get<double>(), kOffsetPx, 0.25) << centre.dump();
  EXPECT_GT(centre["sigma_px"].get<double>(), 0.0);
  const json& held_out = document["held_out"];
  EXPECT_EQ(held_out["fit_views"].get<int>() + held_out["held_out_views"].get<int>(), 65);
  EXPECT_GT(held_out["relative_residual"].get<double>(), held_out["noise_floor"].get<double>());

  const Outcome given = Photorig(solve + " --cor-offset-mm " +
                                     std::to_string(kOffsetPx * 0.5) + " --out " + (dir.path() / "given").string() +
                                     " --json",
                                 dir);
  ASSERT_EQ(given.exit_code, 0) << given.out << given.err;
  const json truth = Document(given);
  EXPECT_EQ(truth["centre_of_rotation"]["source"], "given");
  EXPECT_LT(document["relative_error_vs_truth"].get<double>(), 1.05 * truth["relative_error_vs_truth"].get<double>());
  // The nominal centre, 3 px off: worse by both the held-out residual and the truth.
  const Outcome nominal = Photorig(solve + " --cor-offset-mm 0 --out " +
                                       (dir.path() / "nominal").string() + " --json",
                                   dir);
  const json off = Document(nominal);
  EXPECT_GT(off["held_out"]["relative_residual"].get<double>(), held_out["relative_residual"].get<double>());
  EXPECT_GT(off["relative_error_vs_truth"].get<double>(), document["relative_error_vs_truth"].get<double>());
  std::printf("found %+.3f px (sigma %.3f): error %.4f, held-out %.4f; true centre: %.4f, %.4f; nominal: %.4f, %.4f\n",
              centre["offset_px"].get<double>(), centre["sigma_px"].get<double>(),
              document["relative_error_vs_truth"].get<double>(), held_out["relative_residual"].get<double>(),
              truth["relative_error_vs_truth"].get<double>(), truth["held_out"]["relative_residual"].get<double>(),
              off["relative_error_vs_truth"].get<double>(), off["held_out"]["relative_residual"].get<double>());
}

// One flat and one dark give no noise estimate for the discrepancy rule: the
// iterations stop where the held-out residual is lowest instead.
TEST(TomographyRun, OneFlatAndOneDarkStopWhereTheHeldOutResidualIsLowest) {
  TempDir dir;
  TomographyInput input = SimulatedScan();
  input.flats.resize(1);
  input.darks.resize(1);
  const std::string folder = (dir.path() / "scan").string();
  WriteProjectionFolder(input, folder);
  const Outcome outcome = Photorig("solve tomography --projections " + folder + " --cor-offset-mm 0 --out " +
                                       (dir.path() / "out").string() + " --json",
                                   dir);
  ASSERT_EQ(outcome.exit_code, 0) << outcome.out << outcome.err;
  const json document = Document(outcome);
  EXPECT_EQ(document["stop_reason"], "held-out-minimum");
  EXPECT_TRUE(document["held_out"]["stopping_rule"].get<bool>());
  EXPECT_EQ(document["iterations"], document["held_out"]["iterations"]);
  EXPECT_LT(document["relative_error_vs_truth"].get<double>(), kErrorBound);
  std::printf("one flat, one dark: %d iterations, error %.4f, held-out residual %.4f\n", document["iterations"].get<int>(),
              document["relative_error_vs_truth"].get<double>(), document["held_out"]["relative_residual"].get<double>());
}

// Three detector columns whose response drifted 6-8 % from their flats:
// --ring-filter finds every pixel of them and brings the error down.
TEST(TomographyRun, TheRingFilterRemovesTheStripesOfDriftedColumns) {
  TempDir dir;
  TomographyInput input = SimulatedScan();
  const int cols = input.geometry.detector_cols, rows = input.geometry.detector_rows;
  for (auto& frame : input.projections)
    for (const auto& [col, gain] : {std::pair{20, 1.06}, std::pair{30, 0.92}, std::pair{41, 1.08}})
      for (int row = 0; row < rows; ++row) {
        std::uint16_t& dn = frame[static_cast<std::size_t>(row * cols + col)];
        dn = static_cast<std::uint16_t>(std::lround(dn * gain));
      }
  const std::string folder = (dir.path() / "scan").string();
  WriteProjectionFolder(input, folder);
  const std::string solve = "solve tomography --projections " + folder + " --method sart --tv --cor-offset-mm 0 --no-held-out";
  const json plain = Document(Photorig(solve + " --out " + (dir.path() / "plain").string() + " --json", dir));
  const Outcome outcome = Photorig(solve + " --ring-filter --out " + (dir.path() / "filtered").string() + " --json", dir);
  ASSERT_EQ(outcome.exit_code, 0) << outcome.out << outcome.err;
  const json filtered = Document(outcome);
  EXPECT_GE(filtered["ring_filter"]["stripes"].get<int>(), 3 * rows);
  EXPECT_FALSE(filtered.contains("held_out"));
  const double before = plain["relative_error_vs_truth"].get<double>(), after = filtered["relative_error_vs_truth"].get<double>();
  std::printf("drifted columns: error %.4f, filtered %.4f (%d pixels corrected)\n", before, after,
              filtered["ring_filter"]["stripes"].get<int>());
  EXPECT_LT(after, 0.9 * before);
}

TEST(TomographyRun, MissingFlatsOrDarksAreRefusedSayingWhat) {
  TempDir dir;
  TomographyInput input = SimulatedScan(32);
  input.flats.clear();
  const std::string no_flats = (dir.path() / "no-flats").string();
  WriteProjectionFolder(input, no_flats);
  const Outcome outcome = Photorig("solve tomography --projections " + no_flats + " --json", dir);
  EXPECT_EQ(outcome.exit_code, 2);
  EXPECT_NE(Document(outcome).value("error", "").find("no flat fields"), std::string::npos) << outcome.out;

  input = SimulatedScan(32);
  input.darks.clear();
  EXPECT_THROW(
      {
        try {
          const std::string folder = (dir.path() / "no-darks").string();
          WriteProjectionFolder(input, folder);
          LoadProjectionFolder(folder);
        } catch (const std::invalid_argument& e) {
          EXPECT_NE(std::string(e.what()).find("no dark frames"), std::string::npos) << e.what();
          throw;
        }
      },
      std::invalid_argument);
}

TEST(TomographyRun, AGeometryThatDoesNotFitTheFramesIsRefused) {
  TempDir dir;
  const std::string folder = (dir.path() / "scan").string();
  WriteProjectionFolder(SimulatedScan(32), folder);
  // One angle too many.
  json geometry = json::parse(ReadText(fs::path(folder) / "geometry.json"));
  geometry["angles_deg"].push_back(180.0);
  std::ofstream(fs::path(folder) / "geometry.json") << geometry.dump();
  Outcome outcome = Photorig("solve tomography --projections " + folder + " --json", dir);
  EXPECT_EQ(outcome.exit_code, 2);
  EXPECT_NE(Document(outcome).value("error", "").find("32 projections but 33 angles"), std::string::npos) << outcome.out;
  // A detector of another size than the frames.
  geometry["angles_deg"].erase(geometry["angles_deg"].size() - 1);
  geometry["detector_cols"] = 48;
  std::ofstream(fs::path(folder) / "geometry.json") << geometry.dump();
  outcome = Photorig("solve tomography --projections " + folder + " --json", dir);
  EXPECT_EQ(outcome.exit_code, 2);
  EXPECT_NE(Document(outcome).value("error", "").find("the detector in the geometry has 48 x 8"), std::string::npos)
      << outcome.out;
}

TEST(TomographyRun, AWrongCentreOfRotationIsNotTrustedAndExitsOne) {
  TempDir dir;
  const std::string folder = (dir.path() / "scan").string();
  WriteProjectionFolder(SimulatedScan(), folder);
  const Outcome outcome =
      Photorig("solve tomography --projections " + folder + " --cor-offset-mm 2 --out " + (dir.path() / "out").string() +
                   " --json",
               dir);
  EXPECT_EQ(outcome.exit_code, 1);
  const json document = Document(outcome);
  EXPECT_FALSE(document.value("trusted", true));
  EXPECT_EQ(document.value("termination", ""), "no-convergence");
  // Written all the same, for a look at what went wrong.
  EXPECT_TRUE(fs::exists(dir.path() / "out" / "volume.nrrd"));
}

}  // namespace
}  // namespace photorig::daemon
