#include "photorig/daemon/diligent.h"

#include "photorig/daemon/image_io.h"

#include <matio.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace photorig::daemon {
namespace fs = std::filesystem;
namespace {

std::vector<std::string> ReadLines(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open " + path.string());
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.find_first_not_of(" \t") != std::string::npos) lines.push_back(line);
  }
  return lines;
}

std::vector<cv::Vec3d> ReadTriples(const fs::path& path, std::size_t expected) {
  const auto lines = ReadLines(path);
  if (lines.size() != expected)
    throw std::runtime_error(path.string() + ": " + std::to_string(lines.size()) + " lines for " +
                             std::to_string(expected) + " images");
  std::vector<cv::Vec3d> values;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    std::istringstream fields(lines[i]);
    cv::Vec3d v;
    if (!(fields >> v[0] >> v[1] >> v[2]))
      throw std::runtime_error(path.string() + ":" + std::to_string(i + 1) + ": expected three numbers");
    values.push_back(v);
  }
  return values;
}

cv::Mat ReadNormalsMat(const fs::path& path, cv::Size size) {
  mat_t* file = Mat_Open(path.c_str(), MAT_ACC_RDONLY);
  if (!file) throw std::runtime_error("cannot open " + path.string() + " as a MATLAB file");
  matvar_t* variable = Mat_VarRead(file, "Normal_gt");
  if (!variable) {
    Mat_Close(file);
    throw std::runtime_error(path.string() + ": no variable Normal_gt");
  }
  const bool shape_ok = variable->rank == 3 && variable->dims[0] == static_cast<size_t>(size.height) &&
                        variable->dims[1] == static_cast<size_t>(size.width) && variable->dims[2] == 3 &&
                        variable->class_type == MAT_C_DOUBLE && !variable->isComplex;
  cv::Mat normals;
  if (shape_ok) {
    normals.create(size, CV_32FC3);
    const auto* data = static_cast<const double*>(variable->data);
    const std::size_t h = size.height, w = size.width;
    for (std::size_t r = 0; r < h; ++r)
      for (std::size_t c = 0; c < w; ++c)
        for (int k = 0; k < 3; ++k)  // MATLAB arrays are column-major
          normals.at<cv::Vec3f>(r, c)[k] = static_cast<float>(data[r + h * (c + w * k)]);
  }
  Mat_VarFree(variable);
  Mat_Close(file);
  if (!shape_ok)
    throw std::runtime_error(path.string() + ": Normal_gt must be a real double array of " +
                             std::to_string(size.height) + " x " + std::to_string(size.width) + " x 3");
  return normals;
}

void WriteNormalsMat(const fs::path& path, const cv::Mat& normals) {
  const std::size_t h = normals.rows, w = normals.cols;
  std::vector<double> data(h * w * 3);
  for (std::size_t r = 0; r < h; ++r)
    for (std::size_t c = 0; c < w; ++c)
      for (int k = 0; k < 3; ++k) {
        const float v = normals.at<cv::Vec3f>(r, c)[k];
        data[r + h * (c + w * k)] = std::isfinite(v) ? v : 0.0;  // DiLiGenT stores 0 off the object
      }
  mat_t* file = Mat_CreateVer(path.c_str(), nullptr, MAT_FT_MAT5);
  if (!file) throw std::runtime_error("cannot create " + path.string());
  size_t dims[3] = {h, w, 3};
  matvar_t* variable = Mat_VarCreate("Normal_gt", MAT_C_DOUBLE, MAT_T_DOUBLE, 3, dims, data.data(), 0);
  const int status = Mat_VarWrite(file, variable, MAT_COMPRESSION_NONE);
  Mat_VarFree(variable);
  Mat_Close(file);
  if (status != 0) throw std::runtime_error("cannot write " + path.string());
}

}  // namespace

