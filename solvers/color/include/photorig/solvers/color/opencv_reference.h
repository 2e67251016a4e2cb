#pragma once
// Runs OpenCV's ColorCorrectionModel (3x3, CIEDE2000 loss) on the same chart
// measurement through the photorig-color-opencv-ccm executable, one process
// per call, and scores it the same way as Calibrate (training and leave-one-out).

#include "photorig/solvers/color/calibration.h"

#include <string>
#include <vector>

namespace photorig::solvers::color {

struct OpenCvReference {
  bool ok = false;
  std::string message;
  std::vector<double> training_de, held_out_de;  // per usable patch, in input order
  double training_mean = 0.0, held_out_mean = 0.0;
  double fit_ms = 0.0, loo_ms = 0.0;
};

OpenCvReference RunOpenCvReference(const std::string& executable, const CalibrationInput& input);

}  // namespace photorig::solvers::color
