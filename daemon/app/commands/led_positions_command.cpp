// photorig calibrate leds --run DIR --sphere X,Y[,Z] --sphere X,Y[,Z] ... --radius-mm R
//   [--rig IN.yaml --out-rig NEW.yaml] [--out DIR (default RUN/results/leds)]
// A near-LED dome's LED positions from mirror spheres at known places, one
// frame per LED: report.json and a new rig YAML (an existing file is never
// overwritten; none is written while an LED is unusable).

#include "../command.h"
#include "../command_output.h"
#include "calibration_outputs.h"
#include "photorig/daemon/pipelines/led_positions.h"

#include <cmath>
#include <iostream>
#include <sstream>

namespace photorig::app {
namespace {

struct Options {
  std::string run_dir;
  std::vector<std::string> spheres;
  double radius_mm = 0.0;
  CalibrationOutputs outputs;
};

// "X,Y" or "X,Y,Z" in millimetres; false for anything else.
bool ParseCentre(const std::string& text, Eigen::Vector3d* centre) {
  std::vector<double> values;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    std::size_t used = 0;
    try {
      values.push_back(std::stod(item, &used));
    } catch (const std::exception&) {
      return false;
    }
    if (used != item.size() || !std::isfinite(values.back())) return false;
  }
  if (values.size() != 2 && values.size() != 3) return false;
  *centre = {values[0], values[1], values.size() == 3 ? values[2] : 0.0};
  return true;
}

int Execute(const Options& o) {
  config::LedPositionRequest request;
  for (const std::string& text : o.spheres) {
    Eigen::Vector3d centre;
    if (!ParseCentre(text, &centre))
      return Fail(kExitUsage, "--sphere '" + text + "' is not X,Y or X,Y,Z in millimetres");
    request.sphere_centres_mm.push_back(centre);
  }
  if (request.sphere_centres_mm.size() < 2)
    return Fail(kExitUsage, "give --sphere X,Y[,Z] for each of two or more mirror spheres");
  request.sphere_radius_mm = o.radius_mm;
  request.base_rig = o.outputs.BaseRig();
  request.out_rig = o.outputs.out_rig;
  if (std::string why; !request.IsValid(&why)) return Fail(kExitUsage, why);

  const std::string out = o.outputs.Directory(o.run_dir, "leds");
  const daemon::LedPositionCalibration result =
      daemon::CalibrateLedPositions(daemon::LoadLedPositionInputs(o.run_dir), request, out);
  if (result.bad_input) return Fail(kExitUsage, result.message);
  std::cout << result.message << "; rays meet within " << result.solve.mean_rms_ray_distance_mm
            << " mm RMS on average; LEDs moved " << result.mean_shift_mm << " mm on average (at most "
            << result.max_shift_mm << " mm) from the rig's positions; outputs in " << out << "\n";
  if (result.mean_error_mm >= 0.0)
    std::cout << "against the simulated truth: mean error " << result.mean_error_mm << " mm, max " << result.max_error_mm
              << " mm\n";
  if (!result.out_rig.empty()) std::cout << "calibrated rig: " << result.out_rig << "\n";
  ResultFields() = daemon::ToJson(result);
  ResultFields()["out"] = out;
  if (!result.success) return Fail(kExitFailed, result.message);
  return kExitOk;
}

CLI::App* Setup(CLI::App& app, Options* o) {
  CLI::App* leds =
      CalibrateGroup(app)->add_subcommand("leds", "near-LED positions from two or more mirror spheres at known places");
  leds->add_option("--run", o->run_dir, "run directory with one frame per LED")->required()->check(CLI::ExistingDirectory);
  leds->add_option("--sphere", o->spheres, "a mirror sphere's centre X,Y[,Z] in mm, dome frame (Z default 0); repeat per sphere")
      ->required()
      ->expected(1)
      ->take_all();
  leds->add_option("--radius-mm", o->radius_mm, "the spheres' radius")->required();
  AddCalibrationOutputOptions(leds, &o->outputs, "rig YAML to copy with the calibrated positions", "leds");
  return leds;
}

const bool registered = RegisterCommand<Options, Setup, Execute>();

}  // namespace
}  // namespace photorig::app
