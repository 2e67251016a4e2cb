// The automatically chosen model against OpenCV's ColorCorrectionModel (3x3,
// CIEDE2000 loss) on the same simulated captures, camera by camera, each OpenCV
// fit in its own process.

#include "photorig/solvers/color/calibration.h"
#include "photorig/solvers/color/opencv_reference.h"
#include "sim_chart.h"

#include <gtest/gtest.h>

namespace photorig::solvers::color {
namespace {

TEST(ColorVersusOpenCv, ChosenModelBeatsOpenCvOnEveryCamera) {
  LocateOptions locate;
  locate.use_detector = false;
  locate.fixed_corners = sim::ChartGeometry{}.GridCorners();
  for (const std::string& camera : CameraNames()) {
    const sim::ChartRender render = testing::RenderChart(camera, Illuminant::kD65);
    const ChartCalibration ours = CalibrateChartImage(render.raw, render.dark, Illuminant::kD65, locate,
                                                      testing::SimMeasureOptions(render), CalibrationOptions{});
    ASSERT_TRUE(ours.summary.IsSolutionUsable()) << camera << ": " << ours.summary.message;
    CalibrationInput input;
    input.reference_xyz = ours.reference.xyz;
    input.white_xyz = ours.reference.white_xyz;
    for (const auto& patch : ours.patches) {
      input.camera_rgb.push_back(patch.rgb);
      input.usable.push_back(patch.flag == PatchFlag::kOk);
    }
    const OpenCvReference opencv = RunOpenCvReference(std::string(PHOTORIG_BIN_DIR) + "/photorig-color-opencv-ccm", input);
    ASSERT_TRUE(opencv.ok) << opencv.message;
    const ModelEvaluation& chosen = ours.summary.models[static_cast<std::size_t>(ours.summary.chosen)];
    EXPECT_LT(chosen.held_out_mean, opencv.held_out_mean)
        << camera << ": " << chosen.spec.Name() << " " << chosen.held_out_mean << " vs OpenCV " << opencv.held_out_mean;
    std::cout << camera << ": " << chosen.spec.Name() << " LOO " << chosen.held_out_mean << ", OpenCV 3x3 LOO "
              << opencv.held_out_mean << "\n";
  }
}

}  // namespace
}  // namespace photorig::solvers::color
