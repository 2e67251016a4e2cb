// Writes CHART_DIR/camera_calibration.csv: checkerboard lens calibration of
// three simulated lenses (the dome's: k1 -0.05, k2 0.01; a wider, decentred
// one; a distortion-free one) from 5, 9 and 13 photographs at two noise
// levels, with every distortion model fixed and with the model chosen: the
// recovered lens's error on the sample plane against the truth, the focal
// length's error, the reprojection RMS and the time of the calibration, and
// whether the calibration trusted its result (5 photographs about the centre
// do not reach the image's corners: refused, drawn hollow).
#include "checkerboard_scene.h"
#include "lens_plane_error.h"
#include "photorig/solvers/camera/calibration.h"

#include <cstdio>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

namespace {

using namespace photorig;
using solvers::camera::DistortionModel;

struct Lens {
  const char* name;
  std::array<double, 5> distortion;
};

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s CHART_DIR\n", argv[0]);
    return 2;
  }
  const std::string path = std::string(argv[1]) + "/camera_calibration.csv";
  std::ofstream out(path);
  out << "lens,noise,images,model,chosen,trusted,corner_reach,time_ms,rms_px,plane_rms_px,plane_max_px,fx_error_pct\n";
  const Lens lenses[] = {{"dome", {-0.05, 0.01, 0.0, 0.0, 0.0}},
                         {"wide-decentred", {-0.3, 0.12, 0.002, -0.0015, 0.0}},
                         {"distortion-free", {0.0, 0.0, 0.0, 0.0, 0.0}}};
  std::vector<std::optional<DistortionModel>> models = {std::nullopt};
  for (const auto& named : solvers::camera::kDistortionModelNames) models.push_back(named.value);
  for (const Lens& lens : lenses) {
    sim::CameraModel truth = testing::TrueCamera();
    truth.distortion = lens.distortion;
    for (const double noise : {0.005, 0.02}) {
      const std::vector<cv::Mat> all = testing::Render(truth, testing::Poses(), noise);
      for (const std::size_t count : {5u, 9u, 13u}) {
        // The plane image, then the tilted poses in the fixture's order.
        const std::vector<cv::Mat> images(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(count));
        for (const std::optional<DistortionModel>& model : models) {
          solvers::camera::CheckerboardCalibrationOptions options;
          options.inner_corners_cols = 9;
          options.inner_corners_rows = 6;
          options.square_mm = 10.0;
          options.distortion = model;
          const auto summary = solvers::camera::CalibrateFromCheckerboards(options, images);
          const char* name = model ? solvers::core::NameOf(solvers::camera::kDistortionModelNames, *model) : "auto";
          if (summary.lens.fx_px <= 0.0) {
            std::fprintf(stderr, "%s, noise %g, %zu images, %s: %s\n", lens.name, noise, count, name,
                         summary.message.c_str());
            continue;
          }
          const testing::PlaneError plane = testing::LensPlaneError(truth, summary.lens);
          const char* chosen = solvers::core::NameOf(solvers::camera::kDistortionModelNames, summary.distortion_model);
          out << lens.name << ',' << noise << ',' << count << ',' << name << ',' << chosen << ','
              << (summary.IsSolutionUsable() ? 1 : 0) << ',' << summary.corner_reach << ',' << summary.total_ms << ',' << summary.rms_px << ',' << plane.rms_px << ',' << plane.max_px << ','
              << 100.0 * (summary.lens.fx_px - truth.fx) / truth.fx << '\n';
          std::fprintf(stderr, "%-16s noise %.3f %2zu images %-15s -> %-15s %7.1f ms, plane %.3f px (max %.3f), reach %.2f\n",
                       lens.name, noise, count, name, chosen, summary.total_ms, plane.rms_px, plane.max_px,
                       summary.corner_reach);
          if (!model) std::fprintf(stderr, "  %s\n", summary.distortion_reason.c_str());
        }
      }
    }
  }
  return out ? 0 : 1;
}
