// From `photorig run` of the simulated glossy sphere to `photorig solve svbrdf`
// and `photorig relight --model svbrdf`: one Blinn-Phong material with the
// simulator's lobe, the held-out error below the Lambertian one, a glTF asset,
// and the shared exit codes and --json document.

#include "../daemon/test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <filesystem>

namespace {

using photorig::testing::ReadText;
using photorig::testing::RunPhotorig;
using photorig::testing::SourceDir;
using photorig::testing::TempDir;

// The JSON document of a --json command's output (its progress text aside).
nlohmann::json JsonIn(const std::filesystem::path& output) {
  const std::string text = ReadText(output);
  return nlohmann::json::parse(text.substr(text.find('{'), text.rfind('}') - text.find('{') + 1));
}

TEST(SvbrdfCli, SolvesTheSimulatedGlossySphere) {
  TempDir dir;
  const std::string run = (dir.path() / "run").string();
  ASSERT_EQ(RunPhotorig("run " + SourceDir() + "/config/recipes/ps-shiny-sphere.yaml --no-solve --out " + run,
                        dir.path() / "run.log"),
            0)
      << ReadText(dir.path() / "run.log");
  // A block of the sphere, to keep the test short.
  cv::Mat frame = cv::imread((std::filesystem::path(run) / "ground_truth" / "normals.tiff").string(), cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(frame.empty());
  cv::Mat mask = cv::Mat::zeros(frame.size(), CV_8U);
  mask(cv::Rect(frame.cols / 2 - 30, frame.rows / 2 - 30, 60, 60)).setTo(255);
  const std::string mask_path = (dir.path() / "mask.png").string();
  ASSERT_TRUE(cv::imwrite(mask_path, mask));

  ASSERT_EQ(RunPhotorig("solve svbrdf --json --held-out 2 --max-materials 2 --mask " + mask_path + " --run " + run,
                        dir.path() / "solve.json"),
            0)
      << ReadText(dir.path() / "solve.json");
  const auto json = JsonIn(dir.path() / "solve.json");
  EXPECT_EQ(json["command"], "solve svbrdf");
  EXPECT_TRUE(json["ok"]);
  ASSERT_EQ(json["materials"].size(), 1u) << json.dump(2);
  const auto& m = json["materials"][0];
  EXPECT_EQ(m["model"], "blinn_phong");
  EXPECT_NEAR(m["shape"].get<double>(), 60.0, 3.0);
  // The simulator's rho_s 0.1 at e = 60 is k_s = 0.1 / c(60) = 0.375 (docs/brdf.md).
  EXPECT_NEAR(m["specular"][0].get<double>(), 0.375, 0.02);
  const auto& mean = json["held_out"]["mean"];
  EXPECT_LT(mean["per_material"]["rmse"].get<double>(), 0.5 * mean["lambertian"]["rmse"].get<double>());
  const std::filesystem::path results = std::filesystem::path(run) / "results" / "svbrdf";
  for (const char* file : {"albedo.tiff", "material.png", "flags.png", "report.json", "asset/asset.gltf", "asset/asset.bin",
                           "asset/base_colour.png", "asset/albedo.exr"})
    EXPECT_TRUE(std::filesystem::exists(results / file)) << file;
  // flags.png is the map in the legend's colours with the legend drawn to its
  // right: its "fitted" pixels are the fitted ones the report counts.
  const auto& flags = json["previews"]["flags.png"];
  const cv::Mat view = cv::imread((results / "flags.png").string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(view.empty());
  const int width = flags["map_size"][0], height = flags["map_size"][1];
  EXPECT_EQ(flags["legend_x"].get<int>(), width);
  EXPECT_GT(view.cols, width + 40) << "no legend panel";
  cv::Vec3b fitted_bgr;
  std::size_t names = 0;
  for (const auto& entry : flags["legend"]) {
    names += !entry["name"].get<std::string>().empty();
    if (entry["name"] == "fitted") fitted_bgr = cv::Vec3b(entry["rgb"][2], entry["rgb"][1], entry["rgb"][0]);
  }
  EXPECT_EQ(names, 6u);
  cv::Mat fitted;
  cv::inRange(view(cv::Rect(0, 0, width, height)), fitted_bgr, fitted_bgr, fitted);
  EXPECT_EQ(cv::countNonZero(fitted), json["pixels"]["fitted"].get<int>());

  EXPECT_EQ(RunPhotorig("relight --model svbrdf --light 0.3,0.2,0.9 --run " + run + " --out " +
                            (dir.path() / "relit.tiff").string(),
                        dir.path() / "relight.log"),
            0)
      << ReadText(dir.path() / "relight.log");
  EXPECT_TRUE(std::filesystem::exists(dir.path() / "relit.tiff"));

  // One held-out light, shown: the same error as the solve's check for that
  // light, and the written frames give it back.
  const auto& first = json["held_out"]["errors"][0];
  const int light = first["light"].get<int>();
  double solve_rmse = 0.0;
  for (const auto& e : json["held_out"]["errors"])
    if (e["light"] == light && e["method"] == "per_material") solve_rmse = e["rmse"].get<double>();
  const std::string held = (dir.path() / "held.tiff").string();
  ASSERT_EQ(RunPhotorig("relight --json --model svbrdf --held-out " + std::to_string(light) + " --run " + run + " --out " + held,
                        dir.path() / "held.json"),
            0)
      << ReadText(dir.path() / "held.json");
  const auto held_json = JsonIn(dir.path() / "held.json");
  EXPECT_EQ(held_json["method"], "per_material");
  EXPECT_NEAR(held_json["rmse"].get<double>(), solve_rmse, 1e-9 * solve_rmse);
  EXPECT_LT(held_json["rmse"].get<double>(), 0.5 * held_json["methods"]["lambertian"]["rmse"].get<double>());
  const cv::Mat predicted = cv::imread(held, cv::IMREAD_UNCHANGED);
  const cv::Mat measured = cv::imread(held_json["measured"].get<std::string>(), cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(predicted.empty());
  ASSERT_EQ(predicted.size(), measured.size());
  double sum = 0.0;
  long long count = 0;
  for (int i = 0; i < static_cast<int>(predicted.total()); ++i) {
    const float p = predicted.ptr<float>()[i], m = measured.ptr<float>()[i];
    if (std::isfinite(p) && std::isfinite(m)) sum += (p - m) * (p - m), ++count;
  }
  ASSERT_GT(count, 1000);
  EXPECT_NEAR(std::sqrt(sum / count), solve_rmse, 1e-4 * solve_rmse);
  EXPECT_TRUE(std::filesystem::exists(held_json["preview"].get<std::string>()));
  EXPECT_EQ(RunPhotorig("relight --held-out 9999 --run " + run + " --out " + held, dir.path() / "bad.log"), 2)
      << ReadText(dir.path() / "bad.log");
}

// The same sphere on the near dome through its pinhole camera: the fits see
// each pixel's own LED vectors, irradiances and line of sight, and recover
// the simulator's lobe as on the distant dome; the held-out image is
// predicted with the same geometry.
TEST(SvbrdfCli, NearLedsAndAPinholeCameraAreSeenFromEachPixel) {
  TempDir dir;
  const std::string run = (dir.path() / "run").string();
  ASSERT_EQ(RunPhotorig("run " + SourceDir() + "/config/recipes/ps-shiny-sphere.yaml --rig " + SourceDir() +
                            "/config/rigs/sim-dome-near.yaml --no-solve --out " + run,
                        dir.path() / "run.log"),
            0)
      << ReadText(dir.path() / "run.log");
  ASSERT_EQ(RunPhotorig("solve svbrdf --json --held-out 2 --max-materials 2 --method blinn-phong --no-gltf --run " + run,
                        dir.path() / "solve.json"),
            0)
      << ReadText(dir.path() / "solve.json");
  const auto json = JsonIn(dir.path() / "solve.json");
  EXPECT_TRUE(json["ok"]);
  const auto ps_report =
      nlohmann::json::parse(ReadText(std::filesystem::path(run) / "results" / "svbrdf" / "ps" / "report.json"));
  EXPECT_EQ(ps_report["light_model"]["model"], "near");
  const nlohmann::json* largest = nullptr;
  for (const auto& m : json["materials"])
    if (!largest || m["pixels"].get<int>() > (*largest)["pixels"].get<int>()) largest = &m;
  ASSERT_NE(largest, nullptr) << json.dump(2);
  EXPECT_EQ((*largest)["model"], "blinn_phong");
  EXPECT_NEAR((*largest)["shape"].get<double>(), 60.0, 3.0);
  EXPECT_NEAR((*largest)["specular"][0].get<double>(), 0.375, 0.02);
  const auto& mean = json["held_out"]["mean"];
  EXPECT_LT(mean["per_material"]["rmse"].get<double>(), 0.5 * mean["lambertian"]["rmse"].get<double>());
  const int light = json["held_out"]["errors"][0]["light"].get<int>();
  double solve_rmse = 0.0;
  for (const auto& e : json["held_out"]["errors"])
    if (e["light"] == light && e["method"] == "per_material") solve_rmse = e["rmse"].get<double>();
  ASSERT_EQ(RunPhotorig("relight --json --model svbrdf --held-out " + std::to_string(light) + " --run " + run + " --out " +
                            (dir.path() / "held.tiff").string(),
                        dir.path() / "held.json"),
            0)
      << ReadText(dir.path() / "held.json");
  EXPECT_NEAR(JsonIn(dir.path() / "held.json")["rmse"].get<double>(), solve_rmse, 1e-9 * solve_rmse);
}

TEST(SvbrdfCli, UsageErrorsExitTwo) {
  TempDir dir;
  EXPECT_EQ(RunPhotorig("solve svbrdf --json", dir.path() / "none.json"), 2) << ReadText(dir.path() / "none.json");
  const std::string text = ReadText(dir.path() / "none.json");
  const auto json = nlohmann::json::parse(text.substr(text.find('{'), text.rfind('}') - text.find('{') + 1));
  EXPECT_FALSE(json["ok"]);
  EXPECT_EQ(json["exit_code"], 2);
  EXPECT_EQ(RunPhotorig("solve svbrdf --max-materials 0 --dataset " + dir.path().string(), dir.path() / "k.log"), 2);
  EXPECT_EQ(RunPhotorig("relight --model svbrdf --light 0,0,1 --run " + dir.path().string() + " --out x.tiff",
                        dir.path() / "relight.log"),
            2)
      << ReadText(dir.path() / "relight.log");
  EXPECT_EQ(RunPhotorig("relight --held-out 0 --run " + dir.path().string() + " --out x.tiff", dir.path() / "held.log"), 2)
      << ReadText(dir.path() / "held.log");
  EXPECT_EQ(RunPhotorig("relight --held-out 0 --light 0,0,1 --run " + dir.path().string() + " --out x.tiff",
                        dir.path() / "both.log"),
            2);
}

}  // namespace
