// photorig calibrate color (--image CHART [--dark DARK] | --sim-camera NAME) [--illuminant D65] [--chart-roi ...]
//                          [--no-detect] [--white-level DN] [--black-level DN] [--loss xyz|ciede2000]
//                          [--models a,b,...] --out DIR
// photorig apply-color --model MODEL --in IMAGE... [--dark DARK] [--black-level DN] [--exposure-ratio R] --out DIR

#include "../command.h"
#include "photorig/color/apply.h"
#include "photorig/color/calibration.h"
#include "photorig/color/model_io.h"
#include "photorig/daemon/image_io.h"
#include "photorig/sim/color_chart.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>

namespace photorig::app {
namespace {

namespace fs = std::filesystem;

struct CalibrateOptions {
  std::string image, dark, sim_camera, illuminant = "D65", chart_roi, loss = "xyz", out;
  std::vector<std::string> models;
  bool no_detect = false;
  double white_level = 0.0, black_level = 0.0;
  std::uint64_t seed = 1;
};

std::string ReadText(const std::string& path) {
  std::ifstream file(path);
  if (!file) throw std::runtime_error("cannot read " + path);
  std::stringstream text;
  text << file.rdbuf();
  return text.str();
}

// The simulated rig's chart capture: spectral render, raw frame and dark frame written to `out`.
void RenderSimulatedChart(CalibrateOptions& options, color::Illuminant illuminant) {
  const color::ChartCaptureSpectra s =
      color::ChartCaptureSpectraFor(options.sim_camera, illuminant, color::WavelengthGrid(400.0, 680.0, 5.0));
  const sim::SensorModel sensor;
  const sim::ChartRender render = sim::RenderColorChart({s.wavelength_nm, s.patch_reflectance, s.illuminant, s.camera_sensitivity},
                                                        sim::ChartGeometry{}, sensor,
                                                        sim::ExposureForWhite(sensor, 0.8), 0.0, options.seed);
  options.image = (fs::path(options.out) / "chart.png").string();
  options.dark = (fs::path(options.out) / "dark.png").string();
  daemon::WriteImage(options.image, render.raw);
  daemon::WriteImage(options.dark, render.dark);
  if (options.white_level == 0.0) options.white_level = render.clip_level_dn;
  std::printf("rendered %s chart under %s: %s, %s\n", options.sim_camera.c_str(), color::IlluminantName(illuminant),
              options.image.c_str(), options.dark.c_str());
}

int ExecuteCalibrate(CalibrateOptions options) {
  if (options.image.empty() == options.sim_camera.empty()) {
    std::fprintf(stderr, "calibrate color: give exactly one of --image or --sim-camera\n");
    return 2;
  }
  color::Illuminant illuminant;
  color::LocateOptions locate;
  color::CalibrationOptions calibration;
  try {
    illuminant = color::ParseIlluminant(options.illuminant);
    calibration.loss = color::ParseFitLoss(options.loss);
    if (!options.models.empty()) {
      calibration.candidates.clear();
      for (const auto& name : options.models) calibration.candidates.push_back(color::ModelSpec::Parse(name));
    }
    if (!options.chart_roi.empty()) locate.fixed_corners = color::ParseChartCorners(options.chart_roi);
    if (!options.sim_camera.empty()) color::CameraSensitivity(options.sim_camera);
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "calibrate color: %s\n", e.what());
    return 2;
  }
  locate.use_detector = !options.no_detect;
  fs::create_directories(options.out);
  if (!options.sim_camera.empty()) RenderSimulatedChart(options, illuminant);

  const cv::Mat image = daemon::ReadImage(options.image);
  const cv::Mat dark = options.dark.empty() ? cv::Mat() : daemon::ReadImage(options.dark);
  color::MeasureOptions measure;
  measure.clip_level = options.white_level;
  measure.black_level = options.black_level;
  const color::ChartCalibration result =
      color::CalibrateChartImage(image, dark, illuminant, locate, measure, calibration);

  std::vector<std::string> names(color::ColorChecker24Names().begin(), color::ColorChecker24Names().end());
  if (result.located.location) std::printf("%s\n", result.located.message.c_str());
  std::printf("%s", color::FormatCalibrationReport(result.summary, names).c_str());
  nlohmann::json report = color::CalibrationReport(result.summary, result.patches, names);
  report["image"] = options.image;
  report["dark"] = options.dark;
  report["illuminant"] = options.illuminant;
  report["chart_location"] = result.located.message;
  daemon::WriteFileDurably((fs::path(options.out) / "report.json").string(), report.dump(2) + "\n");
  daemon::WriteFileDurably((fs::path(options.out) / "report.txt").string(),
                           color::FormatCalibrationReport(result.summary, names));
  if (!result.summary.IsUsable()) return 3;

