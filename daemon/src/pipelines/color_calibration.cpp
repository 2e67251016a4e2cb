#include "photorig/daemon/pipelines/color_calibration.h"

#include "photorig/config/rig.h"
#include "photorig/daemon/io/image_io.h"
#include "photorig/sim/color_chart.h"
#include "photorig/solvers/color/apply.h"
#include "photorig/solvers/color/model_io.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <stdexcept>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
namespace color = solvers::color;

// The image a colour operation produced, or std::invalid_argument naming
// `what` and the solver's reason.
cv::Mat Produced(const solvers::core::Summary& summary, cv::Mat image, const std::string& what) {
  if (!summary.IsSolutionUsable()) throw std::invalid_argument(what + ": " + summary.message);
  return image;
}

// The simulated rig's chart capture: spectral render, raw frame and dark frame
// written to `out`, named in request->image and request->dark. With a rig, its
// sensor and frame size are used and the chart lies where the rig's
// camera.color_chart says; otherwise a bare chart. Returns what it rendered.
std::string RenderSimulatedChart(ColorCalibrationRequest* request, const std::optional<config::RigConfig>& rig,
                                 const std::string& out) {
  // CalibrateColor checked the camera's name.
  const color::ChartCaptureSpectra s =
      color::ChartCaptureSpectraFor(request->sim_camera, request->illuminant, color::WavelengthGrid(400.0, 680.0, 5.0))
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
                                                        request->seed);
  request->image = (fs::path(out) / "chart.png").string();
  request->dark = (fs::path(out) / "dark.png").string();
  const bool mosaic = !request->bayer.empty();
  WriteImage(request->image, mosaic ? sim::BayerMosaic(render.raw, request->bayer) : render.raw);
  WriteImage(request->dark, mosaic ? sim::BayerMosaic(render.dark, request->bayer) : render.dark);
  if (request->white_level == 0.0) request->white_level = render.clip_level_dn;
  return "rendered " + request->sim_camera + " chart under " + color::IlluminantName(request->illuminant) +
         (mosaic ? " through a " + request->bayer + " Bayer mosaic" : "") + ": " + request->image + ", " + request->dark;
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

// Where the chart sits when the detector finds nothing: chart_roi, else the
// rig's camera.color_chart. Throws std::invalid_argument for a bad chart_roi.
color::LocateOptions LocateOptionsOf(const ColorCalibrationRequest& request, const std::optional<config::RigConfig>& rig) {
  color::LocateOptions locate;
  locate.use_detector = request.detect;
  if (rig && rig->camera.color_chart) {
    std::array<cv::Point2f, 4> corners;
    for (std::size_t i = 0; i < 4; ++i)
      corners[i] = cv::Point2f(static_cast<float>(rig->camera.color_chart->corners_px[i].x()),
                               static_cast<float>(rig->camera.color_chart->corners_px[i].y()));
    locate.fixed_corners = corners;
    locate.fixed_source = request.rig + " camera.color_chart";
  }
  if (!request.chart_roi.empty()) {
    const std::string named = request.chart_roi_name + " " + request.chart_roi;
    std::string why;
    locate.fixed_corners = color::ParseChartCorners(request.chart_roi, &why);
    if (!locate.fixed_corners)
      throw std::invalid_argument(named + ": " + why +
                                  "; give the chart's outer corners in image pixels as x,y,w,h or "
                                  "x0,y0,x1,y1,x2,y2,x3,y3 (top-left first, then clockwise)");
    locate.fixed_source = named;
  }
  return locate;
}

// report.json: the calibration's report and where its input came from.
nlohmann::json ReportOf(const ColorCalibrationRequest& request, const color::ChartCalibration& result,
                        const std::vector<std::string>& names) {
  nlohmann::json report = color::CalibrationReport(result.summary, result.patches, names);
  report["image"] = request.image;
  report["dark"] = request.dark;
  report["illuminant"] = color::IlluminantName(request.illuminant);
  report["chart_location"] = result.located.message;
  if (result.located.location) {
    report["chart_location_method"] = result.located.location->method;
    nlohmann::json corners = nlohmann::json::array();
    for (const cv::Point2f& p : result.located.location->corners) corners.push_back({p.x, p.y});
    report["chart_corners_px"] = corners;
  }
  if (!request.bayer.empty()) report["bayer"] = request.bayer;
  if (!request.rig.empty()) report["rig"] = request.rig;
  return report;
}

}  // namespace