PhotometricStereoInput LoadDiligent(const std::string& directory) {
  const fs::path root(directory);
  PhotometricStereoInput input;
  input.source = directory;
  const auto names = ReadLines(root / "filenames.txt");
  if (names.size() < 3) throw std::runtime_error((root / "filenames.txt").string() + ": fewer than 3 images");
  const auto directions = ReadTriples(root / "light_directions.txt", names.size());
  const auto intensities = ReadTriples(root / "light_intensities.txt", names.size());
  for (std::size_t i = 0; i < names.size(); ++i) {
    const fs::path file = root / names[i];
    const cv::Mat image = ReadImage(file.string());
    if (!input.stack.images.empty() && image.size() != input.stack.images.front().size())
      throw std::runtime_error(file.string() + ": size differs from " + (root / names[0]).string());
    // Colour-balance each channel by its intensity but keep the sensor's scale:
    // grey = mean_c(I_c * mean(L) / L_c), light scale = mean(L). Thresholds in
    // DN (shadows, quantisation) then keep their meaning.
    std::vector<cv::Mat> channels;
    cv::split(image, channels);
    const double mean_intensity = (intensities[i][0] + intensities[i][1] + intensities[i][2]) / 3.0;
    if (!(intensities[i][0] > 0 && intensities[i][1] > 0 && intensities[i][2] > 0))
      throw std::runtime_error((root / "light_intensities.txt").string() + ":" + std::to_string(i + 1) +
                               ": intensities must be > 0");
    cv::Mat grey = cv::Mat::zeros(image.size(), CV_32F);
    for (std::size_t c = 0; c < channels.size(); ++c) {
      // OpenCV reads BGR; light_intensities.txt lists R G B.
      const double intensity = channels.size() == 3 ? intensities[i][2 - c] : mean_intensity;
      cv::Mat channel;
      channels[c].convertTo(channel, CV_32F, mean_intensity / (intensity * channels.size()));
      grey += channel;
    }
    const cv::Vec3d d = directions[i];
    const double length = cv::norm(d);
    if (!(length > 0)) throw std::runtime_error((root / "light_directions.txt").string() + ":" +
                                                std::to_string(i + 1) + ": zero direction");
    input.stack.images.push_back(grey);
    input.stack.light_directions.emplace_back(d[0] / length, d[1] / length, d[2] / length);
    input.stack.light_scales.push_back(mean_intensity);
  }
  // Channels are rescaled, so there is no common full-scale code to detect.
  input.saturation_level = std::numeric_limits<double>::infinity();
  if (fs::exists(root / "mask.png")) {
    cv::Mat mask = ReadImage((root / "mask.png").string());
    if (mask.channels() > 1) cv::extractChannel(mask, mask, 0);
    if (mask.depth() != CV_8U) mask.convertTo(mask, CV_8U, 1.0 / 257.0);
    input.object_mask = mask > 0;
    input.mask_source = (root / "mask.png").string();
  }
  if (fs::exists(root / "Normal_gt.mat"))
    input.truth_normals = ReadNormalsMat(root / "Normal_gt.mat", input.stack.images.front().size());
  return input;
}

void ExportDiligent(const std::string& run_directory, const std::string& output_directory) {
  const PhotometricStereoInput input = LoadRunStack(run_directory);
  const fs::path out(output_directory);
  fs::create_directories(out);
  std::string filenames, directions, intensities;
  char line[160];
  for (int k = 0; k < input.stack.light_count(); ++k) {
    cv::Mat signal = input.stack.images[k].clone();
    if (!input.stack.dark.empty()) signal -= input.stack.dark;
    cv::Mat grey16, rgb;
    signal.convertTo(grey16, CV_16U);  // saturates negatives at 0
    cv::merge(std::vector<cv::Mat>{grey16, grey16, grey16}, rgb);
    std::snprintf(line, sizeof(line), "%03d.png", k + 1);
    WriteImage((out / line).string(), rgb);
    filenames += std::string(line) + "\n";
    const Eigen::Vector3d& d = input.stack.light_directions[k];
    std::snprintf(line, sizeof(line), "%.9f %.9f %.9f\n", d.x(), d.y(), d.z());
    directions += line;
    const double s = input.stack.light_scales[k];
    std::snprintf(line, sizeof(line), "%.9g %.9g %.9g\n", s, s, s);
    intensities += line;
  }
  WriteFileDurably((out / "filenames.txt").string(), filenames);
  WriteFileDurably((out / "light_directions.txt").string(), directions);
  WriteFileDurably((out / "light_intensities.txt").string(), intensities);
  if (!input.truth_normals.empty()) {
    cv::Mat mask(input.truth_normals.size(), CV_8U);
    for (int r = 0; r < mask.rows; ++r)
      for (int c = 0; c < mask.cols; ++c) mask.at<std::uint8_t>(r, c) = std::isfinite(input.truth_normals.at<cv::Vec3f>(r, c)[0]) ? 255 : 0;
    WriteImage((out / "mask.png").string(), mask);
    WriteNormalsMat(out / "Normal_gt.mat", input.truth_normals);
  }
}

}  // namespace photorig::daemon
