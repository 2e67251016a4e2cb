// photorig calibrate color (--image CHART [--dark DARK] | --sim-camera NAME) [--rig RIG.yaml] [--illuminant D65]
//                          [--chart-roi ...] [--no-detect] [--bayer RGGB] [--white-level DN] [--black-level DN]
//                          [--loss xyz|ciede2000] [--models a,b,...] --out DIR
// photorig apply-color --model MODEL --in IMAGE... [--dark DARK] [--bayer RGGB] [--black-level DN] [--exposure-ratio R]
//                      --out DIR

#include "../command.h"
#include "../command_output.h"
#include "../progress_display.h"
#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/pipelines/color_calibration.h"
#include "photorig/solvers/color/apply.h"
#include "photorig/solvers/color/model_io.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>

namespace photorig::app {
namespace {

namespace fs = std::filesystem;

struct CalibrateOptions {
  daemon::ColorCalibrationRequest request;
  std::vector<std::string> models;
  bool no_detect = false;
  std::string out;
};

std::string ReadText(const std::string& path) {
  std::ifstream file(path);
  if (!file) throw std::runtime_error("cannot read " + path);
  std::stringstream text;
  text << file.rdbuf();
  return text.str();
}

int ExecuteCalibrate(CalibrateOptions options) {
  daemon::ColorCalibrationRequest& request = options.request;
  if (request.image.empty() == request.sim_camera.empty()) {
    return Fail(kExitUsage, "give exactly one of --image or --sim-camera");
  }
  request.detect = !options.no_detect;
  request.chart_roi_name = "--chart-roi";
  ProgressDisplay progress;
  request.calibration.progress = progress.Callback();
  daemon::ColorCalibrationResult result;
  try {
    if (!options.models.empty()) request.calibration.candidates = daemon::ParseColorModels(options.models);
    result = daemon::CalibrateColor(request, options.out);
  } catch (const std::invalid_argument& e) {
    progress.EndLine();
    return Fail(kExitUsage, e.what());
  }
  progress.EndLine();

  if (!result.rendered.empty()) std::printf("%s\n", result.rendered.c_str());
  std::printf("%s\n", result.chart.located.message.c_str());
  std::printf("%s", result.table.c_str());
  ResultFields()["out"] = options.out;
  ResultFields()["report"] = result.report;
  if (!result.chart.summary.IsSolutionUsable())
    return Fail(kExitFailed, "no usable colour model: " + result.chart.summary.message);
  if (!result.apply_failure.empty()) return Fail(kExitFailed, result.apply_failure);
  std::printf("wrote %s/{model.json, model.yaml, report.json, report.txt, corrected_srgb.png}\n", options.out.c_str());
  ResultFields()["model"] = (fs::path(options.out) / "model.json").string();
  return kExitOk;
}

struct ApplyCommandOptions {
  std::string model, dark, bayer, out;
  std::vector<std::string> inputs;
  double black_level = 0.0, exposure_ratio = 1.0;
};

int ExecuteApply(const ApplyCommandOptions& options) {
  solvers::color::ColorModel model;
  try {
    model = solvers::color::ParseModel(ReadText(options.model), options.model);
  } catch (const std::invalid_argument& e) {
    return Fail(kExitUsage, e.what());
  }
  solvers::color::ApplyOptions apply;
  apply.black_level = options.black_level;
  apply.exposure_ratio = options.exposure_ratio;
  cv::Mat dark;
  try {
    if (!options.dark.empty()) dark = daemon::ReadColorCapture(options.dark, options.bayer);
  } catch (const std::invalid_argument& e) {
    return Fail(kExitUsage, e.what());
  }
  // Outputs are named by their input's stem: two inputs of one stem would
  // write the same files, the second over the first.
  std::map<std::string, std::string> stems;
  for (const std::string& input : options.inputs) {
    const auto [first, inserted] = stems.emplace(fs::path(input).stem().string(), input);
    if (!inserted)
      return Fail(kExitUsage, input + " and " + first->second + " would both write " +
                                  (fs::path(options.out) / first->first).string() +
                                  "_*: rename one, or convert them into different --out folders");
  }
  fs::create_directories(options.out);
  // An input that cannot be converted is named and skipped: the others are
  // still converted, and the command fails at the end naming every one.
  std::vector<std::string> failed;
  ResultFields()["outputs"] = nlohmann::json::array();
  ResultFields()["failed"] = nlohmann::json::array();
  auto skip = [&](const std::string& input, const std::string& why) {
    std::fprintf(stderr, "apply-color: %s: skipped: %s\n", input.c_str(), why.c_str());
    ResultFields()["failed"].push_back({{"input", input}, {"error", why}});
    failed.push_back(input);
  };
  for (const std::string& input : options.inputs) {
    cv::Mat image;
    try {
      image = daemon::ReadColorCapture(input, options.bayer);
    } catch (const std::invalid_argument& e) {
      skip(input, e.what());
      continue;
    }
    if (image.channels() != 3) {
      skip(input, "has " + std::to_string(image.channels()) + " channel(s); colour correction needs 3 (B, G, R)");
      continue;
    }
    cv::Mat xyz, srgb;
    const solvers::core::Summary corrected = solvers::color::CameraToXyz(model, image, dark, apply, &xyz);
    const solvers::core::Summary encoded =
        corrected.IsSolutionUsable() ? solvers::color::XyzToSrgb8(xyz, model.white_xyz, &srgb) : corrected;
    if (!encoded.IsSolutionUsable()) {
      skip(input, encoded.message);
      continue;
    }
    const std::string stem = (fs::path(options.out) / fs::path(input).stem()).string();
    daemon::WriteFloatTiff(stem + "_xyz.tiff", xyz);
    daemon::WriteImage(stem + "_srgb.png", srgb);
    std::printf("%s -> %s_xyz.tiff, %s_srgb.png\n", input.c_str(), stem.c_str(), stem.c_str());
    ResultFields()["outputs"].push_back({{"input", input}, {"xyz", stem + "_xyz.tiff"}, {"srgb", stem + "_srgb.png"}});
  }
  if (!failed.empty()) {
    std::string names;
    for (const std::string& input : failed) names += (names.empty() ? "" : ", ") + input;
    return Fail(kExitUsage, std::to_string(failed.size()) + " of " + std::to_string(options.inputs.size()) +
                                " inputs not converted (" + names + "); the others are in " + options.out);
  }
  return kExitOk;
}

CLI::App* SetupCalibrate(CLI::App& app, CalibrateOptions* options) {
  CLI::App* sub =
      CalibrateGroup(app)->add_subcommand("color", "colour-correction model from a 24-patch ColorChecker capture");
  sub->add_option("--image", options->request.image, "chart capture (B, G, R; 8/16-bit or float)")->check(CLI::ExistingFile);
  sub->add_option("--dark", options->request.dark, "dark frame at the same exposure")->check(CLI::ExistingFile);
  sub->add_option("--sim-camera", options->request.sim_camera,
                  "render the chart on the simulated rig with this camera (nikon-5100, sigma-sdmerill, canon-5d-mark-ii)");
  sub->add_option("--seed", options->request.seed, "noise seed for --sim-camera");
  AddChoice(sub, "--illuminant", &options->request.illuminant, solvers::color::kIlluminantNames, "light on the chart");
  sub->add_option("--rig", options->request.rig,
                  "rig YAML: its camera.color_chart is the fixed chart position (with --sim-camera: the rig's "
                  "sensor, frame and chart placement)")
      ->check(CLI::ExistingFile);
  sub->add_option("--chart-roi", options->request.chart_roi,
                  "where the chart sits: x,y,w,h or x0,y0,...,x3,y3 (grid corners); overrides the rig's");
  sub->add_flag("--no-detect", options->no_detect, "skip the mcc detector; use --chart-roi or the rig's position");
  sub->add_option("--bayer", options->request.bayer,
                  "captures are one-channel Bayer raws with this top-left block (RGGB, BGGR, GRBG, GBRG); "
                  "demosaiced before measuring (with --sim-camera: render through this mosaic)");
  sub->add_option("--white-level", options->request.white_level, "raw value at which pixels clip (default: type maximum)");
  sub->add_option("--black-level", options->request.black_level, "subtracted when there is no dark frame");
  AddChoice(sub, "--loss", &options->request.calibration.loss, solvers::color::kFitLossNames,
            "xyz: least squares; ciede2000: refined with Ceres");
  sub->add_option("--models", options->models, "candidates (default all): linear affine root-poly-2 root-poly-3 poly-2 poly-3")
      ->delimiter(',');
  sub->add_option("--out", options->out, "output directory")->required();
  return sub;
}

CLI::App* SetupApply(CLI::App& app, ApplyCommandOptions* options) {
  CLI::App* sub = app.add_subcommand("apply-color", "apply a colour model to captures or a colour albedo map");
  sub->add_option("--model", options->model, "model.json or model.yaml from calibrate color")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--in", options->inputs, "3-channel images (a capture stack, a colour albedo)")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--dark", options->dark, "dark frame")->check(CLI::ExistingFile);
  sub->add_option("--bayer", options->bayer, "inputs are one-channel Bayer raws (RGGB, BGGR, GRBG, GBRG): demosaic first");
  sub->add_option("--black-level", options->black_level, "subtracted when there is no dark frame");
  sub->add_option("--exposure-ratio", options->exposure_ratio,
                  "exposure x gain relative to the chart capture; for an albedo map, 1 / (chart DN per unit albedo)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--out", options->out, "output directory")->required();
  return sub;
}

const bool registered_calibrate = RegisterCommand<CalibrateOptions, SetupCalibrate, ExecuteCalibrate>();
const bool registered_apply = RegisterCommand<ApplyCommandOptions, SetupApply, ExecuteApply>();

}  // namespace
}  // namespace photorig::app
