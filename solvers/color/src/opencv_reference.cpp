#include "photorig/solvers/color/opencv_reference.h"

#include "photorig/solvers/color/colorimetry.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <sstream>
#include <unistd.h>

namespace photorig::solvers::color {

OpenCvReference RunOpenCvReference(const std::string& executable, const CalibrationInput& input) {
  OpenCvReference out;
  if (!std::filesystem::exists(executable)) {
    out.message = "OpenCV reference executable not found: " + executable;
    return out;
  }
  // OpenCV ignores values outside (0, 0.98) as saturated: bring the brightest usable
  // patch to 0.9 (a pure scale, which a 3x3 model absorbs).
  double brightest = 0.0;
  int used = 0;
  for (std::size_t i = 0; i < input.camera_rgb.size(); ++i)
    if (input.usable[i]) brightest = std::max(brightest, input.camera_rgb[i].maxCoeff()), ++used;
  if (used < 4 || brightest <= 0.0) {
    out.message = "too few usable patches for the OpenCV reference";
    return out;
  }
  const auto path = std::filesystem::temp_directory_path() /
                    ("photorig-opencv-ccm-" + std::to_string(::getpid()) + "-" + std::to_string(reinterpret_cast<std::uintptr_t>(&out)) + ".txt");
  {
    std::ofstream file(path);
    file.precision(17);
    file << input.white_xyz.x() << " " << input.white_xyz.y() << " " << input.white_xyz.z() << "\n" << used << "\n";
    for (std::size_t i = 0; i < input.camera_rgb.size(); ++i) {
      if (!input.usable[i]) continue;
      const Eigen::Vector3d rgb = input.camera_rgb[i] * (0.9 / brightest);
      const Eigen::Vector3d lab = XyzToLab(input.reference_xyz[i], input.white_xyz);
      file << rgb.x() << " " << rgb.y() << " " << rgb.z() << " " << lab.x() << " " << lab.y() << " " << lab.z() << "\n";
    }
  }
  const std::string command = "'" + executable + "' < '" + path.string() + "' 2>&1";
  FILE* pipe = ::popen(command.c_str(), "r");
  std::string text;
  if (pipe) {
    char buffer[4096];
    while (std::size_t n = std::fread(buffer, 1, sizeof(buffer), pipe)) text.append(buffer, n);
    const int status = ::pclose(pipe);
    std::filesystem::remove(path);
    if (status != 0) {
      out.message = "OpenCV reference failed: " + text;
      return out;
    }
  }
  std::istringstream lines(text);
  std::string key;
  while (lines >> key) {
    if (key == "fit_ms") {
      lines >> out.fit_ms;
    } else if (key == "loo_ms") {
      lines >> out.loo_ms;
    } else {
      double training = 0.0, held_out = 0.0;
      lines >> training >> held_out;
      out.training_de.push_back(training);
      out.held_out_de.push_back(held_out);
    }
  }
  if (static_cast<int>(out.held_out_de.size()) != used) {
    out.message = "OpenCV reference printed " + std::to_string(out.held_out_de.size()) + " patches, expected " +
                  std::to_string(used) + ": " + text;
    return out;
  }
  out.training_mean = std::accumulate(out.training_de.begin(), out.training_de.end(), 0.0) / used;
  out.held_out_mean = std::accumulate(out.held_out_de.begin(), out.held_out_de.end(), 0.0) / used;
  out.ok = true;
  return out;
}

}  // namespace photorig::solvers::color
