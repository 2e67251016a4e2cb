// color_model_sweep OPENCV_CCM_EXECUTABLE [--loss xyz|ciede2000]
// CSV on stdout, one row per camera x model (and OpenCV's 3x3 per camera):
//   camera,model,terms,loss,training_mean,held_out_mean,held_out_max,fit_loo_ms,chosen
// All on simulated D65 captures of the BabelColor chart.

#include "chart_capture.h"
#include "photorig/solvers/color/opencv_reference.h"

#include <cstdio>
#include <string>

int main(int argc, char** argv) {
  using namespace photorig::solvers::color;
  if (argc < 2) {
    std::fprintf(stderr, "usage: color_model_sweep OPENCV_CCM_EXECUTABLE [--loss xyz|ciede2000]\n");
    return 2;
  }
  CalibrationOptions options;
  if (argc >= 4 && std::string(argv[2]) == "--loss") {
    const std::optional<FitLoss> loss = ParseFitLoss(argv[3]);
    if (!loss) {
      std::fprintf(stderr, "unknown fit loss '%s' (known: xyz, ciede2000)\n", argv[3]);
      return 2;
    }
    options.loss = *loss;
  }
  std::printf("camera,model,terms,loss,training_mean,held_out_mean,held_out_max,fit_loo_ms,chosen\n");
  for (const std::string& camera : CameraNames()) {
    const ChartCalibration chart = bench::SimulatedChart(camera, Illuminant::kD65, options);
    for (std::size_t i = 0; i < chart.summary.models.size(); ++i) {
      const ModelEvaluation& m = chart.summary.models[i];
      if (!m.usable) continue;
      std::printf("%s,%s,%d,%s,%.4f,%.4f,%.4f,%.4f,%d\n", camera.c_str(), m.spec.Name().c_str(), m.spec.TermCount(),
                  FitLossName(options.loss), m.training_mean, m.held_out_mean, m.held_out_max, m.fit_ms + m.loo_ms,
                  static_cast<int>(i) == chart.summary.chosen);
    }
    const OpenCvReference opencv = RunOpenCvReference(argv[1], bench::InputOf(chart));
    if (!opencv.ok) {
      std::fprintf(stderr, "%s: %s\n", camera.c_str(), opencv.message.c_str());
      return 1;
    }
    double worst = 0.0;
    for (const double d : opencv.held_out_de) worst = std::max(worst, d);
    std::printf("%s,opencv-3x3,3,ciede2000,%.4f,%.4f,%.4f,%.4f,0\n", camera.c_str(), opencv.training_mean,
                opencv.held_out_mean, worst, opencv.fit_ms + opencv.loo_ms);
  }
  return 0;
}
