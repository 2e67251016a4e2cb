// README.md's everyday commands, run as written (from a scratch working
// directory, the README's recipes and rigs): each exits 0, writes only where
// it says, and the previews it writes map the data the way report.json says.
// Commands that need hardware, a server left running (photorigd,
// photorig-sim-modbus) or minutes (make bench, make charts, the vivid VM) are
// not here.

#include "photorig/config/modules.h"
#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/io/internal/previews.h"
#include "photorig/solvers/lighting/envmap.h"
#include "test_support.h"

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>

namespace {

namespace fs = std::filesystem;
using photorig::testing::ReadText;
using photorig::testing::SourceDir;
using photorig::testing::TempDir;
using nlohmann::json;

// A scratch working directory `work/` and the command's stdout and stderr
// beside it, so what a command writes into its working directory can be seen.
class Workspace {
 public:
  Workspace() { fs::create_directories(work()); }
  fs::path work() const { return dir_.path() / "work"; }
  // Runs build/bin/photorig `arguments` in work(); returns its exit code.
  int Run(const std::string& arguments) { return Shell(std::string(PHOTORIG_BIN_DIR) + "/photorig " + arguments); }
  // Runs a shell command line in work(); returns its exit code.
  int Shell(const std::string& line) {
    const std::string command = "cd '" + work().string() + "' && " + line + " > '" + (dir_.path() / "stdout").string() +
                                "' 2> '" + (dir_.path() / "stderr").string() + "' < /dev/null";
    const int status = std::system(command.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  std::string Stdout() const { return ReadText(dir_.path() / "stdout"); }
  std::string Stderr() const { return ReadText(dir_.path() / "stderr"); }
  std::string Output() const { return Stdout() + Stderr(); }
  // Names directly inside work().
  std::set<std::string> Entries() const {
    std::set<std::string> names;
    for (const auto& entry : fs::directory_iterator(work())) names.insert(entry.path().filename().string());
    return names;
  }

 private:
  TempDir dir_;
};

std::string Config(const std::string& path) { return SourceDir() + "/config/" + path; }

json Report(const fs::path& path) { return json::parse(ReadText(path)); }

cv::Mat ReadGrey(const fs::path& path) {
  cv::Mat image = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
  EXPECT_FALSE(image.empty()) << path;
  return image;
}

// A scalar preview: 0 outside the mask; inside, round(255 (v - low) / (high - low)) clipped.
void ExpectScalarPreview(const fs::path& png, const cv::Mat& values, const cv::Mat& mask, const json& mapping) {
  const cv::Mat view = ReadGrey(png);
  ASSERT_EQ(view.size(), values.size()) << png;
  const double low = mapping["low"], high = mapping["high"];
  int wrong = 0;
  for (int r = 0; r < view.rows; ++r)
    for (int c = 0; c < view.cols; ++c) {
      const float v = values.at<float>(r, c);
      const int expected = mask.at<std::uint8_t>(r, c) && std::isfinite(v)
                               ? std::clamp(static_cast<int>(std::lround(255.0 * (v - low) / (high - low))), 0, 255)
                               : 0;
      wrong += std::abs(view.at<std::uint8_t>(r, c) - expected) > 1;
    }
  EXPECT_EQ(wrong, 0) << png;
}

cv::Vec3b Bgr(const json& entry) {
  return cv::Vec3b(entry["rgb"][2].get<int>(), entry["rgb"][1].get<int>(), entry["rgb"][0].get<int>());
}

// A categorical preview: every map pixel one of the legend's colours, the
// solved pixels (mask.png) exactly those of `name`'s colour (or, when
// `name_marks_solved` is false, exactly those not of it), and every legend
// colour drawn as a swatch in the panel right of the map.
void ExpectCategoricalPreview(const fs::path& png, const cv::Mat& solved, const json& mapping, const std::string& name,
                              bool name_marks_solved) {
  const cv::Mat view = cv::imread(png.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(view.empty()) << png;
  const int width = mapping["map_size"][0], height = mapping["map_size"][1];
  ASSERT_EQ(cv::Size(width, height), solved.size()) << png;
  ASSERT_EQ(mapping["legend_x"].get<int>(), width);
  ASSERT_GT(view.cols, width) << png << ": no legend panel";
  std::map<std::string, cv::Vec3b> colours;
  for (const json& entry : mapping["legend"]) colours[entry["name"]] = Bgr(entry);
  ASSERT_TRUE(colours.count(name)) << png;
  const cv::Vec3b marker = colours[name];
  int off_palette = 0, wrong = 0;
  for (int r = 0; r < height; ++r)
    for (int c = 0; c < width; ++c) {
      const cv::Vec3b p = view.at<cv::Vec3b>(r, c);
      off_palette += std::none_of(colours.begin(), colours.end(), [&](const auto& kv) { return kv.second == p; });
      wrong += (solved.at<std::uint8_t>(r, c) != 0) != ((p == marker) == name_marks_solved);
    }
  EXPECT_EQ(off_palette, 0) << png;
  EXPECT_EQ(wrong, 0) << png;
  const cv::Mat panel = view.colRange(width, view.cols);
  for (const auto& [name, colour] : colours) {
    cv::Mat same;
    cv::inRange(panel, colour, colour, same);
    EXPECT_GE(cv::countNonZero(same), 100) << png << ": no swatch for " << name;
  }
}

// Every preview of a photometric-stereo result against the data it shows.
void ExpectPreviewsMatchTheData(const fs::path& results) {
  SCOPED_TRACE(results.string());
  const json report = Report(results / "report.json");
  ASSERT_TRUE(report.contains("previews")) << report.dump(2);
  const json& previews = report["previews"];
  const cv::Mat solved = ReadGrey(results / "mask.png");
  ASSERT_GT(cv::countNonZero(solved), 0);

  // Albedo: 255 is the recorded percentile of the solved albedo (so the view
  // is not the mask: a DN-scaled albedo no longer clips everywhere).
  const cv::Mat albedo = photorig::daemon::ReadFloatTiff((results / "albedo.tiff").string());
  const json& a = previews["albedo.png"];
  EXPECT_EQ(a["low"].get<double>(), 0.0);
  const double percentile = a["percentile"];
  EXPECT_NEAR(a["high"].get<double>(), photorig::daemon::PercentileOverMask(albedo, solved, percentile),
              1e-6 * a["high"].get<double>());
  ExpectScalarPreview(results / "albedo.png", albedo, solved, a);
  EXPECT_GT(cv::countNonZero(solved & (ReadGrey(results / "albedo.png") < 255)), 0);

  // Depth and confidence: their own min .. max over the solved pixels.
  for (const std::string name : {"depth", "confidence"}) {
    if (!fs::exists(results / (name + ".tiff"))) continue;
    const cv::Mat values = photorig::daemon::ReadFloatTiff((results / (name + ".tiff")).string());
    const json& m = previews[name + ".png"];
    double low = 0, high = 0;
    cv::minMaxLoc(values, &low, &high, nullptr, nullptr, solved & (values == values));
    EXPECT_NEAR(m["low"].get<double>(), low, 1e-6 * std::max(1.0, std::abs(low))) << name;
    EXPECT_NEAR(m["high"].get<double>(), high, 1e-6 * std::max(1.0, std::abs(high))) << name;
    if (high > low) ExpectScalarPreview(results / (name + ".png"), values, solved, m);
  }
  ExpectCategoricalPreview(results / "flags.png", solved, previews["flags.png"], "solved", true);
  ExpectCategoricalPreview(results / "model.png", solved, previews["model.png"], "none", false);
}

TEST(ReadmeCommands, ShinyRunSolveExportAndDataset) {
  Workspace ws;
  // photorig run config/recipes/ps-shiny-sphere.yaml --out runs/shiny
  ASSERT_EQ(ws.Run("run " + Config("recipes/ps-shiny-sphere.yaml") + " --out runs/shiny"), 0) << ws.Output();
  ExpectPreviewsMatchTheData(ws.work() / "runs/shiny/results/ps");
  // photorig solve ps --run runs/shiny --method auto
  ASSERT_EQ(ws.Run("solve ps --run runs/shiny --method auto"), 0) << ws.Output();
  ExpectPreviewsMatchTheData(ws.work() / "runs/shiny/results/ps");
  const json solved = Report(ws.work() / "runs/shiny/results/ps/report.json");
  EXPECT_EQ(solved["method"], "auto");
  // No mask given, dark frames present: only pixels the lights reach are solved.
  EXPECT_NE(solved["mask"]["source"].get<std::string>().find("automatic"), std::string::npos);
  const cv::Mat truth = ReadGrey(ws.work() / "runs/shiny/ground_truth/mask.png");
  const cv::Mat mask = ReadGrey(ws.work() / "runs/shiny/results/ps/mask.png");
  EXPECT_EQ(cv::countNonZero(mask & ~truth), 0) << "background pixels solved";
  // photorig export diligent --run runs/shiny --out /tmp/shiny-diligent
  ASSERT_EQ(ws.Run("export diligent --run runs/shiny --out shiny-diligent"), 0) << ws.Output();
  // photorig solve ps --dataset DiLiGenT/pmsData/ballPNG --method robust
  ASSERT_EQ(ws.Run("solve ps --dataset shiny-diligent --method robust"), 0) << ws.Output();
  ExpectPreviewsMatchTheData(ws.work() / "shiny-diligent/results/ps");
  const json dataset = Report(ws.work() / "shiny-diligent/results/ps/report.json");
  EXPECT_NE(dataset["mask"]["source"].get<std::string>().find("mask.png"), std::string::npos);
  EXPECT_EQ(ws.Entries(), (std::set<std::string>{"runs", "shiny-diligent"}));

  // With unit light intensities the albedo is in DN, thousands of them, as in
  // DiLiGenT's 16-bit folders: the preview still spans its range instead of
  // clipping to a copy of the mask.
  {
    std::ofstream ones(ws.work() / "shiny-diligent/light_intensities.txt");
    for (int k = 0; k < dataset["lights"].get<int>(); ++k) ones << "1 1 1\n";
  }
  ASSERT_EQ(ws.Run("solve ps --dataset shiny-diligent --method robust --out in-dn"), 0) << ws.Output();
  ExpectPreviewsMatchTheData(ws.work() / "in-dn");
  EXPECT_GT(Report(ws.work() / "in-dn/report.json")["previews"]["albedo.png"]["high"].get<double>(), 1000.0);
  const cv::Mat in_dn_mask = ReadGrey(ws.work() / "in-dn/mask.png");
  EXPECT_GT(cv::countNonZero(in_dn_mask & (ReadGrey(ws.work() / "in-dn/albedo.png") < 128)), 0);
}

TEST(ReadmeCommands, RunOverModbusTcp) {
  Workspace ws;
  // photorig run config/recipes/ps-sphere.yaml --rig config/rigs/sim-dome-modbus.yaml
  ASSERT_EQ(ws.Run("run " + Config("recipes/ps-sphere.yaml") + " --rig " + Config("rigs/sim-dome-modbus.yaml")), 0)
      << ws.Output();
  ASSERT_EQ(ws.Entries(), std::set<std::string>{"runs"});
  const auto run = fs::directory_iterator(ws.work() / "runs")->path();
  ExpectPreviewsMatchTheData(run / "results/ps");
}

TEST(ReadmeCommands, RunWithAGigEVisionCamera) {
#if !PHOTORIG_HAVE_SIM_GIGE
  GTEST_SKIP() << "built without the gige module";
#endif
  Workspace ws;
  // photorig run config/recipes/ps-sphere.yaml --rig config/rigs/sim-dome-gige.yaml
  ASSERT_EQ(ws.Run("run " + Config("recipes/ps-sphere.yaml") + " --rig " + Config("rigs/sim-dome-gige.yaml")), 0)
      << ws.Output();
  const auto run = fs::directory_iterator(ws.work() / "runs")->path();
  ExpectPreviewsMatchTheData(run / "results/ps");
}

TEST(ReadmeCommands, DryRunsDevicesAndTheGonioreflectometer) {
  Workspace ws;
  // photorig dry-run config/recipes/ps-sphere.yaml
  EXPECT_EQ(ws.Run("dry-run " + Config("recipes/ps-sphere.yaml")), 0) << ws.Output();
  // photorig dry-run config/recipes/gonio-sample.yaml --steps
  EXPECT_EQ(ws.Run("dry-run " + Config("recipes/gonio-sample.yaml") + " --steps"), 0) << ws.Output();
  EXPECT_TRUE(ws.Entries().empty()) << "a dry run wrote files";
  // photorig devices
  EXPECT_EQ(ws.Run("devices"), 0) << ws.Output();
  // photorig run config/recipes/gonio-sample.yaml: 12 posed frames and a dark, nothing solved.
  EXPECT_EQ(ws.Run("run " + Config("recipes/gonio-sample.yaml")), 0) << ws.Output();
  EXPECT_EQ(ws.Entries(), std::set<std::string>{"runs"});
  const fs::path run = fs::directory_iterator(ws.work() / "runs")->path();
  const json manifest = Report(run / "manifest.json");
  ASSERT_EQ(manifest["frames"].size(), 13u);
  EXPECT_EQ(std::count_if(manifest["frames"].begin(), manifest["frames"].end(),
                          [](const json& frame) { return frame["kind"] == "pose" && frame.contains("pose"); }),
            12);
  EXPECT_FALSE(fs::exists(run / "results"));
  // Photometric stereo has nothing to solve there, and says which solver does.
  EXPECT_EQ(ws.Run("solve ps --run " + run.string()), 2) << ws.Output();
  EXPECT_NE(ws.Stderr().find("a gonioreflectometer run: solve it with `photorig solve brdf --run " + run.string()),
            std::string::npos)
      << ws.Stderr();
  EXPECT_FALSE(fs::exists(run / "results"));
}

// The README's line that starts with `start`, as written up to its comment.
std::string ReadmeLine(const std::string& start) {
  std::istringstream readme(ReadText(SourceDir() + "/README.md"));
  for (std::string line; std::getline(readme, line);)
    if (line.rfind("    " + start, 0) == 0) return line.substr(4, line.find("  #") - 4);
  return "";
}

TEST(ReadmeCommands, TomographyRunSolveAndTheMpirunLineAsRoot) {
  Workspace ws;
  // photorig run config/recipes/tomography.yaml --out runs/tomo
  ASSERT_EQ(ws.Run("run " + Config("recipes/tomography.yaml") + " --out runs/tomo"), 0) << ws.Output();
  // photorig solve tomography --run runs/tomo --method cgls
  ASSERT_EQ(ws.Run("solve tomography --run runs/tomo --method cgls"), 0) << ws.Output();
  EXPECT_EQ(Report(ws.work() / "runs/tomo/results/tomography/report.json")["method"], "cgls");
  // The mpirun line as written (build/bin/ being this build's), whoever runs the tests.
  const std::string line = ReadmeLine("mpirun ");
  ASSERT_FALSE(line.empty()) << "README.md has no mpirun line";
  if (std::system("command -v mpirun > /dev/null") != 0) GTEST_SKIP() << "no mpirun here (libopenmpi-dev)";
  const int code = ws.Shell(std::regex_replace(line, std::regex("build/bin/"), std::string(PHOTORIG_BIN_DIR) + "/"));
  if (code == 2 && ws.Stderr().find("built without MPI") != std::string::npos) GTEST_SKIP() << ws.Stderr();
  ASSERT_EQ(code, 0) << line << "\n" << ws.Output();
  const json report = Report(ws.work() / "runs/tomo/results/tomography/report.json");
  EXPECT_EQ(report["method"], "sirt");
  EXPECT_TRUE(report["trusted"].get<bool>()) << report.dump(2);
}

// Normalised correlation over the pixels where `mask` is set.
double Correlation(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
  cv::Scalar mean_a, std_a, mean_b, std_b;
  cv::meanStdDev(a, mean_a, std_a, mask);
  cv::meanStdDev(b, mean_b, std_b, mask);
  const cv::Mat product = (a - mean_a[0]).mul(b - mean_b[0]);
  return cv::mean(product, mask)[0] / (std_a[0] * std_b[0]);
}

cv::Mat ReadFloat(const fs::path& path) {
  cv::Mat image;
  cv::imread(path.string(), cv::IMREAD_UNCHANGED).convertTo(image, CV_32F);
  return image;
}

TEST(ReadmeCommands, LightCalibrationEnvironmentMapAndRelighting) {
  Workspace ws;
  // photorig run config/recipes/light-calibration.yaml --out runs/lights
  ASSERT_EQ(ws.Run("run " + Config("recipes/light-calibration.yaml") + " --out runs/lights"), 0) << ws.Output();
  // photorig calibrate lights --run runs/lights --radius-mm 17 --rig config/rigs/sim-dome.yaml --out-rig NEW_RIG.yaml
  ASSERT_EQ(ws.Run("calibrate lights --run runs/lights --radius-mm 17 --rig " + Config("rigs/sim-dome.yaml") +
                   " --out-rig NEW_RIG.yaml"), 0) << ws.Output();
  EXPECT_TRUE(fs::exists(ws.work() / "NEW_RIG.yaml"));
  EXPECT_TRUE(fs::exists(ws.work() / "runs/lights/results/lights/report.json"));
  // Nothing but the asked-for rig outside the run's own results.
  EXPECT_EQ(ws.Entries(), (std::set<std::string>{"runs", "NEW_RIG.yaml"}));
  EXPECT_EQ(Report(ws.work() / "runs/lights/results/lights/report.json")["summary"]["unusable"], 0);
  // Photometric stereo sees a calibration capture for what it is, and blames no light.
  EXPECT_EQ(ws.Run("solve ps --run runs/lights"), 2) << ws.Output();
  EXPECT_NE(ws.Stderr().find("runs/lights was captured to calibrate the lights (recipe light-calibration)"),
            std::string::npos)
      << ws.Stderr();
  EXPECT_NE(ws.Stderr().find("`photorig calibrate lights --run runs/lights` solves it"), std::string::npos) << ws.Stderr();
  EXPECT_FALSE(fs::exists(ws.work() / "runs/lights/results/ps"));

  // photorig envmap --ball runs/lights/frames/0010_led09.png --dark runs/lights/frames/0000_dark.png
  //     --circle 191.5 191.5 170 --out map.hdr
  ASSERT_EQ(ws.Run("envmap --ball runs/lights/frames/0010_led09.png --dark runs/lights/frames/0000_dark.png "
                   "--circle 191.5 191.5 170 --out map.hdr"), 0) << ws.Output();
  // The sphere is where the README says: the calibration's own report.
  const json calibration = Report(ws.work() / "runs/lights/results/lights/report.json");
  EXPECT_NEAR(calibration["sphere"]["cx_px"].get<double>(), 191.5, 0.1);
  EXPECT_NEAR(calibration["sphere"]["cy_px"].get<double>(), 191.5, 0.1);
  EXPECT_NEAR(calibration["sphere"]["radius_px"].get<double>(), 170.0, 0.1);
  // A frame of a run needs no --dark: the run's dark frame is taken, and said so.
  ASSERT_EQ(ws.Run("envmap --ball runs/lights/frames/0010_led09.png --circle 191.5 191.5 170 --out auto.hdr"), 0)
      << ws.Output();
  EXPECT_NE(ws.Stderr().find("the run's dark frame"), std::string::npos) << ws.Stderr();
  EXPECT_EQ(ReadText(ws.work() / "auto.hdr"), ReadText(ws.work() / "map.hdr"));
  // The map is the LED's light, not the sensor's offset: almost all of its
  // energy lies within 10 degrees of LED 9.
  cv::Mat map = cv::imread((ws.work() / "map.hdr").string(), cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(map.empty());
  cv::cvtColor(map, map, cv::COLOR_BGR2GRAY);
  const json manifest = Report(ws.work() / "runs/lights/manifest.json");
  const auto& d = manifest["lights"][9]["direction"];
  const Eigen::Vector3d led9(d[0].get<double>(), d[1].get<double>(), d[2].get<double>());
  double near = 0.0, total = 0.0;
  for (int r = 0; r < map.rows; ++r)
    for (int c = 0; c < map.cols; ++c) {
      const Eigen::Vector3d w = photorig::solvers::lighting::LatLongDirection(c, r, map.cols, map.rows);
      const double e = map.at<float>(r, c) * std::sqrt(std::max(0.0, 1.0 - w.y() * w.y()));  // x solid angle
      total += e;
      if (w.dot(led9.normalized()) > std::cos(10.0 * M_PI / 180.0)) near += e;
    }
  EXPECT_GT(near, 0.9 * total);

  // photorig relight --run runs/demo --envmap map.hdr --out relit.tiff
  ASSERT_EQ(ws.Run("run " + Config("recipes/ps-sphere.yaml") + " --out runs/demo"), 0) << ws.Output();
  ASSERT_EQ(ws.Run("relight --run runs/demo --envmap map.hdr --out relit.tiff"), 0) << ws.Output();
  cv::Mat relit = photorig::daemon::ReadFloatTiff((ws.work() / "relit.tiff").string());
  if (relit.channels() == 3) cv::cvtColor(relit, relit, cv::COLOR_RGB2GRAY);
  const fs::path demo = ws.work() / "runs/demo";
  const cv::Mat dark = ReadFloat(demo / "frames/0000_dark.png");
  const cv::Mat led9_frame = ReadFloat(demo / "frames/0010_led09.png") - dark;
  cv::Mat all_leds = cv::Mat::zeros(dark.size(), CV_32F);
  for (const auto& entry : fs::directory_iterator(demo / "frames"))
    if (entry.path().filename().string().find("_led") != std::string::npos) all_leds += ReadFloat(entry.path()) - dark;
  const cv::Mat object = ReadGrey(demo / "results/ps/mask.png");
  const double with_led9 = Correlation(relit, led9_frame, object);
  const double with_all = Correlation(relit, all_leds, object);
  EXPECT_GT(with_led9, 0.9) << "with all LEDs: " << with_all;
  EXPECT_GT(with_led9, with_all + 0.3);
  std::printf("relit vs LED 9: %.3f, vs all LEDs: %.3f; map energy within 10 deg of LED 9: %.1f %%\n", with_led9,
              with_all, 100.0 * near / total);
}

// Mean angle in degrees between the directions of report.json and the truth.
double MeanErrorDeg(const json& report, const fs::path& truth_file) {
  std::ifstream in(truth_file);
  double sum = 0.0;
  int n = 0;
  for (const json& light : report["lights"]) {
    Eigen::Vector3d truth, estimate(light["direction"][0], light["direction"][1], light["direction"][2]);
    in >> truth.x() >> truth.y() >> truth.z();
    sum += std::acos(std::clamp(truth.normalized().dot(estimate.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
    ++n;
  }
  return sum / n;
}

TEST(ReadmeCommands, AWrongCircleReportsAnUncertaintyThatCoversItsError) {
  Workspace ws;
  ASSERT_EQ(ws.Run("run " + Config("recipes/light-calibration.yaml") + " --out runs/lights"), 0) << ws.Output();
  const fs::path truth = ws.work() / "runs/lights/ground_truth/light_directions.txt";
  // The sphere is at (191.5, 191.5) with radius 170 px; the second circle is 4 px off.
  ASSERT_EQ(ws.Run("calibrate lights --run runs/lights --circle 191.5 191.5 170 --out right"), 0) << ws.Output();
  ASSERT_EQ(ws.Run("calibrate lights --run runs/lights --circle 195.5 191.5 170 --out wrong"), 0) << ws.Output();
  const json right = Report(ws.work() / "right/report.json"), wrong = Report(ws.work() / "wrong/report.json");
  const double right_error = MeanErrorDeg(right, truth), wrong_error = MeanErrorDeg(wrong, truth);
  const double right_sigma = right["summary"]["mean_uncertainty_deg"], wrong_sigma = wrong["summary"]["mean_uncertainty_deg"];
  EXPECT_LT(right_error, 0.2);
  EXPECT_GT(wrong_error, 1.0);  // the wrong circle does matter
  EXPECT_GE(right_sigma, right_error);
  EXPECT_GE(wrong_sigma, wrong_error);
  EXPECT_GT(wrong_sigma, 5.0 * right_sigma);
  // Per light, two sigmas cover the error of all but a few.
  std::ifstream in(truth);
  int covered = 0;
  for (const json& light : wrong["lights"]) {
    Eigen::Vector3d t, e(light["direction"][0], light["direction"][1], light["direction"][2]);
    in >> t.x() >> t.y() >> t.z();
    const double error = std::acos(std::clamp(t.normalized().dot(e.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
    covered += error <= 2.0 * light["uncertainty_deg"].get<double>();
  }
  EXPECT_GE(covered, 0.9 * wrong["lights"].size());

  // Without --out the outputs go to the run's results; with --images, --out is required.
  ASSERT_EQ(ws.Run("calibrate lights --run runs/lights --circle 191.5 191.5 170"), 0) << ws.Output();
  EXPECT_EQ(Report(ws.work() / "runs/lights/results/lights/report.json")["sphere"]["source"], "circle");
  EXPECT_EQ(ws.Run("calibrate lights --images runs/lights/frames/0001_led00.png runs/lights/frames/0002_led01.png "
                   "runs/lights/frames/0003_led02.png --circle 191.5 191.5 170"), 2) << ws.Output();
  EXPECT_NE(ws.Stderr().find("--out"), std::string::npos) << ws.Stderr();
  EXPECT_EQ(ws.Entries(), (std::set<std::string>{"runs", "right", "wrong"}));

  // A circle that does not fit inside the frame is refused, naming both sizes.
  EXPECT_EQ(ws.Run("envmap --ball runs/lights/frames/0010_led09.png --circle 192 192 200 --out map.hdr"), 2);
  EXPECT_NE(ws.Stderr().find("384x384"), std::string::npos) << ws.Stderr();
  EXPECT_NE(ws.Stderr().find("-8..392"), std::string::npos) << ws.Stderr();
  EXPECT_FALSE(fs::exists(ws.work() / "map.hdr"));
}

TEST(ReadmeCommands, ColourCalibrationAndApplyingIt) {
  Workspace ws;
  // photorig calibrate color --sim-camera nikon-5100 --rig config/rigs/sim-dome.yaml --bayer RGGB --out cal/
  ASSERT_EQ(ws.Run("calibrate color --sim-camera nikon-5100 --rig " + Config("rigs/sim-dome.yaml") +
                   " --bayer RGGB --out cal/"), 0) << ws.Output();
  // photorig calibrate color --image chart.tiff --dark dark.tiff --bayer RGGB --rig RIG.yaml --out cal/
  ASSERT_EQ(ws.Run("calibrate color --image cal/chart.png --dark cal/dark.png --bayer RGGB --rig " +
                   Config("rigs/sim-dome.yaml") + " --out cal2/"), 0) << ws.Output();
  // photorig apply-color --model cal/model.yaml --in raw.png --bayer RGGB --dark dark.png --out corrected/
  // (the chart the simulated camera shot is the raw image)
  ASSERT_EQ(ws.Run("apply-color --model cal/model.yaml --in cal/chart.png --bayer RGGB --dark cal/dark.png "
                   "--out corrected/"), 0) << ws.Output();
  EXPECT_EQ(ws.Entries(), (std::set<std::string>{"cal", "cal2", "corrected"}));
}

// photorig solve ps --run runs/shiny --mask object.png, on a small simulated dome.
TEST(ReadmeCommands, SolveWithAMaskSolvesOnlyThere) {
  Workspace ws;
  const fs::path rig = ws.work() / "rig.yaml", recipe = ws.work() / "recipe.yaml";
  std::ofstream(rig) << photorig::testing::SmallRigYaml("", 8);
  std::ofstream(recipe) << photorig::testing::SmallRecipeYaml(rig.string(), 2);
  ASSERT_EQ(ws.Run("run recipe.yaml --no-solve --out run"), 0) << ws.Output();

  // A mask of the wrong size names the file and both sizes.
  ASSERT_TRUE(cv::imwrite((ws.work() / "small.png").string(), cv::Mat(16, 20, CV_8U, cv::Scalar(255))));
  EXPECT_EQ(ws.Run("solve ps --run run --mask small.png --out wrong"), 2) << ws.Output();
  EXPECT_NE(ws.Stderr().find("small.png"), std::string::npos) << ws.Stderr();
  EXPECT_NE(ws.Stderr().find("20x16"), std::string::npos) << ws.Stderr();
  EXPECT_NE(ws.Stderr().find("32x32"), std::string::npos) << ws.Stderr();

  // The left half only.
  cv::Mat half = cv::Mat::zeros(32, 32, CV_8U);
  half.colRange(0, 16).setTo(255);
  ASSERT_TRUE(cv::imwrite((ws.work() / "half.png").string(), half));
  ASSERT_EQ(ws.Run("solve ps --run run --mask half.png --out masked"), 0) << ws.Output();
  const cv::Mat solved = ReadGrey(ws.work() / "masked/mask.png");
  EXPECT_GT(cv::countNonZero(solved), 0);
  EXPECT_EQ(cv::countNonZero(solved.colRange(16, 32)), 0);
  const json report = Report(ws.work() / "masked/report.json");
  EXPECT_EQ(report["mask"]["source"], "half.png");
  EXPECT_EQ(report["mask"]["pixels"], 32 * 16);
  ExpectPreviewsMatchTheData(ws.work() / "masked");
}

}  // namespace
