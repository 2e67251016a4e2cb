// What the browser interface needs from photorigd: its files served without a
// token but under the Host rule, the recipes to choose from, and a run's
// images as previews, statistics and values.

#include "photorig/daemon/service/internal/api_client.h"
#include "photorig/daemon/service/api_server.h"
#include "photorig/daemon/io/image_io.h"
#include "served_api.h"
#include "test_support.h"

#include <gtest/gtest.h>
#include <httplib.h>
#include <opencv2/imgcodecs.hpp>

#include <cstring>
#include <filesystem>
#include <thread>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using photorig::testing::SmallRecipeYaml;
using photorig::testing::SmallRigYaml;
using photorig::testing::TempDir;

const char kToken[] = "a-test-token-of-sufficient-length";

cv::Mat DecodePng(const std::string& bytes) {
  return cv::imdecode(std::vector<unsigned char>(bytes.begin(), bytes.end()), cv::IMREAD_COLOR);
}

class Web : public ::testing::Test {
 protected:
  void StartDaemon(const std::string& token = "", std::size_t max_image_values = ApiOptions{}.max_image_values) {
    ServiceOptions options;
    options.data_root = (dir_.path() / "data").string();
    options.rig_path = dir_.Write("rig.yaml", SmallRigYaml());
    options.solve = false;
    options.recipe_folders = {(dir_.path() / "config-recipes").string()};
    dir_.Write("config-recipes/small.yaml", SmallRecipeYaml());
    dir_.Write("config-recipes/broken.yaml", "recipe: [\n");
    dir_.Write("config-recipes/notes.txt", "not a recipe");
    ApiOptions api;
    api.port = 0;
    api.token = token;
    api.max_image_values = max_image_values;
    api.web_root = (dir_.path() / "web").string();
    dir_.Write("web/index.html", "<!doctype html><title>photorig</title>");
    dir_.Write("web/app.js", "export const page = 1;");
    api.javascript_root = (dir_.path() / "javascript").string();
    dir_.Write("javascript/three/build/three.module.js", "export const REVISION = '111';");
    served_ = std::make_unique<ServedApi>(options, api);
  }
  ApiClient Client(const std::string& token = "") { return served_->Client(token); }
  // A finished 5-frame run of the small dome; its id.
  std::string FinishedRun() {
    ApiClient client = Client();
    const auto submitted = client.Post("/api/v1/runs", {{"name", "small.yaml"}, {"recipe", SmallRecipeYaml()}});
    EXPECT_EQ(submitted.http_status, 201) << submitted.body.dump();
    const std::string id = submitted.body["id"];
    EXPECT_EQ(client.FollowEvents(id, [](const std::string&, const json&) { return true; }), "");
    return id;
  }

  TempDir dir_;
  std::unique_ptr<ServedApi> served_;
};

TEST_F(Web, PagesAndLibrariesNeedNoTokenButTheApiDoesAndForeignHostsAreRefused) {
  StartDaemon(kToken);
  httplib::Client http("127.0.0.1", served_->port());
  const auto page = http.Get("/");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_NE(page->body.find("<title>photorig</title>"), std::string::npos);
  const auto script = http.Get("/app.js");
  ASSERT_TRUE(script);
  EXPECT_EQ(script->get_header_value("Content-Type"), "text/javascript");  // ES modules need a JavaScript type
  const auto library = http.Get("/vendor/three/build/three.module.js");
  ASSERT_TRUE(library);
  EXPECT_EQ(library->status, 200);
  EXPECT_EQ(library->body, "export const REVISION = '111';");
  // Only the two libraries' folders are served, and nothing outside them.
  EXPECT_EQ(http.Get("/vendor/three/../../web/index.html")->status, 404);
  EXPECT_EQ(http.Get("/api/v1/health")->status, 401);
  EXPECT_EQ(http.Get("/api/v1/recipes")->status, 401);
  const auto rebound = http.Get("/", {{"Host", "attacker.example:8750"}});
  ASSERT_TRUE(rebound);
  EXPECT_EQ(rebound->status, 403);
}

TEST_F(Web, RecipesListsTheConfigFolderAndTheDataRootButNotSubmittedCopies) {
  StartDaemon();
  dir_.Write("data/recipes/mine.yaml", SmallRecipeYaml());
  FinishedRun();  // leaves data/recipes/000001-small.yaml
  const auto reply = Client().Get("/api/v1/recipes");
  ASSERT_EQ(reply.http_status, 200) << reply.body.dump();
  std::vector<std::string> listed;
  for (const json& recipe : reply.body["recipes"])
    listed.push_back(recipe["source"].get<std::string>() + ":" + recipe["file"].get<std::string>());
  EXPECT_EQ(listed, (std::vector<std::string>{"config:broken.yaml", "config:small.yaml", "data_root:mine.yaml"}));
  const json& small = reply.body["recipes"][1];
  EXPECT_EQ(small["name"], "small");
  EXPECT_EQ(small["text"], SmallRecipeYaml());
  EXPECT_TRUE(fs::path(small["path"].get<std::string>()).is_absolute());
  EXPECT_TRUE(reply.body["recipes"][0].contains("error"));  // listed, saying why it does not load
}