std::vector<color::ModelSpec> ParseColorModels(const std::vector<std::string>& names) {
  std::vector<color::ModelSpec> specs;
  for (const std::string& name : names) {
    const std::optional<color::ModelSpec> spec = color::ModelSpec::Parse(name);
    if (!spec)
      throw std::invalid_argument("unknown colour model '" + name + "' (known: " + color::ModelSpec::KnownNames() + ")");
    specs.push_back(*spec);
  }
  return specs;
}

cv::Mat ReadColorCapture(const std::string& path, const std::string& bayer) {
  cv::Mat image = ReadInputImage(path);
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
  const solvers::core::Summary demosaiced = color::Demosaic(image, bayer, &bgr);
  return Produced(demosaiced, bgr, path + ": --bayer " + bayer);
}

ColorCalibrationResult CalibrateColor(ColorCalibrationRequest request, const std::string& out_directory) {
  if (request.image.empty() == request.sim_camera.empty())
    throw std::invalid_argument("give exactly one of a chart image and a simulated camera");
  // The simulated camera renders its own dark frame: a given one would be overwritten unread.
  if (!request.sim_camera.empty() && !request.dark.empty())
    throw std::invalid_argument("a simulated camera renders its own dark frame: drop the dark frame " + request.dark);
  if (!std::isfinite(request.white_level) || request.white_level < 0.0 || !std::isfinite(request.black_level))
    throw std::invalid_argument("the white level (" + std::to_string(request.white_level) + ") must be >= 0 (0: the image "
                                "type's maximum) and the black level (" + std::to_string(request.black_level) +
                                ") finite");
  if (std::string why; !request.calibration.IsValid(&why)) throw std::invalid_argument(why);
  std::optional<config::RigConfig> rig;
  if (!request.rig.empty()) {
    try {
      rig = config::LoadRigConfig(request.rig);
    } catch (const config::ConfigError& e) {
      throw std::invalid_argument(e.what());
    }
  }
  const color::LocateOptions locate = LocateOptionsOf(request, rig);
  if (!request.sim_camera.empty()) {
    std::string cameras;
    for (const std::string& name : color::CameraNames()) cameras += (cameras.empty() ? "" : ", ") + name;
    if (!color::CameraDescription(request.sim_camera))
      throw std::invalid_argument("unknown camera '" + request.sim_camera + "' (known: " + cameras + ")");
    if (rig && !(rig->sim && rig->camera.color_chart))
      throw std::invalid_argument(request.rig + ": a simulated camera with a rig needs a simulated rig with "
                                  "camera.color_chart");
  }
  ColorCalibrationResult result;
  if (!request.sim_camera.empty()) {
    fs::create_directories(out_directory);
    result.rendered = RenderSimulatedChart(&request, rig, out_directory);
  }
  const cv::Mat image = ReadColorCapture(request.image, request.bayer);
  const cv::Mat dark = request.dark.empty() ? cv::Mat() : ReadColorCapture(request.dark, request.bayer);
  fs::create_directories(out_directory);

  color::MeasureOptions measure;
  measure.clip_level = request.white_level;
  measure.black_level = request.black_level;
  result.chart = color::CalibrateChartImage(image, dark, request.illuminant, locate, measure, request.calibration);
  const std::vector<std::string> names(color::ColorChecker24Names().begin(), color::ColorChecker24Names().end());
  result.report = ReportOf(request, result.chart, names);
  WriteFileDurably((fs::path(out_directory) / "report.json").string(), result.report.dump(2) + "\n");
  result.table = color::FormatCalibrationReport(result.chart.summary, names);
  WriteFileDurably((fs::path(out_directory) / "report.txt").string(), result.table);
  if (!result.chart.summary.IsSolutionUsable()) return result;

  const color::ColorModel& model = result.chart.summary.chosen_model();
  for (const char* name : {"model.json", "model.yaml"}) {
    const std::string path = (fs::path(out_directory) / name).string();
    WriteFileDurably(path, color::SerializeModel(model, path));
  }
  color::ApplyOptions apply;
  apply.black_level = request.black_level;
  cv::Mat xyz, srgb;
  const solvers::core::Summary corrected = color::CameraToXyz(model, image, dark, apply, &xyz);
  const solvers::core::Summary encoded =
      corrected.IsSolutionUsable() ? color::XyzToSrgb8(xyz, model.white_xyz, &srgb) : corrected;
  if (!encoded.IsSolutionUsable()) {
    result.apply_failure = "applying the model to " + request.image + " failed: " + encoded.message;
    return result;
  }
  WriteImage((fs::path(out_directory) / "corrected_srgb.png").string(), srgb);
  return result;
}

}  // namespace photorig::daemon
