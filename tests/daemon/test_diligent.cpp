// A DiLiGenT-layout folder is read only when it is what it claims to be: each
// way a folder can be subtly wrong (and used to solve with "success") is an
// error naming the file and line.

#include "photorig/daemon/pipelines/diligent.h"
#include "photorig/config/rig.h"
#include "photorig/config/sim.h"
#include "photorig/config/yaml_node.h"
#include "test_support.h"

#include <matio.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <gtest/gtest.h>

#include <cmath>

namespace photorig::daemon {
namespace {

using testing::TempDir;

constexpr int kSize = 16;

// A 16x16 folder of four 16-bit RGB images, a disc mask and unit normals on
// the disc (zeros off it, as DiLiGenT stores them).
class DiligentFolder : public ::testing::Test {
 protected:
  void SetUp() override {
    names_ = "001.png\n002.png\n003.png\n004.png\n";
    directions_ = "0.3 0.2 0.93\n-0.3 0.2 0.93\n0.2 -0.3 0.93\n-0.2 -0.3 0.93\n";
    intensities_ = "1 1 1\n1.2 1.1 1.0\n0.9 1.0 1.1\n1 1 1\n";
    for (int k = 1; k <= 4; ++k) WriteImageFile(k, CV_16U);
    mask_ = cv::Mat::zeros(kSize, kSize, CV_8U);
    cv::circle(mask_, {kSize / 2, kSize / 2}, kSize / 3, cv::Scalar(255), cv::FILLED);
    cv::imwrite((dir_.path() / "mask.png").string(), mask_);
  }

  void WriteImageFile(int k, int depth) {
    cv::Mat image(kSize, kSize, CV_MAKETYPE(depth, 3), cv::Scalar::all(depth == CV_8U ? 100 : 25000 + 100 * k));
    char name[16];
    std::snprintf(name, sizeof(name), "%03d.png", k);
    cv::imwrite((dir_.path() / name).string(), image);
  }

  // Normal_gt as DiLiGenT stores it; `scale` != 1 makes the vectors non-unit.
  void WriteNormals(double scale) const {
    std::vector<double> data(kSize * kSize * 3, 0.0);
    for (int r = 0; r < kSize; ++r)
      for (int c = 0; c < kSize; ++c)
        if (mask_.at<std::uint8_t>(r, c)) data[r + kSize * (c + kSize * 2)] = scale;  // (0, 0, scale), column-major
    const std::string path = (dir_.path() / "Normal_gt.mat").string();
    mat_t* file = Mat_CreateVer(path.c_str(), nullptr, MAT_FT_MAT5);
    size_t dims[3] = {kSize, kSize, 3};
    matvar_t* variable = Mat_VarCreate("Normal_gt", MAT_C_DOUBLE, MAT_T_DOUBLE, 3, dims, data.data(), 0);
    Mat_VarWrite(file, variable, MAT_COMPRESSION_NONE);
    Mat_VarFree(variable);
    Mat_Close(file);
  }

  PhotometricStereoInput Load() {
    dir_.Write("filenames.txt", names_);
    dir_.Write("light_directions.txt", directions_);
    dir_.Write("light_intensities.txt", intensities_);
    return LoadDiligent(dir_.path().string());
  }

  // The ConfigError's text, or "" when the folder loaded.
  std::string LoadError() {
    try {
      Load();
    } catch (const config::ConfigError& e) {
      return e.what();
    }
    return "";
  }

