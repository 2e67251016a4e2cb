// photorig solve brdf --run DIR [--loss weighted|log] [--out DIR]   (--json as every command: docs/cli.md)
//
// Gonioreflectometer frames -> BRDF samples -> every candidate model fitted
// and the one the data support chosen (solvers/brdf). Each pose frame gives
// one sample: the mean of a central block of pixels (every pixel of the
// orthographic camera sees the sample under the same directions), minus the
// dark frames' mean, divided by what a perfect white diffuser would give
// without the 1/pi (lamp irradiance x level x camera response x exposure x
// gain x cos theta_i). Its sigma is the block's standard error. A grey camera
// gives the same value in all three channels.

#include "../command.h"
#include "../command_output.h"
#include "brdf_report.h"
#include "photorig/daemon/run_store.h"
#include "photorig/solvers/brdf/fit.h"
#include "photorig/solvers/brdf/pose_plan.h"

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>

namespace photorig::app {
namespace {

namespace brdf = photorig::solvers::brdf;
namespace fs = std::filesystem;

// A block the sample fills up to a camera arm at 80 deg on config/rigs/sim-gonio.yaml
// (a 12 mm sample seen through 0.5 mm pixels, foreshortened by cos 80 deg: +-2.1 mm).
constexpr int kBlockPx = 8;

struct Options {
  std::string run_dir, out, loss = "weighted";
};

struct Extraction {
  std::vector<brdf::BrdfSample> samples;
  int pose_frames = 0, dark_frames = 0, clipped = 0, below_horizon = 0;
};

cv::Mat CentralBlock(const cv::Mat& frame) {
  const int x = (frame.cols - kBlockPx) / 2, y = (frame.rows - kBlockPx) / 2;
  cv::Mat block;
  frame(cv::Rect(x, y, kBlockPx, kBlockPx)).convertTo(block, CV_64F);
  return block;
}

Extraction ExtractSamples(const std::string& run_dir, const daemon::RunManifest& manifest) {
  Extraction out;
  if (manifest.lights.empty()) throw std::runtime_error(run_dir + "/manifest.json: the run has no lamp");
  double dark_sum = 0.0;
  for (const daemon::FrameRecord& r : manifest.frames)
    if (r.kind == "dark") {
      dark_sum += cv::mean(CentralBlock(daemon::LoadFrame(run_dir, r)))[0];
      ++out.dark_frames;
    }
  // Without dark frames the black level stays in the signal; say so rather than guess it.
  if (out.dark_frames == 0) throw std::runtime_error(run_dir + ": no dark frames to subtract (add a dark step)");
  const double dark_dn = dark_sum / out.dark_frames;
  for (const daemon::FrameRecord& r : manifest.frames) {
    if (r.kind != "pose" || !r.pose) continue;
    ++out.pose_frames;
    const cv::Mat block = CentralBlock(daemon::LoadFrame(run_dir, r));
    double max_dn;
    cv::minMaxLoc(block, nullptr, &max_dn);
    const int bits = r.bit_depth > 0 ? r.bit_depth : manifest.bit_depth;
    if (max_dn >= std::ldexp(1.0, bits) - 1.0) {
      ++out.clipped;
      continue;
    }
    const brdf::DirectionPair dirs =
        brdf::ArmDirections({r.pose->light_arm_deg, r.pose->camera_arm_deg, r.pose->sample_rotation_deg});
    if (dirs.wi.z() <= 0.0 || dirs.wo.z() <= 0.0) {
      ++out.below_horizon;
      continue;
    }
    cv::Scalar mean, sd;
    cv::meanStdDev(block, mean, sd);
    const double level = r.level > 0.0 ? r.level : 1.0;
    const double scale = manifest.lights[0].intensity * level * manifest.dn_per_radiance_per_us * r.exposure_us *
                         std::pow(10.0, r.gain_db / 20.0) * dirs.wi.z();
    brdf::BrdfSample s;
    s.wi = dirs.wi;
    s.wo = dirs.wo;
    s.value.setConstant((mean[0] - dark_dn) / scale);
    s.sigma.setConstant(std::max(sd[0], 0.5) / std::sqrt(double(block.total())) / scale);  // >= half a DN
    out.samples.push_back(s);
  }
  return out;
}

int Execute(const Options& options) {
  nlohmann::json doc = {{"run", options.run_dir}};
  // The report is also the command's --json document (main adds command, ok, exit_code).
  auto finish = [&](ExitCode code, const std::string& error) {
    ResultFields() = doc;
    return error.empty() ? static_cast<int>(code) : Fail(code, error);
  };
  brdf::SelectionOptions selection;
  selection.fit.loss = options.loss == "log" ? brdf::FitLoss::kLog : brdf::FitLoss::kWeighted;
  Extraction extraction;
  try {
    extraction = ExtractSamples(options.run_dir, daemon::LoadRunManifest(options.run_dir));
  } catch (const std::exception& e) {
    return finish(kExitUsage, e.what());
  }
  doc["pose_frames"] = extraction.pose_frames;
  doc["samples"] = extraction.samples.size();
  doc["clipped_frames"] = extraction.clipped;
  doc["below_horizon_frames"] = extraction.below_horizon;
  if (extraction.samples.empty()) return finish(kExitFailed, "no usable pose frames");
  const brdf::SelectionSummary s = brdf::SelectModel(extraction.samples, selection);
  doc.update(SelectionJson(s));

  const std::string out = options.out.empty() ? (fs::path(options.run_dir) / "results" / "brdf").string() : options.out;
  fs::create_directories(out);
  std::ofstream(fs::path(out) / "report.json") << doc.dump(2) << "\n";
  const solvers::Summary written = brdf::WriteSamplesCsv((fs::path(out) / "samples.csv").string(), extraction.samples);
  if (!written.IsSolutionUsable()) return finish(kExitFailed, written.message);
  doc["results"] = out;

  FILE* text = stdout;  // under --json main points it at stderr
  std::fprintf(text, "%zu samples from %d pose frames (%d clipped, %d below the horizon), closest theta_h %.1f deg\n",
               extraction.samples.size(), extraction.pose_frames, extraction.clipped, extraction.below_horizon,
               s.min_theta_h_deg);
  PrintSelection(text, s);
  std::fprintf(text, "results: %s/\n", out.c_str());
  return finish(s.IsSolutionUsable() ? kExitOk : kExitFailed, s.IsSolutionUsable() ? "" : s.message);
}

CommandRunner Setup(CLI::App& app) {
  auto options = std::make_shared<Options>();
  CLI::App* solve = SubcommandGroup(app, "solve", "run a solver on stored data");
  CLI::App* sub = solve->add_subcommand("brdf", "fit BRDF models to a gonioreflectometer run and choose one");
  sub->add_option("--run", options->run_dir, "run directory")->required()->check(CLI::ExistingDirectory);
  sub->add_option("--loss", options->loss, "weighted (by each sample's deviation, default) | log")
      ->check(CLI::IsMember({"weighted", "log"}));
  sub->add_option("--out", options->out, "output directory (default: RUN/results/brdf)");
  return {sub, [options] { return Execute(*options); }};
}

const bool registered = RegisterCommand(Setup);

}  // namespace
}  // namespace photorig::app
