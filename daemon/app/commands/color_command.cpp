// photorig calibrate color (--image CHART [--dark DARK] | --sim-camera NAME) [--rig RIG.yaml] [--illuminant D65]
//                          [--chart-roi ...] [--no-detect] [--bayer RGGB] [--white-level DN] [--black-level DN]
//                          [--loss xyz|ciede2000] [--models a,b,...] --out DIR
// photorig apply-color --model MODEL --in IMAGE... [--dark DARK] [--bayer RGGB] [--black-level DN] [--exposure-ratio R]
//                      --out DIR

#include "../command.h"
#include "../command_output.h"
#include "../progress_display.h"
#include "photorig/solvers/color/apply.h"
#include "photorig/solvers/color/calibration.h"
#include "photorig/solvers/color/model_io.h"
#include "photorig/daemon/io/image_io.h"
#include "photorig/config/rig.h"
#include "photorig/config/sim.h"
#include "photorig/config/yaml_node.h"
#include "photorig/sim/color_chart.h"

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>

namespace photorig::app {
namespace {

namespace fs = std::filesystem;

// The image a colour operation produced, or std::invalid_argument naming `what`
// and the solver's reason: the commands report it and exit 2.
cv::Mat Produced(const solvers::core::Summary& summary, cv::Mat image, const std::string& what) {
  if (!summary.IsSolutionUsable()) throw std::invalid_argument(what + ": " + summary.message);
  return image;
}

// A name a parser rejected, as std::invalid_argument listing the known ones.
template <typename T>
T Known(const std::optional<T>& parsed, const std::string& kind, const std::string& name, const std::string& known) {
  if (!parsed) throw std::invalid_argument("unknown " + kind + " '" + name + "' (known: " + known + ")");
  return *parsed;
}

struct CalibrateOptions {
  std::string image, dark, sim_camera, rig, chart_roi, bayer, out;
  solvers::color::Illuminant illuminant = solvers::color::Illuminant::kD65;
  solvers::color::FitLoss loss = solvers::color::FitLoss::kXyzLeastSquares;
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

// The simulated rig's chart capture: spectral render, raw frame and dark frame
// written to `out`. With a rig, its sensor and frame size are used and the chart
// lies where the rig's camera.color_chart says; otherwise a bare chart.
void RenderSimulatedChart(CalibrateOptions& options, solvers::color::Illuminant illuminant,
                          const std::optional<config::RigConfig>& rig) {
  // ExecuteCalibrate checked the camera's name.
  const solvers::color::ChartCaptureSpectra s =
      solvers::color::ChartCaptureSpectraFor(options.sim_camera, illuminant, solvers::color::WavelengthGrid(400.0, 680.0, 5.0))
          .value();
  sim::SensorModel sensor;
  sim::ChartGeometry geometry;
  if (rig) {
    sensor = rig->sim->sensor;
    const auto& corners = rig->camera.color_chart->corners_px;
    const Eigen::Vector2d low = corners[0].cwiseMin(corners[1]).cwiseMin(corners[2]).cwiseMin(corners[3]);
    const Eigen::Vector2d high = corners[0].cwiseMax(corners[1]).cwiseMax(corners[2]).cwiseMax(corners[3]);
    geometry = sim::ChartGeometry::PlacedIn(cv::Rect2d(low.x(), low.y(), high.x() - low.x(), high.y() - low.y()),
                                            cv::Size(rig->camera.width, rig->camera.height));
  }
  const sim::ChartRender render = sim::RenderColorChart({s.wavelength_nm, s.patch_reflectance, s.illuminant, s.camera_sensitivity},
                                                        geometry, sensor, sim::ExposureForWhite(sensor, 0.8), 0.0,
                                                        options.seed);
  options.image = (fs::path(options.out) / "chart.png").string();
  options.dark = (fs::path(options.out) / "dark.png").string();
  const bool mosaic = !options.bayer.empty();
  daemon::WriteImage(options.image, mosaic ? sim::BayerMosaic(render.raw, options.bayer) : render.raw);
  daemon::WriteImage(options.dark, mosaic ? sim::BayerMosaic(render.dark, options.bayer) : render.dark);
  if (options.white_level == 0.0) options.white_level = render.clip_level_dn;
  std::printf("rendered %s chart under %s%s: %s, %s\n", options.sim_camera.c_str(), solvers::color::IlluminantName(illuminant),
              mosaic ? (" through a " + options.bayer + " Bayer mosaic").c_str() : "", options.image.c_str(),
              options.dark.c_str());
}

// The means of a one-channel image's four 2x2 phases (top-left, top-right,
// bottom-left, bottom-right) above its darkest pixel, when they differ by
// more than a tenth: behind a colour filter array the red, green and blue
// sites see different light, while a monochrome image's phases sample the
// same scene and agree to a percent or so.
std::optional<std::array<double, 4>> MosaicPhaseMeans(const cv::Mat& image) {
  if (image.channels() != 1 || image.rows < 4 || image.cols < 4) return std::nullopt;
  cv::Mat values;
  image.convertTo(values, CV_64F);
  double darkest = 0.0;
  cv::minMaxLoc(values, &darkest);
  std::array<double, 4> means{};
  std::array<long, 4> counts{};
  for (int y = 0; y < values.rows; ++y) {
    const double* row = values.ptr<double>(y);
    for (int x = 0; x < values.cols; ++x) {
      means[(y % 2) * 2 + x % 2] += row[x] - darkest;
      ++counts[(y % 2) * 2 + x % 2];
    }
  }
  for (int i = 0; i < 4; ++i) means[i] /= double(counts[i]);
  const auto [low, high] = std::minmax_element(means.begin(), means.end());
  if (!(*high > 0.0) || *high - *low < 0.1 * *high) return std::nullopt;
  return means;
}

// A one-channel Bayer raw becomes B, G, R; anything else is returned as read.
cv::Mat ReadCapture(const std::string& path, const std::string& bayer) {
  cv::Mat image = daemon::ReadImage(path);
  if (bayer.empty()) {
    if (const auto means = MosaicPhaseMeans(image)) {
      char figures[160];
      std::snprintf(figures, sizeof(figures), "%.0f, %.0f, %.0f and %.0f DN", (*means)[0], (*means)[1], (*means)[2],
                    (*means)[3]);
      throw std::invalid_argument(
          path + " looks like a raw Bayer mosaic: one channel whose 2x2 phases average " + figures +
          " above black; pass --bayer with the colours of its top-left 2x2 block (RGGB, BGGR, GRBG or GBRG)");
    }
    return image;
  }
  if (image.channels() != 1)
    throw std::invalid_argument(path + ": --bayer needs a one-channel raw, got " + std::to_string(image.channels()) +
                                " channels");
  cv::Mat bgr;
  const solvers::core::Summary demosaiced = solvers::color::Demosaic(image, bayer, &bgr);
  return Produced(demosaiced, bgr, path + ": --bayer " + bayer);
}

int ExecuteCalibrate(CalibrateOptions options) {
  if (options.image.empty() == options.sim_camera.empty()) {
    return Fail(kExitUsage, "give exactly one of --image or --sim-camera");
  }
  const solvers::color::Illuminant illuminant = options.illuminant;
  solvers::color::LocateOptions locate;
  solvers::color::CalibrationOptions calibration;
  std::optional<config::RigConfig> rig;
  try {
    calibration.loss = options.loss;
    if (!options.models.empty()) {
      calibration.candidates.clear();
      for (const auto& name : options.models) {
        calibration.candidates.push_back(
            Known(solvers::color::ModelSpec::Parse(name), "colour model", name, solvers::color::ModelSpec::KnownNames()));
      }
    }
    if (!options.rig.empty()) {
      rig = config::LoadRigConfig(options.rig);
      if (const auto& chart = rig->camera.color_chart) {
        std::array<cv::Point2f, 4> corners;
        for (std::size_t i = 0; i < 4; ++i)
          corners[i] = cv::Point2f(static_cast<float>(chart->corners_px[i].x()), static_cast<float>(chart->corners_px[i].y()));
        locate.fixed_corners = corners;
        locate.fixed_source = options.rig + " camera.color_chart";
      }
    }
    if (!options.chart_roi.empty()) {
      std::string why;
      locate.fixed_corners = solvers::color::ParseChartCorners(options.chart_roi, &why);
      if (!locate.fixed_corners)
        return Fail(kExitUsage, "--chart-roi " + options.chart_roi + ": " + why +
                                    "; give the chart's outer corners in image pixels as x,y,w,h or "
                                    "x0,y0,x1,y1,x2,y2,x3,y3 (top-left first, then clockwise)");
      locate.fixed_source = "--chart-roi " + options.chart_roi;
    }
    if (!options.sim_camera.empty()) {
      std::string cameras;
      for (const std::string& name : solvers::color::CameraNames()) cameras += (cameras.empty() ? "" : ", ") + name;
      Known(solvers::color::CameraDescription(options.sim_camera), "camera", options.sim_camera, cameras);
      if (rig && !(rig->sim && rig->camera.color_chart))
        throw std::invalid_argument(options.rig + ": --sim-camera with --rig needs a simulated rig with camera.color_chart");
    }
  } catch (const config::ConfigError& e) {
    return Fail(kExitUsage, e.what());
  } catch (const std::invalid_argument& e) {
    return Fail(kExitUsage, e.what());
  }
  locate.use_detector = !options.no_detect;
  fs::create_directories(options.out);
  cv::Mat image, dark;
  try {
    if (!options.sim_camera.empty()) RenderSimulatedChart(options, illuminant, rig);
    image = ReadCapture(options.image, options.bayer);
    if (!options.dark.empty()) dark = ReadCapture(options.dark, options.bayer);
  } catch (const std::exception& e) {
    return Fail(kExitUsage, e.what());
  }
  solvers::color::MeasureOptions measure;
  measure.clip_level = options.white_level;
  measure.black_level = options.black_level;
  ProgressDisplay progress;
  calibration.progress = progress.Callback();
  const solvers::color::ChartCalibration result =
      solvers::color::CalibrateChartImage(image, dark, illuminant, locate, measure, calibration);
  progress.EndLine();

  std::vector<std::string> names(solvers::color::ColorChecker24Names().begin(), solvers::color::ColorChecker24Names().end());
  std::printf("%s\n", result.located.message.c_str());
  std::printf("%s", solvers::color::FormatCalibrationReport(result.summary, names).c_str());
  nlohmann::json report = solvers::color::CalibrationReport(result.summary, result.patches, names);
  report["image"] = options.image;
  report["dark"] = options.dark;
  report["illuminant"] = solvers::color::IlluminantName(illuminant);
  report["chart_location"] = result.located.message;
  if (result.located.location) {
    report["chart_location_method"] = result.located.location->method;
    nlohmann::json corners = nlohmann::json::array();
    for (const cv::Point2f& p : result.located.location->corners) corners.push_back({p.x, p.y});
    report["chart_corners_px"] = corners;
  }
  if (!options.bayer.empty()) report["bayer"] = options.bayer;
  if (!options.rig.empty()) report["rig"] = options.rig;
  daemon::WriteFileDurably((fs::path(options.out) / "report.json").string(), report.dump(2) + "\n");
  daemon::WriteFileDurably((fs::path(options.out) / "report.txt").string(),
                           solvers::color::FormatCalibrationReport(result.summary, names));
  ResultFields()["out"] = options.out;
  ResultFields()["report"] = report;
  if (!result.summary.IsSolutionUsable()) return Fail(kExitFailed, "no usable colour model: " + result.summary.message);

  const solvers::color::ColorModel& model = result.summary.chosen_model();
  for (const char* name : {"model.json", "model.yaml"}) {
    const std::string path = (fs::path(options.out) / name).string();
    daemon::WriteFileDurably(path, solvers::color::SerializeModel(model, path));
  }
  solvers::color::ApplyOptions apply;
  apply.black_level = options.black_level;
  cv::Mat xyz, srgb;
  const solvers::core::Summary corrected = solvers::color::CameraToXyz(model, image, dark, apply, &xyz);
  const solvers::core::Summary encoded =
      corrected.IsSolutionUsable() ? solvers::color::XyzToSrgb8(xyz, model.white_xyz, &srgb) : corrected;
  if (!encoded.IsSolutionUsable()) {
    return Fail(kExitFailed, "applying the model to " + options.image + " failed: " + encoded.message);
  }
  daemon::WriteImage((fs::path(options.out) / "corrected_srgb.png").string(), srgb);
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
    if (!options.dark.empty()) dark = ReadCapture(options.dark, options.bayer);
  } catch (const std::invalid_argument& e) {
    return Fail(kExitUsage, e.what());
  }
  fs::create_directories(options.out);
  for (const std::string& input : options.inputs) {
    cv::Mat image;
    try {
      image = ReadCapture(input, options.bayer);
    } catch (const std::invalid_argument& e) {
      return Fail(kExitUsage, e.what());
    }
    if (image.channels() != 3)
      return Fail(kExitUsage, input + " has " + std::to_string(image.channels()) +
                                  " channel(s); colour correction needs 3 (B, G, R)");
    cv::Mat xyz, srgb;
    const solvers::core::Summary corrected = solvers::color::CameraToXyz(model, image, dark, apply, &xyz);
    const solvers::core::Summary encoded =
        corrected.IsSolutionUsable() ? solvers::color::XyzToSrgb8(xyz, model.white_xyz, &srgb) : corrected;
    if (!encoded.IsSolutionUsable()) return Fail(kExitUsage, input + ": " + encoded.message);
    const std::string stem = (fs::path(options.out) / fs::path(input).stem()).string();
    daemon::WriteFloatTiff(stem + "_xyz.tiff", xyz);
    daemon::WriteImage(stem + "_srgb.png", srgb);
    std::printf("%s -> %s_xyz.tiff, %s_srgb.png\n", input.c_str(), stem.c_str(), stem.c_str());
    ResultFields()["outputs"].push_back({{"input", input}, {"xyz", stem + "_xyz.tiff"}, {"srgb", stem + "_srgb.png"}});
  }
  return kExitOk;
}

CLI::App* SetupCalibrate(CLI::App& app, CalibrateOptions* options) {
  CLI::App* sub =
      CalibrateGroup(app)->add_subcommand("color", "colour-correction model from a 24-patch ColorChecker capture");
  sub->add_option("--image", options->image, "chart capture (B, G, R; 8/16-bit or float)")->check(CLI::ExistingFile);
  sub->add_option("--dark", options->dark, "dark frame at the same exposure")->check(CLI::ExistingFile);
  sub->add_option("--sim-camera", options->sim_camera,
                  "render the chart on the simulated rig with this camera (nikon-5100, sigma-sdmerill, canon-5d-mark-ii)");
  sub->add_option("--seed", options->seed, "noise seed for --sim-camera");
  AddChoice(sub, "--illuminant", &options->illuminant, solvers::color::kIlluminantNames, "light on the chart");
  sub->add_option("--rig", options->rig,
                  "rig YAML: its camera.color_chart is the fixed chart position (with --sim-camera: the rig's "
                  "sensor, frame and chart placement)")
      ->check(CLI::ExistingFile);
  sub->add_option("--chart-roi", options->chart_roi,
                  "where the chart sits: x,y,w,h or x0,y0,...,x3,y3 (grid corners); overrides the rig's");
  sub->add_flag("--no-detect", options->no_detect, "skip the mcc detector; use --chart-roi or the rig's position");
  sub->add_option("--bayer", options->bayer,
                  "captures are one-channel Bayer raws with this top-left block (RGGB, BGGR, GRBG, GBRG); "
                  "demosaiced before measuring (with --sim-camera: render through this mosaic)");
  sub->add_option("--white-level", options->white_level, "raw value at which pixels clip (default: type maximum)");
  sub->add_option("--black-level", options->black_level, "subtracted when there is no dark frame");
  AddChoice(sub, "--loss", &options->loss, solvers::color::kFitLossNames,
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
