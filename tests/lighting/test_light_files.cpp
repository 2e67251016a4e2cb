#include "photorig/solvers/lighting/light_files.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

namespace photorig::solvers::lighting {
namespace {

// Unique to this process: CTest runs tests of one file in parallel processes.
std::string TempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("photorig_lighting_" + std::to_string(::getpid()) + "_" + name)).string();
}

void WriteText(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

TEST(LightFiles, LpRoundTripKeepsNamesAndDirections) {
  const std::vector<LightPosition> lights = {{"img_000.png", {0.1, -0.2, 0.974679434}},
                                             {"img_001.png", {-0.5, 0.5, 0.707106781}}};
  const std::string path = TempPath("roundtrip.lp");
  WriteLpFile(path, lights);
  std::ifstream in(path);
  std::string first;
  std::getline(in, first);
  EXPECT_EQ(first, "2");
  const std::vector<LightPosition> read = ReadLpFile(path);
  ASSERT_EQ(read.size(), 2u);
  EXPECT_EQ(read[1].image, "img_001.png");
  EXPECT_NEAR((read[0].direction - lights[0].direction).norm(), 0.0, 1e-8);
  std::filesystem::remove(path);
}

TEST(LightFiles, MalformedLpNamesFileAndLine) {
  const std::string path = TempPath("bad.lp");
  WriteText(path, "3\na.png 0 0 1\nb.png 0 zero 1\nc.png 0 0 1\n");
  try {
    ReadLpFile(path);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path + ":3:"), std::string::npos) << e.what();
  }
  WriteText(path, "3\na.png 0 0 1\n");
  EXPECT_THROW(ReadLpFile(path), std::runtime_error);
  std::filesystem::remove(path);
}

TEST(LightFiles, DiligentTriplesRoundTripAndRejectShortRows) {
  const std::string path = TempPath("light_directions.txt");
  WriteTriplesFile(path, {{0.1, 0.2, 0.97}, {1.0, 0.9, 0.8}});
  const auto rows = ReadTriplesFile(path);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_DOUBLE_EQ(rows[1].y(), 0.9);
  WriteText(path, "0.1 0.2 0.97\n0.5 0.5\n");
  try {
    ReadTriplesFile(path);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(":2:"), std::string::npos) << e.what();
  }
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace photorig::solvers::lighting