TEST_F(Web, PreviewsStatsAndValuesDescribeTheFrameOnDisk) {
  StartDaemon();
  const std::string id = FinishedRun();
  const std::string file = "frames/0001_led00.png";
  const cv::Mat frame = ReadImage((dir_.path() / "data/runs" / id / file).string());
  ASSERT_EQ(frame.type(), CV_16UC1);
  double low = 0, high = 0;
  cv::minMaxLoc(frame, &low, &high);
  ASSERT_GT(high, low);
  const double saturation = (low + high) / 2;
  const int above = cv::countNonZero(frame >= saturation);

  httplib::Client http("127.0.0.1", served_->port());
  const std::string base = "/api/v1/runs/" + id;
  const auto values = http.Get(base + "/values/" + file);
  ASSERT_TRUE(values);
  ASSERT_EQ(values->status, 200) << values->body;
  EXPECT_EQ(values->get_header_value("X-Image-Width"), "32");
  EXPECT_EQ(values->get_header_value("X-Image-Height"), "32");
  EXPECT_EQ(values->get_header_value("X-Image-Channels"), "1");
  ASSERT_EQ(values->body.size(), 32u * 32u * sizeof(float));
  std::vector<float> decoded(32 * 32);
  std::memcpy(decoded.data(), values->body.data(), values->body.size());
  for (int i = 0; i < 32 * 32; ++i) ASSERT_EQ(decoded[i], frame.at<std::uint16_t>(i / 32, i % 32)) << "pixel " << i;

  const std::string query = "?saturation=" + std::to_string(saturation);
  const auto stats = Client().Get(base + "/stats/" + file + query);
  ASSERT_EQ(stats.http_status, 200) << stats.body.dump();
  EXPECT_EQ(stats.body["min"], low);
  EXPECT_EQ(stats.body["max"], high);
  EXPECT_EQ(stats.body["clipped"], above);
  std::uint64_t counted = 0;
  for (const json& bin : stats.body["histogram"]) counted += bin.get<std::uint64_t>();
  EXPECT_EQ(counted, 32u * 32u);

  const auto preview = http.Get(base + "/preview/" + file + query + "&gamma=1");
  ASSERT_TRUE(preview);
  ASSERT_EQ(preview->status, 200) << preview->body;
  EXPECT_EQ(preview->get_header_value("Content-Type"), "image/png");
  EXPECT_EQ(preview->get_header_value("X-Preview-Clipped"), std::to_string(above));
  EXPECT_EQ(std::stod(preview->get_header_value("X-Preview-Low")), low);
  const cv::Mat png = DecodePng(preview->body);
  ASSERT_EQ(png.size(), frame.size());
  int red = 0;
  for (int i = 0; i < 32 * 32; ++i) red += png.at<cv::Vec3b>(i / 32, i % 32) == cv::Vec3b(0, 0, 255);
  EXPECT_EQ(red, above);  // every clipped pixel red, and only those
  const cv::Point darkest = [&] {
    cv::Point at;
    cv::minMaxLoc(frame, nullptr, nullptr, &at);
    return at;
  }();
  EXPECT_EQ(png.at<cv::Vec3b>(darkest), cv::Vec3b(0, 0, 0));  // `low` maps to black

  const auto small = http.Get(base + "/preview/" + file + "?max_side=16");
  ASSERT_TRUE(small);
  const cv::Mat shrunk = DecodePng(small->body);
  EXPECT_EQ(shrunk.size(), cv::Size(16, 16));
}

TEST_F(Web, ValuesAnswersImagesUpToItsLimitAndRefusesLargerOnesSayingWhy) {
  StartDaemon("", 32 * 32);  // the small dome's frames are 32 x 32, one channel
  const std::string id = FinishedRun();
  const std::string base = "/api/v1/runs/" + id;
  // A 3-channel float map of the same size holds three times the limit.
  cv::Mat normals(32, 32, CV_32FC3, cv::Scalar(0, 0, 1));
  fs::create_directories(dir_.path() / "data/runs" / id / "results");
  WriteFloatTiff((dir_.path() / "data/runs" / id / "results/normals.tiff").string(), normals);
  httplib::Client http("127.0.0.1", served_->port());
  const auto frame = http.Get(base + "/values/frames/0001_led00.png");
  ASSERT_TRUE(frame);
  EXPECT_EQ(frame->status, 200) << frame->body;
  EXPECT_EQ(frame->body.size(), 32u * 32u * sizeof(float));
  const auto refused = Client().Get(base + "/values/results/normals.tiff");
  EXPECT_EQ(refused.http_status, 413);
  EXPECT_NE(refused.body.value("error", "").find("3072 values (32 x 32 x 3), more than the 1024"), std::string::npos)
      << refused.body.dump();
  // The same map stays readable shrunk.
  const auto preview = http.Get(base + "/preview/results/normals.tiff");
  ASSERT_TRUE(preview);
  EXPECT_EQ(preview->status, 200);
}

TEST_F(Web, ImageRoutesKeepToTheRunAndToImages) {
  StartDaemon();
  const std::string id = FinishedRun();
  httplib::Client http("127.0.0.1", served_->port());
  const std::string base = "/api/v1/runs/" + id;
  EXPECT_EQ(http.Get(base + "/values/../../queue.sqlite")->status, 400);
  EXPECT_EQ(http.Get(base + "/preview/%2E%2E/%2E%2E/queue.sqlite")->status, 400);
  EXPECT_EQ(http.Get(base + "/values/manifest.json")->status, 400);
  EXPECT_EQ(http.Get(base + "/stats/frames/9999_none.png")->status, 404);
  // A name longer than the file system allows is a missing file, not a 500.
  EXPECT_EQ(http.Get(base + "/stats/frames/" + std::string(300, 'x') + ".png")->status, 404);
  EXPECT_EQ(http.Get(base + "/files/" + std::string(300, 'x') + ".json")->status, 404);
  EXPECT_EQ(http.Get("/api/v1/runs/000099-none/preview/frames/0001_led00.png")->status, 404);
  EXPECT_EQ(http.Get(base + "/preview/frames/0001_led00.png?gamma=0")->status, 400);
  EXPECT_EQ(http.Get(base + "/preview/frames/0001_led00.png?low=abc")->status, 400);
}

}  // namespace
}  // namespace photorig::daemon