  const color::ColorModel& model = result.summary.chosen_model();
  for (const char* name : {"model.json", "model.yaml"}) {
    const std::string path = (fs::path(options.out) / name).string();
    daemon::WriteFileDurably(path, color::SerializeModel(model, path));
  }
  color::ApplyOptions apply;
  apply.black_level = options.black_level;
  const cv::Mat xyz = color::CameraToXyz(model, image, dark, apply);
  daemon::WriteImage((fs::path(options.out) / "corrected_srgb.png").string(), color::XyzToSrgb8(xyz, model.white_xyz));
  std::printf("wrote %s/{model.json, model.yaml, report.json, report.txt, corrected_srgb.png}\n", options.out.c_str());
  return 0;
}

struct ApplyCommandOptions {
  std::string model, dark, out;
  std::vector<std::string> inputs;
  double black_level = 0.0, exposure_ratio = 1.0;
};

int ExecuteApply(const ApplyCommandOptions& options) {
  color::ColorModel model;
  try {
    model = color::ParseModel(ReadText(options.model), options.model);
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "apply-color: %s\n", e.what());
    return 2;
  }
  color::ApplyOptions apply;
  apply.black_level = options.black_level;
  apply.exposure_ratio = options.exposure_ratio;
  const cv::Mat dark = options.dark.empty() ? cv::Mat() : daemon::ReadImage(options.dark);
  fs::create_directories(options.out);
  for (const std::string& input : options.inputs) {
    const cv::Mat image = daemon::ReadImage(input);
    if (image.channels() != 3) {
      std::fprintf(stderr, "apply-color: %s has %d channel(s); colour correction needs 3 (B, G, R)\n", input.c_str(),
                   image.channels());
      return 2;
    }
    const cv::Mat xyz = color::CameraToXyz(model, image, dark, apply);
    const std::string stem = (fs::path(options.out) / fs::path(input).stem()).string();
    daemon::WriteFloatTiff(stem + "_xyz.tiff", xyz);
    daemon::WriteImage(stem + "_srgb.png", color::XyzToSrgb8(xyz, model.white_xyz));
    std::printf("%s -> %s_xyz.tiff, %s_srgb.png\n", input.c_str(), stem.c_str(), stem.c_str());
  }
  return 0;
}

CommandRunner SetupCalibrate(CLI::App& app) {
  auto options = std::make_shared<CalibrateOptions>();
  CLI::App* calibrate = SubcommandGroup(app, "calibrate", "calibrate the rig from captured targets");
  CLI::App* sub = calibrate->add_subcommand("color", "colour-correction model from a 24-patch ColorChecker capture");
  sub->add_option("--image", options->image, "chart capture (B, G, R; 8/16-bit or float)")->check(CLI::ExistingFile);
  sub->add_option("--dark", options->dark, "dark frame at the same exposure")->check(CLI::ExistingFile);
  sub->add_option("--sim-camera", options->sim_camera,
                  "render the chart on the simulated rig with this camera (nikon-5100, sigma-sdmerill, canon-5d-mark-ii)");
  sub->add_option("--seed", options->seed, "noise seed for --sim-camera");
  sub->add_option("--illuminant", options->illuminant, "light on the chart: D50 | D65 | A");
  sub->add_option("--chart-roi", options->chart_roi, "where the chart sits: x,y,w,h or x0,y0,...,x3,y3 (grid corners)");
  sub->add_flag("--no-detect", options->no_detect, "skip the mcc detector; use --chart-roi");
  sub->add_option("--white-level", options->white_level, "raw value at which pixels clip (default: type maximum)");
  sub->add_option("--black-level", options->black_level, "subtracted when there is no dark frame");
  sub->add_option("--loss", options->loss, "xyz (least squares) | ciede2000 (refined with Ceres)");
  sub->add_option("--models", options->models, "candidates (default all): linear affine root-poly-2 root-poly-3 poly-2 poly-3")
      ->delimiter(',');
  sub->add_option("--out", options->out, "output directory")->required();
  return {sub, [options] { return ExecuteCalibrate(*options); }};
}

CommandRunner SetupApply(CLI::App& app) {
  auto options = std::make_shared<ApplyCommandOptions>();
  CLI::App* sub = app.add_subcommand("apply-color", "apply a colour model to captures or a colour albedo map");
  sub->add_option("--model", options->model, "model.json or model.yaml from calibrate color")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--in", options->inputs, "3-channel images (a capture stack, a colour albedo)")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--dark", options->dark, "dark frame")->check(CLI::ExistingFile);
  sub->add_option("--black-level", options->black_level, "subtracted when there is no dark frame");
  sub->add_option("--exposure-ratio", options->exposure_ratio, "exposure x gain relative to the chart capture")
      ->check(CLI::PositiveNumber);
  sub->add_option("--out", options->out, "output directory")->required();
  return {sub, [options] { return ExecuteApply(*options); }};
}

const bool registered_calibrate = RegisterCommand(SetupCalibrate);
const bool registered_apply = RegisterCommand(SetupApply);

}  // namespace
}  // namespace photorig::app
