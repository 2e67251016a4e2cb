// photorig.calibrate_lights, calibrate_leds, calibrate_color and
// calibrate_camera: `photorig calibrate lights --run`, `calibrate leds`,
// `calibrate color` and `calibrate camera` in-process, through the same
// pipelines (light_calibration.h, led_positions.h, color_calibration.h,
// camera_calibration.h), which write their results folders and rigs as the
// CLI does.

#include "arrays.h"
#include "bindings.h"
#include "choices.h"
#include "photorig/daemon/pipelines/camera_calibration.h"
#include "photorig/daemon/pipelines/color_calibration.h"
#include "photorig/daemon/pipelines/led_positions.h"
#include "photorig/daemon/pipelines/light_calibration.h"
#include "progress.h"
#include "run.h"

#include <pybind11/stl.h>  // std::optional, std::array and std::vector options

#include <array>
#include <limits>
#include <type_traits>

namespace photorig::python {
namespace {

namespace lighting = solvers::lighting;

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

// The request the CLI builds from its flags; checked once the run's camera is
// in (CalibrateLights below).
config::LightCalibrationRequest LightRequestOf(const std::optional<std::array<double, 3>>& circle,
                                               const std::optional<std::string>& silhouette_image,
                                               double sphere_radius_mm, const std::optional<std::string>& rig,
                                               const std::optional<std::string>& out_rig) {
  config::LightCalibrationRequest request;
  if (circle) request.circle = lighting::Circle{(*circle)[0], (*circle)[1], (*circle)[2]};
  request.silhouette_image = silhouette_image.value_or("");
  request.sphere_radius_mm = sphere_radius_mm;
  request.base_rig = rig.value_or("");
  request.out_rig = out_rig.value_or("");
  return request;
}

// field(e) of each estimate, NaN where it is not usable: (n,) for a number,
// (n, 3) for a vector.
template <typename Estimate, typename Field>
py::array WhereUsable(const std::vector<Estimate>& estimates, Field field) {
  if constexpr (std::is_same_v<decltype(field(estimates.front())), double>) {
    py::array_t<double> values(static_cast<py::ssize_t>(estimates.size()));
    for (std::size_t k = 0; k < estimates.size(); ++k)
      values.mutable_at(k) = estimates[k].usable ? field(estimates[k]) : kNan;
    return values;
  } else {
    std::vector<Eigen::Vector3d> vectors;
    for (const Estimate& e : estimates)
      vectors.push_back(e.usable ? Eigen::Vector3d(field(e)) : Eigen::Vector3d::Constant(kNan));
    return VectorsToArray(vectors);
  }
}

template <typename Estimate>
py::array_t<bool> UsableOf(const std::vector<Estimate>& estimates) {
  py::array_t<bool> usable(static_cast<py::ssize_t>(estimates.size()));
  for (std::size_t k = 0; k < estimates.size(); ++k) usable.mutable_at(k) = estimates[k].usable;
  return usable;
}

// What lights.lp and the DiLiGenT files hold for the usable lights.
void AddEstimates(const daemon::LightCalibrationEstimates& estimates, py::dict* out) {
  const auto& directions = estimates.directions;
  (*out)["direction"] = WhereUsable(directions, [](const auto& e) { return e.direction; });
  (*out)["uncertainty_deg"] = WhereUsable(directions, [](const auto& e) { return e.uncertainty_deg; });
  (*out)["usable"] = UsableOf(directions);
  if (estimates.intensities.empty()) return;
  (*out)["rgb_intensity"] = WhereUsable(estimates.intensities, [](const auto& e) { return e.rgb; });
  // As the calibrated rig's `intensity`.
  (*out)["intensity"] = WhereUsable(estimates.intensities, [](const auto& e) { return e.rgb.mean(); });
}

py::dict CalibrateLights(const std::string& run_directory, config::LightCalibrationRequest request,
                         const lighting::CameraModel& camera, const std::vector<std::string>& white_images,
                         const std::optional<std::string>& out) {
  const std::string destination = ResultsFolder(run_directory, out, "lights");
  daemon::LightCalibrationSummary summary;
  daemon::LightCalibrationEstimates estimates;
  {
    py::gil_scoped_release unlocked;
    daemon::LightCalibrationInputs inputs = daemon::LoadLightCalibrationInputs(run_directory);
    daemon::LoadWhiteFrames(white_images, &inputs);  // std::invalid_argument: ValueError
    request.camera = daemon::SphereCamera(inputs, camera);
    // Checked here, with the run's camera in, to raise rather than return a failed summary.
    if (std::string why; !request.IsValid(&why)) throw std::invalid_argument(why);
    summary = daemon::CalibrateLights(inputs, request, destination, &estimates);
  }
  py::dict out_dict;
  out_dict["summary"] = ToPython(daemon::ToJson(summary));
  out_dict["directory"] = destination;
  if (!estimates.directions.empty()) AddEstimates(estimates, &out_dict);
  return out_dict;
}

// The request `photorig calibrate leds` builds from its flags, refused with IsValid's message.
config::LedPositionRequest LedRequestOf(const std::vector<std::vector<double>>& spheres, double sphere_radius_mm,
                                        const std::optional<std::string>& rig, const std::optional<std::string>& out_rig) {
  config::LedPositionRequest request;
  for (const std::vector<double>& centre : spheres) {
    if (centre.size() != 2 && centre.size() != 3)
      throw py::value_error("each sphere centre is (x, y) or (x, y, z) in mm, not " + std::to_string(centre.size()) +
                            " numbers");
    request.sphere_centres_mm.emplace_back(centre[0], centre[1], centre.size() == 3 ? centre[2] : 0.0);
  }
  request.sphere_radius_mm = sphere_radius_mm;
  request.base_rig = rig.value_or("");
  request.out_rig = out_rig.value_or("");
  if (std::string why; !request.IsValid(&why)) throw py::value_error(why);
  return request;
}

py::dict CalibrateLeds(const std::string& run_directory, const config::LedPositionRequest& request,
                       const std::optional<std::string>& out) {
  const std::string destination = ResultsFolder(run_directory, out, "leds");
  daemon::LedPositionCalibration result;
  {
    py::gil_scoped_release unlocked;
    result = daemon::CalibrateLedPositions(daemon::LoadLedPositionInputs(run_directory), request, destination);
  }
  if (result.bad_input) throw py::value_error(result.message);
  py::dict calibrated;
  calibrated["summary"] = ToPython(daemon::ToJson(result));
  calibrated["directory"] = destination;
  const auto& leds = result.solve.leds;
  calibrated["position_mm"] = WhereUsable(leds, [](const auto& e) { return e.position_mm; });
  calibrated["rms_ray_distance_mm"] = WhereUsable(leds, [](const auto& e) { return e.rms_ray_distance_mm; });
  calibrated["predicted_sigma_mm"] = WhereUsable(leds, [](const auto& e) { return e.predicted_sigma_mm; });
  calibrated["usable"] = UsableOf(leds);
  return calibrated;
}

namespace color = solvers::color;

// Per patch, NaN where a patch was not used.
py::array_t<double> ValuesToArray(const std::vector<double>& values) {
  return py::array_t<double>(static_cast<py::ssize_t>(values.size()), values.data());
}

py::dict CalibrateColor(const daemon::ColorCalibrationRequest& request, const std::string& out, ProgressBridge* bridge) {
  daemon::ColorCalibrationResult result;
  {
    py::gil_scoped_release unlocked;
    result = daemon::CalibrateColor(request, out);  // std::invalid_argument: ValueError
  }
  bridge->RethrowIfFailed();
  py::dict calibrated;
  calibrated["summary"] = ToPython(result.report);
  calibrated["directory"] = out;
  std::vector<Eigen::Vector3d> rgb;
  for (const color::PatchMeasurement& patch : result.chart.patches) rgb.push_back(patch.rgb);
  calibrated["patch_rgb"] = VectorsToArray(rgb);
  const color::CalibrationSummary& summary = result.chart.summary;
  calibrated["model"] = py::none();
  if (!summary.IsSolutionUsable()) return calibrated;
  const color::ModelEvaluation& chosen = summary.models.at(static_cast<std::size_t>(summary.chosen));
  calibrated["model"] = chosen.spec.Name();
  std::vector<Eigen::Vector3d> terms;  // the XYZ coefficients of each term, (terms, 3)
  for (Eigen::Index t = 0; t < chosen.model.coefficients.rows(); ++t)
    terms.push_back(chosen.model.coefficients.row(t).transpose());
  calibrated["coefficients"] = VectorsToArray(terms);
  calibrated["input_scale"] = chosen.model.input_scale;
  calibrated["white_xyz"] = py::array_t<double>(3, chosen.model.white_xyz.data());
  calibrated["training_de"] = ValuesToArray(chosen.training_de);
  calibrated["held_out_de"] = ValuesToArray(chosen.held_out_de);
  return calibrated;
}

// `photorig calibrate camera`'s request; bad options raise ValueError with
// IsValid's message.
daemon::CameraCalibrationRequest CameraRequestOf(const std::vector<std::string>& images, const std::array<int, 2>& board,
                                                 double square_mm, int plane_image, const std::string& rig,
                                                 const std::string& out_rig, const std::string& distortion) {
  daemon::CameraCalibrationRequest request;
  solvers::camera::CheckerboardCalibrationOptions& options = request.options;
  options.inner_corners_cols = board[0];
  options.inner_corners_rows = board[1];
  options.square_mm = square_mm;
  options.plane_image = plane_image;
  if (distortion != "auto")
    options.distortion = ParseChoice(solvers::camera::kDistortionModelNames, distortion, "distortion (or auto)");
  if (std::string why; !options.IsValid(&why)) throw py::value_error(why);
  request.images = images;
  request.base_rig = rig;
  request.out_rig = out_rig;
  return request;
}

py::dict CalibrateCamera(daemon::CameraCalibrationRequest request, ProgressBridge* bridge) {
  request.options.progress = bridge->Callback();
  daemon::CameraCalibrationResult result;
  {
    py::gil_scoped_release unlocked;
    result = daemon::CalibrateCamera(request);  // std::invalid_argument: ValueError
  }
  bridge->RethrowIfFailed();
  const solvers::core::Termination termination = result.summary.termination;
  if (termination == solvers::core::Termination::kInvalidOptions ||
      termination == solvers::core::Termination::kInvalidInput)
    throw py::value_error(result.summary.message);
  py::dict calibrated;
  calibrated["summary"] = ToPython(daemon::ToJson(result, request));
  calibrated["out_rig"] = result.rig_written ? py::cast(request.out_rig) : py::none();
  calibrated["distortion_model"] =
      solvers::core::NameOf(solvers::camera::kDistortionModelNames, result.summary.distortion_model);
  return calibrated;
}

}  // namespace

void BindCalibration(py::module_& m) {
  const config::LightCalibrationRequest defaults;
  m.def(
      "calibrate_lights",
      [](py::object run, std::optional<std::array<double, 3>> circle, std::optional<std::string> silhouette_image,
         double sphere_radius_mm, const std::string& camera, double fx_px, double fy_px, double cx_px, double cy_px,
         const std::vector<std::string>& white_images, std::optional<std::string> rig,
         std::optional<std::string> out_rig, const std::optional<std::string>& out) {
        lighting::CameraModel given;
        given.projection = ParseChoice(lighting::CameraModel::kProjectionNames, camera, "camera");
        given.fx_px = fx_px;
        given.fy_px = fy_px;
        given.cx_px = cx_px;
        given.cy_px = cy_px;
        return CalibrateLights(RunDirectory(run),
                               LightRequestOf(circle, silhouette_image, sphere_radius_mm, rig, out_rig), given,
                               white_images, out);
      },
      py::arg("run"), py::kw_only(), py::arg("circle") = py::none(), py::arg("silhouette_image") = py::none(),
      py::arg("sphere_radius_mm") = defaults.sphere_radius_mm,
      py::arg("camera") = solvers::core::NameOf(lighting::CameraModel::kProjectionNames, defaults.camera.projection),
      py::arg("fx_px") = defaults.camera.fx_px, py::arg("fy_px") = defaults.camera.fy_px,
      py::arg("cx_px") = defaults.camera.cx_px, py::arg("cy_px") = defaults.camera.cy_px,
      py::arg("white_images") = std::vector<std::string>{}, py::arg("rig") = py::none(),
      py::arg("out_rig") = py::none(), py::arg("out") = py::none(),
      "Light directions from a run of a mirror sphere, one frame per LED, as `photorig calibrate lights --run`: "
      "writes the same results folder (out, default RUN/results/lights) and returns direction (n, 3), "
      "uncertainty_deg and usable per light (NaN rows: unusable), rgb_intensity and intensity with white_images, "
      "summary, the CLI's JSON result, and directory. Options are LightCalibrationRequest's: circle (cx, cy, r px), "
      "silhouette_image, sphere_radius_mm, camera with fx_px, fy_px, cx_px, cy_px, rig and out_rig (a copy of rig "
      "with the calibrated lights).");

  m.def(
      "calibrate_leds",
      [](py::object run, const std::vector<std::vector<double>>& spheres, double sphere_radius_mm,
         const std::optional<std::string>& rig, const std::optional<std::string>& out_rig,
         const std::optional<std::string>& out) {
        return CalibrateLeds(RunDirectory(run), LedRequestOf(spheres, sphere_radius_mm, rig, out_rig), out);
      },
      py::arg("run"), py::kw_only(), py::arg("spheres"), py::arg("sphere_radius_mm"), py::arg("rig") = py::none(),
      py::arg("out_rig") = py::none(), py::arg("out") = py::none(),
      "A near-LED dome's LED positions from a run of two or more mirror spheres at known places, one frame per "
      "LED, as `photorig calibrate leds`: writes the same results folder (out, default RUN/results/leds) and "
      "returns position_mm (n, 3) in the dome frame, rms_ray_distance_mm, predicted_sigma_mm and usable per LED "
      "(NaN rows: unusable), summary, the CLI's JSON result, and directory. Options are LedPositionRequest's: "
      "spheres ((x, y) or (x, y, z) mm each), sphere_radius_mm, rig and out_rig.");

  const color::CalibrationOptions fit;
  const daemon::ColorCalibrationRequest chart;
  m.def(
      "calibrate_color",
      [](const std::optional<std::string>& image, const std::string& out, const std::optional<std::string>& dark,
         const std::optional<std::string>& sim_camera, std::uint64_t seed, const std::string& illuminant,
         const std::optional<std::string>& rig, const std::optional<std::string>& chart_roi, bool detect,
         const std::optional<std::string>& bayer, double white_level, double black_level, const std::string& loss,
         const std::optional<std::vector<std::string>>& models, bool normalise_exposure, int white_patch,
         double max_condition_number, double min_chromaticity_spread, double selection_tolerance,
         int max_refinement_iterations, py::object progress) {
        daemon::ColorCalibrationRequest request;
        request.image = image.value_or("");
        request.dark = dark.value_or("");
        request.sim_camera = sim_camera.value_or("");
        request.seed = seed;
        request.illuminant = ParseChoice(color::kIlluminantNames, illuminant, "illuminant");
        request.rig = rig.value_or("");
        request.chart_roi = chart_roi.value_or("");
        request.detect = detect;
        request.bayer = bayer.value_or("");
        request.white_level = white_level;
        request.black_level = black_level;
        color::CalibrationOptions& options = request.calibration;
        options.loss = ParseChoice(color::kFitLossNames, loss, "loss");
        if (models) options.candidates = daemon::ParseColorModels(*models);
        options.normalise_exposure = normalise_exposure;
        options.white_patch = white_patch;
        options.max_condition_number = max_condition_number;
        options.min_chromaticity_spread = min_chromaticity_spread;
        options.selection_tolerance = selection_tolerance;
        options.max_refinement_iterations = max_refinement_iterations;
        ProgressBridge bridge(std::move(progress));
        options.progress = bridge.Callback();
        return CalibrateColor(request, out, &bridge);
      },
      py::arg("image") = py::none(), py::kw_only(), py::arg("out"), py::arg("dark") = py::none(),
      py::arg("sim_camera") = py::none(), py::arg("seed") = chart.seed,
      py::arg("illuminant") = color::IlluminantName(chart.illuminant), py::arg("rig") = py::none(),
      py::arg("chart_roi") = py::none(), py::arg("detect") = chart.detect, py::arg("bayer") = py::none(),
      py::arg("white_level") = chart.white_level, py::arg("black_level") = chart.black_level,
      py::arg("loss") = color::FitLossName(fit.loss), py::arg("models") = py::none(),
      py::arg("normalise_exposure") = fit.normalise_exposure, py::arg("white_patch") = fit.white_patch,
      py::arg("max_condition_number") = fit.max_condition_number,
      py::arg("min_chromaticity_spread") = fit.min_chromaticity_spread,
      py::arg("selection_tolerance") = fit.selection_tolerance,
      py::arg("max_refinement_iterations") = fit.max_refinement_iterations, py::arg("progress") = py::none(),
      "A colour-correction model from a ColorChecker capture (image, with dark) or the simulated rig's rendering "
      "of one (sim_camera), as `photorig calibrate color`: writes the same folder (out) and returns model (the "
      "chosen one's name, or None), coefficients (terms, 3), input_scale, white_xyz, training_de and held_out_de "
      "(CIEDE2000 per patch, NaN: not used), patch_rgb, summary (report.json's fields) and directory. Options are "
      "the CLI's and CalibrationOptions' (models: None for all).");

  const solvers::camera::CheckerboardCalibrationOptions lens;
  m.def(
      "calibrate_camera",
      [](const std::vector<std::string>& images, const std::array<int, 2>& board, double square_mm, int plane_image,
         const std::string& rig, const std::string& out_rig, const std::string& distortion, py::object progress) {
        ProgressBridge bridge(std::move(progress));
        return CalibrateCamera(CameraRequestOf(images, board, square_mm, plane_image, rig, out_rig, distortion),
                               &bridge);
      },
      py::arg("images"), py::kw_only(), py::arg("board"), py::arg("square_mm"),
      py::arg("plane_image") = lens.plane_image, py::arg("rig"), py::arg("out_rig"), py::arg("distortion") = "auto",
      py::arg("progress") = py::none(),
      "A pinhole lens from photographs of a flat checkerboard, one of them (plane_image, an index into images) "
      "lying on the sample plane, as `photorig calibrate camera`: writes out_rig (rig with the calibrated lens) "
      "when the calibration succeeds and returns summary, the CLI's JSON result (lens, deviations, rms_px, "
      "tilt_deg, corner_reach, distortion_model and every candidate's BIC), out_rig (None when none was written) "
      "and distortion_model. board: inner corners (cols, rows); distortion: auto (the model of lowest BIC) or "
      "none, k1, k1-k2, k1-k2-p1-p2, k1-k2-p1-p2-k3. Bad options, unreadable images or an existing out_rig raise "
      "ValueError; a calibration the photographs do not support returns its summary, termination \"failure\".");
}

}  // namespace photorig::python
