// A DiLiGenT folder (LoadDiligent): the input replaces one file of an
// otherwise valid 8x8, four-light folder. The first byte picks the file,
// the rest is its content. The contract is a PhotometricStereoInput or a
// ConfigError naming the file and line.
#include "fuzz_support.h"
#include "photorig/config/yaml_node.h"
#include "photorig/daemon/pipelines/diligent.h"

#include <matio.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <array>
#include <vector>

namespace {

namespace fs = std::filesystem;
constexpr int kSize = 8;  // small: every input decodes all five images
constexpr std::array<const char*, 6> kFiles = {"filenames.txt", "light_directions.txt", "light_intensities.txt",
                                              "mask.png",      "001.png",              "Normal_gt.mat"};

// Writes the valid folder and returns each fuzzed file's original bytes, to put back after each input.
std::vector<std::string> WriteValidFolder(const fs::path& dir) {
  fs::create_directories(dir);
  photorig::fuzz::WriteText(dir / "filenames.txt", "001.png\n002.png\n003.png\n004.png\n");
  photorig::fuzz::WriteText(dir / "light_directions.txt",
                            "0.3 0.2 0.93\n-0.3 0.2 0.93\n0.2 -0.3 0.93\n-0.2 -0.3 0.93\n");
  photorig::fuzz::WriteText(dir / "light_intensities.txt", "1 1 1\n1.2 1.1 1.0\n0.9 1.0 1.1\n1 1 1\n");
  for (int k = 1; k <= 4; ++k) {
    const cv::Mat image(kSize, kSize, CV_16UC3, cv::Scalar::all(25000 + 100 * k));
    cv::imwrite((dir / ("00" + std::to_string(k) + ".png")).string(), image);
  }
  cv::Mat mask = cv::Mat::zeros(kSize, kSize, CV_8U);
  cv::circle(mask, {kSize / 2, kSize / 2}, kSize / 3, cv::Scalar(255), cv::FILLED);
  cv::imwrite((dir / "mask.png").string(), mask);
  std::vector<double> normals(kSize * kSize * 3, 0.0);
  for (int r = 0; r < kSize; ++r)
    for (int c = 0; c < kSize; ++c)
      if (mask.at<std::uint8_t>(r, c)) normals[r + kSize * (c + kSize * 2)] = 1.0;  // (0, 0, 1), column-major
  const std::string mat_path = (dir / "Normal_gt.mat").string();
  mat_t* file = Mat_CreateVer(mat_path.c_str(), nullptr, MAT_FT_MAT5);
  size_t dims[3] = {kSize, kSize, 3};
  matvar_t* variable = Mat_VarCreate("Normal_gt", MAT_C_DOUBLE, MAT_T_DOUBLE, 3, dims, normals.data(), 0);
  Mat_VarWrite(file, variable, MAT_COMPRESSION_NONE);
  Mat_VarFree(variable);
  Mat_Close(file);
  std::vector<std::string> originals;
  for (std::size_t i = 0; i < kFiles.size(); ++i) {
    originals.push_back(photorig::fuzz::ReadBytes(dir / kFiles[i]));
    photorig::fuzz::WriteSeed(kFiles[i], static_cast<std::uint8_t>(i), originals.back());
  }
  photorig::daemon::LoadDiligent(dir.string());  // the harness's own check: the folder is valid
  return originals;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const fs::path dir = photorig::fuzz::WorkDir() / "diligent";
  static const std::vector<std::string> originals = WriteValidFolder(dir);
  if (size == 0) return 0;
  const std::size_t which = data[0] % kFiles.size();
  photorig::fuzz::WriteBytes(dir / kFiles[which], data + 1, size - 1);
  try {
    photorig::daemon::LoadDiligent(dir.string());
  } catch (const photorig::config::ConfigError&) {
  }
  photorig::fuzz::WriteText(dir / kFiles[which], originals[which]);
  return 0;
}
