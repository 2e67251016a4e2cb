// OpenCV's ColorCorrectionModel (opencv2/mcc/ccm.hpp) on a chart measurement,
// as the reference the colour calibration is compared against. One process per
// configuration: ColorCorrectionModel keeps colour-space state in process-global
// objects, so two configurations in one process would influence each other.
//
// stdin:  white_X white_Y white_Z
//         n
//         n lines: r g b L a b   (linear camera RGB in [0, 1], reference CIELAB for that white)
// stdout: n lines: patch training_de00 held_out_de00
//         fit_ms F
//         loo_ms T
// Fitting: 3x3 matrix, CIEDE2000 loss, no linearisation (the input is linear).

#include "photorig/solvers/color/colorimetry.h"

#include <opencv2/mcc/ccm.hpp>

#include <chrono>
#include <cstdio>
#include <iostream>
#include <memory>
#include <vector>

namespace {

using photorig::solvers::color::Ciede2000;
using photorig::solvers::color::LinearSrgbToXyzD65;
using photorig::solvers::color::XyzToLab;

std::unique_ptr<cv::ccm::ColorCorrectionModel> Fit(const std::vector<cv::Vec3d>& rgb, const std::vector<cv::Vec3d>& lab) {
  cv::Mat src(static_cast<int>(rgb.size()), 1, CV_64FC3), dst(static_cast<int>(lab.size()), 1, CV_64FC3);
  for (std::size_t i = 0; i < rgb.size(); ++i) {
    src.at<cv::Vec3d>(static_cast<int>(i)) = rgb[i];
    dst.at<cv::Vec3d>(static_cast<int>(i)) = lab[i];
  }
  auto model = std::make_unique<cv::ccm::ColorCorrectionModel>(src, dst, cv::ccm::COLOR_SPACE_Lab_D65_2);
  model->setCCM_TYPE(cv::ccm::CCM_3x3);
  model->setDistance(cv::ccm::DISTANCE_CIE2000);
  model->setLinear(cv::ccm::LINEARIZATION_IDENTITY);
  model->run();
  return model;
}

Eigen::Vector3d PredictLab(cv::ccm::ColorCorrectionModel& model, const cv::Vec3d& rgb, const Eigen::Vector3d& white) {
  cv::Mat in(1, 1, CV_64FC3);
  in.at<cv::Vec3d>(0) = rgb;
  const cv::Mat linear_srgb = model.infer(in, true);
  const cv::Vec3d v = linear_srgb.at<cv::Vec3d>(0);
  return XyzToLab(LinearSrgbToXyzD65() * Eigen::Vector3d(v[0], v[1], v[2]), white);
}

}  // namespace

int main() {
  Eigen::Vector3d white;
  int n = 0;
  if (!(std::cin >> white[0] >> white[1] >> white[2] >> n) || n < 4) {
    std::cerr << "opencv-ccm: expected 'white_X white_Y white_Z' and a patch count >= 4 on stdin\n";
    return 2;
  }
  std::vector<cv::Vec3d> rgb(static_cast<std::size_t>(n)), lab(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    auto& c = rgb[static_cast<std::size_t>(i)];
    auto& l = lab[static_cast<std::size_t>(i)];
    if (!(std::cin >> c[0] >> c[1] >> c[2] >> l[0] >> l[1] >> l[2])) {
      std::cerr << "opencv-ccm: patch line " << i + 1 << " is not 'r g b L a b'\n";
      return 2;
    }
  }
  auto to_eigen = [](const cv::Vec3d& v) { return Eigen::Vector3d(v[0], v[1], v[2]); };
  try {
    using Clock = std::chrono::steady_clock;
    auto t0 = Clock::now();
    const auto full = Fit(rgb, lab);
    const double fit_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    std::vector<double> training(static_cast<std::size_t>(n)), held_out(static_cast<std::size_t>(n));
    for (std::size_t i = 0; i < rgb.size(); ++i) training[i] = Ciede2000(PredictLab(*full, rgb[i], white), to_eigen(lab[i]));
    t0 = Clock::now();
    for (std::size_t k = 0; k < rgb.size(); ++k) {
      std::vector<cv::Vec3d> rgb_train, lab_train;
      for (std::size_t j = 0; j < rgb.size(); ++j)
        if (j != k) rgb_train.push_back(rgb[j]), lab_train.push_back(lab[j]);
      held_out[k] = Ciede2000(PredictLab(*Fit(rgb_train, lab_train), rgb[k], white), to_eigen(lab[k]));
    }
    const double loo_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    for (std::size_t i = 0; i < rgb.size(); ++i) std::printf("%zu %.6f %.6f\n", i + 1, training[i], held_out[i]);
    std::printf("fit_ms %.4f\nloo_ms %.4f\n", fit_ms, loo_ms);
  } catch (const cv::Exception& e) {
    std::cerr << "opencv-ccm: OpenCV failed: " << e.what() << "\n";
    return 3;
  }
  return 0;
}
