// photorig calibrate lights (--run DIR | --images F...) [--silhouette IMG | --circle CX,CY,R | --radius-mm R]
//   [--camera orthographic|pinhole --fx --fy --cx --cy] [--white-images F...]
//   [--rig IN.yaml --out-rig NEW.yaml] [--out DIR (default RUN/results/lights; required with --images)]
// Light directions from a mirror sphere (one image per LED), optional relative
// intensities from a white sphere, written as .lp, DiLiGenT text files, a JSON
// report and a new rig YAML (an existing file is never overwritten).

#include "../command.h"
#include "../command_output.h"
#include "calibration_outputs.h"
#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/pipelines/light_calibration.h"
#include "photorig/config/rig.h"
#include "photorig/config/sim.h"
#include "photorig/config/yaml_node.h"
#include "ps_report.h"

#include <filesystem>
#include <iostream>
#include <stdexcept>

namespace photorig::app {
namespace {

namespace fs = std::filesystem;

struct Options {
  std::string run_dir, silhouette;
  solvers::lighting::CameraModel camera;  // --camera and its intrinsics (fy 0: fx)
  std::vector<std::string> images, white_images;
  std::vector<double> circle;
  double radius_mm = 0;
  CalibrationOutputs outputs;
};

cv::Mat ReadSingleChannel(const std::string& path) {
  return daemon::ReadInputImage(path, solvers::codecs::ReadMode::kGrey);
}

int Execute(const Options& o) {
  // Nothing is written outside --out or, by default, the run's own results.
  if (o.outputs.out.empty() && o.run_dir.empty()) {
    return Fail(kExitUsage, "calibrate lights: give --out DIR for the outputs (with --run they default to RUN/results/lights)");
  }
  const std::string out = o.outputs.Directory(o.run_dir, "lights");
  daemon::LightCalibrationInputs inputs;
  if (!o.run_dir.empty()) {
    inputs = daemon::LoadLightCalibrationInputs(o.run_dir);
  } else {
    for (const auto& path : o.images) {
      inputs.frames.push_back(ReadSingleChannel(path));
      inputs.names.push_back(fs::path(path).filename().string());
    }
    if (!o.outputs.rig.empty()) {  // nominal directions for locating the sphere from its highlights
      const config::RigConfig rig = config::LoadRigConfig(o.outputs.rig);
      for (const auto& led : rig.lights.leds) inputs.nominal_directions.push_back(led.direction);
      inputs.pixel_pitch_mm = rig.camera.pixel_pitch_mm;
      inputs.projection = rig.camera.projection;
      inputs.pinhole = rig.camera.pinhole;
    }
  }
  config::LightCalibrationRequest request;
  try {
    daemon::LoadWhiteFrames(o.white_images, &inputs);
    // The run's (or rig's) own lens, unless the command line says otherwise.
    request.camera = daemon::SphereCamera(inputs, o.camera);
  } catch (const std::invalid_argument& e) {
    return Fail(kExitUsage, std::string("calibrate lights: ") + e.what());
  }
  if (o.circle.size() == 3) request.circle = solvers::lighting::Circle{o.circle[0], o.circle[1], o.circle[2]};
  request.silhouette_image = o.silhouette;
  request.sphere_radius_mm = o.radius_mm;
  request.base_rig = o.outputs.BaseRig();
  request.out_rig = o.outputs.out_rig;

  const daemon::LightCalibrationSummary summary = daemon::CalibrateLights(inputs, request, out);
  ResultFields() = daemon::ToJson(summary);
  ResultFields()["out"] = out;
  // Before a sphere is located, what stops the calibration is its input (no
  // frames, a request that cannot work); after, the fit. Either way no
  // summary of outputs that were not written.
  if (!summary.success) return Fail(summary.sphere_source == daemon::SphereSource::kNone ? kExitUsage : kExitFailed, summary.message);
  std::cout << "sphere (" << daemon::SphereSourceName(summary.sphere_source) << "): centre " << summary.circle.cx_px << ", "
            << summary.circle.cy_px << " px, radius " << summary.circle.radius_px << " px\n"
            << "lights: " << summary.lights << ", unusable: " << summary.unusable << ", mean uncertainty "
            << summary.mean_uncertainty_deg << " deg, outputs in " << out << "\n";
  if (summary.circle_shift_deg > 0.0)
    std::cout << "circle check: the highlights' circle would move the directions by " << summary.circle_shift_deg
              << " deg on average (included in the uncertainty)\n";
  return kExitOk;
}

CLI::App* Setup(CLI::App& app, Options* o) {
  CLI::App* lights =
      CalibrateGroup(app)->add_subcommand("lights", "light directions (mirror sphere) and intensities (white sphere)");
  auto* run = lights->add_option("--run", o->run_dir, "run directory with one frame per LED")->check(CLI::ExistingDirectory);
  lights->add_option("--images", o->images, "mirror-sphere images, one per light")->check(CLI::ExistingFile)->excludes(run);
  auto* silhouette =
      lights->add_option("--silhouette", o->silhouette, "image showing the sphere's silhouette")->check(CLI::ExistingFile);
  lights->add_option("--circle", o->circle, "sphere circle CX CY R in pixels (default: from the highlights)")
      ->expected(3)->delimiter(',')->excludes(silhouette);
  lights->add_option("--radius-mm", o->radius_mm, "sphere radius: fixes the radius when locating it from highlights");
  AddChoice(lights, "--camera", &o->camera.projection, solvers::lighting::CameraModel::kProjectionNames, "camera projection");
  lights->add_option("--fx", o->camera.fx_px, "pinhole focal length (px)");
  lights->add_option("--fy", o->camera.fy_px, "pinhole focal length y (px; default fx)");
  lights->add_option("--cx", o->camera.cx_px, "pinhole principal point x (px)");
  lights->add_option("--cy", o->camera.cy_px, "pinhole principal point y (px)");
  lights->add_option("--white-images", o->white_images, "white-sphere images, one per light")->check(CLI::ExistingFile);
  AddCalibrationOutputOptions(lights, &o->outputs,
                              "rig YAML to copy with the calibrated lights (and, with --images, the nominal directions)",
                              "lights");
  return lights;
}

const bool registered = RegisterCommand<Options, Setup, Execute>();

}  // namespace
}  // namespace photorig::app