  TempDir dir_;
  std::string names_, directions_, intensities_;
  cv::Mat mask_;
};

TEST_F(DiligentFolder, AWellFormedFolderLoadsWithUnitDirectionsAndTruth) {
  WriteNormals(1.0);
  const PhotometricStereoInput input = Load();
  ASSERT_EQ(input.stack.light_count(), 4);
  for (const auto& d : input.stack.light_directions) EXPECT_NEAR(d.norm(), 1.0, 1e-12);
  EXPECT_EQ(cv::countNonZero(input.object_mask), cv::countNonZero(mask_));
  EXPECT_FLOAT_EQ(input.truth_normals.at<cv::Vec3f>(kSize / 2, kSize / 2)[2], 1.0f);
  EXPECT_TRUE(std::isnan(input.truth_normals.at<cv::Vec3f>(0, 0)[0]));  // off the object: not counted
}

// Each frame as the solve takes it, checked pixel by pixel against the
// formula: grey = sum over B, G, R of I_c mean(L) / (3 L_c); colour in R G B
// with every channel of a pixel at the top code clipped (+inf); each frame
// its own (distinct, continuous) image; grey saved as RGB stays grey.
TEST_F(DiligentFolder, EachFrameIsItsOwnChannelsBalancedByItsLightWithTopCodesClipped) {
  cv::RNG random(7);
  std::vector<cv::Mat> written;
  for (int k = 1; k <= 4; ++k) {
    cv::Mat image(kSize, kSize, CV_16UC3);
    random.fill(image, cv::RNG::UNIFORM, 0, 60000);
    image.at<cv::Vec3w>(3, 5)[k % 3] = 65535;  // one channel at the top code
    char name[16];
    std::snprintf(name, sizeof(name), "%03d.png", k);
    cv::imwrite((dir_.path() / name).string(), image);
    written.push_back(image);
  }
  const std::vector<cv::Vec3d> rgb_intensity = {{1, 1, 1}, {1.2, 1.1, 1.0}, {0.9, 1.0, 1.1}, {1, 1, 1}};
  const PhotometricStereoInput input = Load();
  ASSERT_EQ(input.stack.light_count(), 4);
  ASSERT_TRUE(input.color);
  for (int k = 0; k < 4; ++k) {
    const cv::Mat& grey = input.stack.images[k];
    const cv::Mat& colour = input.color->images[k];
    ASSERT_EQ(grey.type(), CV_32F);
    ASSERT_EQ(colour.type(), CV_32FC3);
    EXPECT_TRUE(grey.isContinuous() && colour.isContinuous());
    if (k > 0) {
      EXPECT_NE(grey.data, input.stack.images[k - 1].data);
    }
    const cv::Vec3d& l = rgb_intensity[k];
    const double mean = (l[0] + l[1] + l[2]) / 3.0;
    EXPECT_DOUBLE_EQ(input.stack.light_scales[k], mean);
    for (int y = 0; y < kSize; ++y)
      for (int x = 0; x < kSize; ++x) {
        const cv::Vec3w bgr = written[k].at<cv::Vec3w>(y, x);
        double expected = 0.0;
        for (int c = 0; c < 3; ++c) expected += bgr[c] * mean / (3.0 * l[2 - c]);
        ASSERT_NEAR(grey.at<float>(y, x), expected, 1e-5 * expected) << "frame " << k << " at " << x << "," << y;
        const cv::Vec3f rgb = colour.at<cv::Vec3f>(y, x);
        const bool top = bgr[0] == 65535 || bgr[1] == 65535 || bgr[2] == 65535;
        for (int c = 0; c < 3; ++c) {
          if (top)
            ASSERT_TRUE(std::isinf(rgb[c])) << "frame " << k << " at " << x << "," << y;
          else
            ASSERT_EQ(rgb[c], bgr[2 - c]) << "frame " << k << " at " << x << "," << y;
        }
      }
  }
}

TEST_F(DiligentFolder, GreyImagesSavedAsRgbLoadAsAGreyStack) {
  const PhotometricStereoInput input = Load();  // SetUp's images: all three channels equal
  EXPECT_FALSE(input.color);
  ASSERT_EQ(input.stack.light_count(), 4);
  // 002's intensities are R 1.2, G 1.1, B 1.0: grey = 25200 mean(L) / 3 sum_c 1 / L_c.
  const double mean = 1.1, expected = 25200.0 * mean / 3.0 * (1.0 / 1.2 + 1.0 / 1.1 + 1.0 / 1.0);
  EXPECT_NEAR(input.stack.images[1].at<float>(4, 4), expected, 1e-5 * expected);
}

TEST_F(DiligentFolder, EightBitImagesAmongSixteenBitOnesAreRefusedByName) {
  WriteImageFile(3, CV_8U);
  const std::string error = LoadError();
  EXPECT_NE(error.find("003.png"), std::string::npos) << error;
  EXPECT_NE(error.find("8-bit"), std::string::npos) << error;
  EXPECT_NE(error.find("16-bit"), std::string::npos) << error;
}

TEST_F(DiligentFolder, NormalsThatAreNotUnitVectorsAreNotGroundTruth) {
  WriteNormals(0.0);  // what a truncated or zeroed file reads as
  const std::string error = LoadError();
  EXPECT_NE(error.find("Normal_gt.mat"), std::string::npos) << error;
  EXPECT_NE(error.find("unit normals at 0 of"), std::string::npos) << error;
}

TEST_F(DiligentFolder, ATruncatedMatFileIsRefused) {
  WriteNormals(1.0);
  const auto path = dir_.path() / "Normal_gt.mat";
  std::filesystem::resize_file(path, std::filesystem::file_size(path) / 2);
  const std::string error = LoadError();
  EXPECT_NE(error.find("Normal_gt.mat"), std::string::npos) << error;
}

// Found by the DiLiGenT fuzzer: 22 bytes that matio took for a headerless
// MATLAB 4 file and sized in gigabytes. Refused from the header, before matio.
TEST_F(DiligentFolder, ADamagedMatFileIsRefusedFromItsHeader) {
  const std::string garbage("\x00\x00\x00\x00\x60\x60\x00\x51\x70\x77\x00\x0f\x0a\x70\x67\xff\x31\x2e\x0a\x70\x67\x00", 22);
  std::ofstream(dir_.path() / "Normal_gt.mat", std::ios::binary | std::ios::trunc) << garbage;
  const std::string error = LoadError();
  EXPECT_NE(error.find("Normal_gt.mat: shorter than a MATLAB file's 128-byte header"), std::string::npos) << error;
  WriteNormals(1.0);  // and a whole file whose first variable claims more than the file holds
  const auto path = dir_.path() / "Normal_gt.mat";
  std::filesystem::resize_file(path, 200);
  EXPECT_NE(LoadError().find("truncated or damaged"), std::string::npos) << LoadError();
}

TEST_F(DiligentFolder, AnEmptyMaskIsRefused) {
  cv::imwrite((dir_.path() / "mask.png").string(), cv::Mat::zeros(kSize, kSize, CV_8U));
  const std::string error = LoadError();
  EXPECT_NE(error.find("mask.png"), std::string::npos) << error;
  EXPECT_NE(error.find("empty"), std::string::npos) << error;
}

TEST_F(DiligentFolder, AMaskOfAnotherSizeNamesTheFileAndBothSizes) {
  cv::imwrite((dir_.path() / "mask.png").string(), cv::Mat::ones(kSize, kSize + 1, CV_8U));
  const std::string error = LoadError();
  EXPECT_NE(error.find("mask.png: 17x16, but the images are 16x16"), std::string::npos) << error;
}

TEST_F(DiligentFolder, VanishingIntensitiesAreRefusedWithTheirLine) {
  intensities_ = "1 1 1\n1e-300 1e-300 1e-300\n1 1 1\n1 1 1\n";
  const std::string error = LoadError();
  EXPECT_NE(error.find("light_intensities.txt:2:"), std::string::npos) << error;
}

TEST_F(DiligentFolder, ANameListedTwiceIsRefused) {
  names_ = "001.png\n002.png\n001.png\n004.png\n";
  const std::string error = LoadError();
  EXPECT_NE(error.find("filenames.txt:3:"), std::string::npos) << error;
  EXPECT_NE(error.find("first on line 1"), std::string::npos) << error;
}

TEST_F(DiligentFolder, ALightBelowTheHorizonIsRefused) {
  directions_ = "0.3 0.2 0.93\n-0.3 0.2 -0.93\n0.2 -0.3 0.93\n-0.2 -0.3 0.93\n";
  const std::string error = LoadError();
  EXPECT_NE(error.find("light_directions.txt:2:"), std::string::npos) << error;
  EXPECT_NE(error.find("below the object's horizon"), std::string::npos) << error;
}

TEST_F(DiligentFolder, AFourthNumberOnADirectionLineIsRefused) {
  directions_ = "0.3 0.2 0.93\n-0.3 0.2 0.93 1\n0.2 -0.3 0.93\n-0.2 -0.3 0.93\n";
  const std::string error = LoadError();
  EXPECT_NE(error.find("light_directions.txt:2:"), std::string::npos) << error;
  EXPECT_NE(error.find("got more"), std::string::npos) << error;
}

TEST_F(DiligentFolder, HugeDirectionsNormaliseWithoutOverflow) {
  directions_ = "1e308 1e308 1e308\n-0.3 0.2 0.93\n0.2 -0.3 0.93\n-0.2 -0.3 0.93\n";
  const PhotometricStereoInput input = Load();
  EXPECT_NEAR(input.stack.light_directions[0].z(), 1.0 / std::sqrt(3.0), 1e-12);
}

TEST_F(DiligentFolder, AListedImageThatIsMissingIsNamedWithItsLine) {
  names_ = "001.png\n002.png\n003.png\n005.png\n";
  const std::string error = LoadError();
  EXPECT_NE(error.find("filenames.txt:4:"), std::string::npos) << error;
  EXPECT_NE(error.find("005.png"), std::string::npos) << error;
}

TEST_F(DiligentFolder, ANameLongerThanTheSystemAllowsIsNamedWithItsLine) {
  // The file system's refusal (ENAMETOOLONG) escaped as a filesystem_error (a fuzzer's find).
  names_ = "001.png\n002.png\n" + std::string(300, 'x') + ".png\n004.png\n";
  const std::string error = LoadError();
  EXPECT_NE(error.find("filenames.txt:3:"), std::string::npos) << error;
  EXPECT_NE(error.find("File name too long"), std::string::npos) << error;
}

TEST_F(DiligentFolder, AnImageOrMaskThatDoesNotDecodeIsAConfigErrorNamingIt) {
  // An empty or damaged PNG escaped as a plain runtime_error, not the folder's ConfigError.
  for (const std::string name : {"002.png", "mask.png"}) {
    const std::filesystem::path file = dir_.path() / name;
    const std::string good = photorig::testing::ReadText(file);
    for (const std::string& bad : {std::string(), good.substr(0, good.size() / 2), std::string("\x89PNG\r\n")}) {
      std::ofstream(file, std::ios::binary | std::ios::trunc) << bad;
      const std::string error = LoadError();
      EXPECT_NE(error.find(name + ": cannot read as an image"), std::string::npos) << name << ": " << error;
    }
    std::ofstream(file, std::ios::binary | std::ios::trunc) << good;
  }
}

}  // namespace
}  // namespace photorig::daemon
