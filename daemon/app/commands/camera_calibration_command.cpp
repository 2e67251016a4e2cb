// photorig calibrate camera --images F... --board COLSxROWS --square-mm S --plane-image F|INDEX
//   --rig IN.yaml --out-rig NEW.yaml [--distortion auto|none|k1|k1-k2|k1-k2-p1-p2|k1-k2-p1-p2-k3]
// The camera's pinhole intrinsics and distortion from checkerboard
// photographs, and its height from the one of the board lying on the sample
// plane, written as a new rig (an existing file is never overwritten).

#include "../command.h"
#include "../command_output.h"
#include "../progress_display.h"
#include "photorig/daemon/pipelines/camera_calibration.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <regex>

namespace photorig::app {
namespace {

namespace fs = std::filesystem;

struct Options {
  std::vector<std::string> images;
  std::string board, plane_image, rig, out_rig;
  std::string distortion = "auto";
  double square_mm = 0.0;
};

// --plane-image: one of --images (by its path or its index from 0), or
// another photograph, which joins them. -1 when it names none of these.
int PlaneImageIndex(const std::string& plane, std::vector<std::string>* images) {
  for (std::size_t i = 0; i < images->size(); ++i) {
    std::error_code error;
    if ((*images)[i] == plane || fs::equivalent((*images)[i], plane, error)) return static_cast<int>(i);
  }
  if (std::regex_match(plane, std::regex("[0-9]+"))) {
    const int index = std::stoi(plane);
    return index < static_cast<int>(images->size()) ? index : -1;
  }
  if (!fs::is_regular_file(plane)) return -1;
  images->push_back(plane);
  return static_cast<int>(images->size()) - 1;
}

int Execute(Options o) {
  daemon::CameraCalibrationRequest request;
  solvers::camera::CheckerboardCalibrationOptions& options = request.options;
  std::smatch board;
  if (!std::regex_match(o.board, board, std::regex("([0-9]+)x([0-9]+)")))
    return Fail(kExitUsage, "calibrate camera: --board takes the inner corners as COLSxROWS, e.g. 9x6");
  options.inner_corners_cols = std::stoi(board[1]);
  options.inner_corners_rows = std::stoi(board[2]);
  options.square_mm = o.square_mm;
  if (o.distortion != "auto")
    options.distortion = solvers::core::ParseName(solvers::camera::kDistortionModelNames, o.distortion);
  options.plane_image = PlaneImageIndex(o.plane_image, &o.images);
  if (options.plane_image < 0)
    return Fail(kExitUsage, "calibrate camera: --plane-image " + o.plane_image +
                                " is neither one of --images (a path or an index from 0) nor an image file");
  if (std::string why; !options.IsValid(&why)) return Fail(kExitUsage, why);
  request.images = o.images;
  request.base_rig = o.rig;
  request.out_rig = o.out_rig;

  ProgressDisplay progress;
  options.progress = progress.Callback();
  const daemon::CameraCalibrationResult result = daemon::CalibrateCamera(request);
  progress.EndLine();

  const solvers::camera::CheckerboardCalibrationSummary& s = result.summary;
  ResultFields() = daemon::ToJson(result, request);
  std::printf("boards found in %zu of %zu images", s.used.size(), request.images.size());
  for (std::size_t i = 0; i < s.used.size() && i < s.image_rms_px.size(); ++i)
    std::printf("%s %s %.3f px", i == 0 ? ":" : ",", s.used[i].c_str(), s.image_rms_px[i]);
  std::printf("\n");
  if (!s.rejected.empty()) {
    std::printf("no board in:");
    for (const std::string& name : s.rejected) std::printf(" %s", name.c_str());
    std::printf("\n");
  }
  if (s.lens.fx_px > 0.0) {  // the fit ran: a refused one shows its figures too
    const solvers::camera::PinholeLens& lens = s.lens;
    std::printf("fx %.2f +- %.2f px, fy %.2f +- %.2f px, cx %.2f +- %.2f px, cy %.2f +- %.2f px\n", lens.fx_px,
                s.fx_std_px, lens.fy_px, s.fy_std_px, lens.cx_px, s.cx_std_px, lens.cy_px, s.cy_std_px);
    std::printf("distortion k1 %.5f k2 %.5f p1 %.6f p2 %.6f k3 %.5f\n", lens.distortion[0], lens.distortion[1],
                lens.distortion[2], lens.distortion[3], lens.distortion[4]);
    std::printf("distortion model %s\n", s.distortion_reason.c_str());
    std::printf("camera %.2f mm above the sample plane, tilted %.3f deg; RMS reprojection error %.3f px; corners "
                "reach %.0f %% of the way to the image's corners\n",
                lens.distance_mm, s.tilt_deg, s.rms_px, 100.0 * s.corner_reach);
  }
  if (!s.IsSolutionUsable()) {
    // Bad options or images are the caller's to fix; a fit the data do not support is a failed calibration.
    const bool usage = s.termination == solvers::core::Termination::kInvalidOptions ||
                       s.termination == solvers::core::Termination::kInvalidInput;
    return Fail(usage ? kExitUsage : kExitFailed, s.message);
  }
  if (!s.message.empty()) std::printf("%s\n", s.message.c_str());
  std::printf("rig written: %s\n", o.out_rig.c_str());
  return kExitOk;
}

CLI::App* Setup(CLI::App& app, Options* o) {
  CLI::App* camera =
      CalibrateGroup(app)->add_subcommand("camera", "pinhole intrinsics and distortion from checkerboard photographs");
  camera->add_option("--images", o->images, "checkerboard photographs in several poses")
      ->required()->check(CLI::ExistingFile);
  camera->add_option("--board", o->board, "inner corners of the board as COLSxROWS (10 x 7 squares: 9x6)")->required();
  camera->add_option("--square-mm", o->square_mm, "side of one square (mm)")->required();
  camera->add_option("--plane-image", o->plane_image,
                     "the photograph of the board lying flat on the sample plane: a file or an index into --images")
      ->required();
  camera
      ->add_option("--distortion", o->distortion,
                   "distortion model: auto (the one of lowest BIC on the corners) or " +
                       solvers::core::JoinNames(solvers::camera::kDistortionModelNames) + " (default auto)")
      ->check(CLI::IsMember([] {
        std::vector<std::string> names = {"auto"};
        for (const auto& named : solvers::camera::kDistortionModelNames) names.emplace_back(named.name);
        return names;
      }()));
  camera->add_option("--rig", o->rig, "rig YAML whose camera took the photographs")->required()->check(CLI::ExistingFile);
  camera->add_option("--out-rig", o->out_rig, "new rig YAML to write, with the calibrated lens")->required();
  return camera;
}

const bool registered = RegisterCommand<Options, Setup, Execute>();

}  // namespace
}  // namespace photorig::app
