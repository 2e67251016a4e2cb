// photorig calibrate lights (--run DIR | --images F...) (--silhouette IMG | --circle CX,CY,R)
//   [--camera orthographic|pinhole --fx --fy --cx --cy] [--white-images F...]
//   [--rig IN.yaml --out-rig NEW.yaml] [--out DIR]
// Light directions from a mirror sphere (one image per LED), optional relative
// intensities from a white sphere, written as .lp, DiLiGenT text files, a JSON
// report and a new rig YAML (an existing file is never overwritten).

#include "../command.h"
#include "photorig/daemon/run_store.h"
#include "photorig/lighting/light_files.h"
#include "photorig/lighting/light_intensity.h"
#include "photorig/lighting/mirror_sphere.h"

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>

namespace photorig::app {
namespace {

namespace fs = std::filesystem;
using namespace photorig::lighting;

struct Options {
  std::string run_dir, silhouette, rig, out_rig, out = "light-calibration", camera = "orthographic";
  std::vector<std::string> images, white_images;
  std::vector<double> circle;
  double fx = 0, fy = 0, cx = 0, cy = 0;
};

cv::Mat ReadSingleChannel(const std::string& path) {
  cv::Mat image = cv::imread(path, cv::IMREAD_ANYDEPTH | cv::IMREAD_GRAYSCALE);
  if (image.empty()) throw std::runtime_error(path + ": cannot read image");
  return image;
}

int Execute(const Options& o) {
  std::vector<cv::Mat> frames;
  std::vector<std::string> names;
  if (!o.run_dir.empty()) {
    const daemon::RunManifest manifest = daemon::LoadRunManifest(o.run_dir);
    frames.resize(manifest.lights.size());
    names.resize(manifest.lights.size());
    for (const auto& record : manifest.frames) {
      if (record.kind != "light" || record.led < 0 || record.led >= static_cast<int>(frames.size())) continue;
      frames[static_cast<std::size_t>(record.led)] = daemon::LoadFrame(o.run_dir, record);
      names[static_cast<std::size_t>(record.led)] = fs::path(record.file).filename().string();
    }
  } else {
    for (const auto& path : o.images) {
      frames.push_back(ReadSingleChannel(path));
      names.push_back(fs::path(path).filename().string());
    }
  }
  if (frames.empty()) {
    std::cerr << "error: no light frames\n";
    return 2;
  }

  CameraModel camera;
  if (o.camera == "pinhole") {
    camera.projection = CameraModel::Projection::kPinhole;
    camera.fx_px = o.fx;
    camera.fy_px = o.fy > 0 ? o.fy : o.fx;
    camera.cx_px = o.cx;
    camera.cy_px = o.cy;
  }
  Circle circle;
  std::vector<Eigen::Vector2d> edges;
  if (o.circle.size() == 3) {
    circle = {o.circle[0], o.circle[1], o.circle[2]};
  } else if (!o.silhouette.empty()) {
    const SphereFitSummary fit = FitSphereSilhouette(ReadSingleChannel(o.silhouette));
    if (!fit.success) {
      std::cerr << "error: " << o.silhouette << ": " << fit.message << "\n";
      return 3;
    }
    circle = fit.circle;
    edges = fit.edge_points;
  } else {
    std::cerr << "error: give --silhouette IMG or --circle CX,CY,R\n";
    return 2;
  }
  const SphereGeometry sphere = LocateSphere(camera, circle, edges);
  if (!sphere.valid) {
    std::cerr << "error: sphere: " << sphere.message << "\n";
    return 2;
  }

  nlohmann::json report{{"sphere", {{"cx_px", circle.cx_px}, {"cy_px", circle.cy_px}, {"radius_px", circle.radius_px}}}};
  std::vector<LightDirectionEstimate> directions;
  int unusable = 0;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    directions.push_back(frames[k].empty() ? LightDirectionEstimate{} : EstimateLightDirection(frames[k], sphere));
    const auto& e = directions.back();
    if (frames[k].empty()) directions.back().note = "no frame";
    unusable += e.usable ? 0 : 1;
    report["lights"].push_back({{"index", k}, {"image", names[k]}, {"usable", e.usable}, {"flags", e.note},
                                {"direction", {e.direction.x(), e.direction.y(), e.direction.z()}},
                                {"uncertainty_deg", e.uncertainty_deg}});
  }
  std::vector<LightIntensityEstimate> intensities(frames.size());
  if (!o.white_images.empty()) {
    if (o.white_images.size() != frames.size()) {
      std::cerr << "error: --white-images needs one image per light (" << frames.size() << ")\n";
      return 2;
    }
    for (std::size_t k = 0; k < frames.size(); ++k) {
      intensities[k] = EstimateIntensityFromSphere(cv::imread(o.white_images[k], cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR),
                                                   sphere, directions[k].direction);
    }
    NormaliseIntensities(&intensities);
    for (std::size_t k = 0; k < frames.size(); ++k) {
      report["lights"][k]["rgb_intensity"] = {intensities[k].rgb.x(), intensities[k].rgb.y(), intensities[k].rgb.z()};
    }
  }

  fs::create_directories(o.out);
  std::vector<LightPosition> lp;
  std::vector<Eigen::Vector3d> diligent_directions, diligent_intensities;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    lp.push_back({names[k], directions[k].direction});
    diligent_directions.push_back(directions[k].direction);
    diligent_intensities.push_back(intensities[k].usable ? intensities[k].rgb : Eigen::Vector3d::Ones());
  }
  WriteLpFile((fs::path(o.out) / "lights.lp").string(), lp);
  WriteTriplesFile((fs::path(o.out) / "light_directions.txt").string(), diligent_directions);
  WriteTriplesFile((fs::path(o.out) / "light_intensities.txt").string(), diligent_intensities);
  std::ofstream((fs::path(o.out) / "report.json").string()) << report.dump(2) << "\n";

  if (!o.rig.empty()) {
    if (o.out_rig.empty() || fs::exists(o.out_rig)) {
      std::cerr << "error: --out-rig must name a new file (never overwritten): " << o.out_rig << "\n";
      return 2;
    }
    YAML::Node rig = YAML::LoadFile(o.rig);
    YAML::Node leds = rig["lights"]["leds"];
    if (!leds.IsSequence() || leds.size() != frames.size()) {
      std::cerr << "error: " << o.rig << ": lights.leds has " << (leds.IsSequence() ? leds.size() : 0)
                << " entries, calibration has " << frames.size() << "\n";
      return 2;
    }
    for (std::size_t k = 0; k < frames.size(); ++k) {
      if (!directions[k].usable) continue;  // keep the previous value for lights that failed
      const Eigen::Vector3d& d = directions[k].direction;
      leds[k]["direction"] = std::vector<double>{d.x(), d.y(), d.z()};
      if (intensities[k].usable) {
        leds[k]["intensity"] = intensities[k].rgb.mean();
        leds[k]["rgb_intensity"] = std::vector<double>{intensities[k].rgb.x(), intensities[k].rgb.y(), intensities[k].rgb.z()};
      }
    }
    std::ofstream out(o.out_rig);
    out << "# Light calibration of " << o.rig << " (photorig calibrate lights)\n" << rig << "\n";
  }
  std::cout << "lights: " << frames.size() << ", unusable: " << unusable << ", outputs in " << o.out << "\n";
  return unusable == 0 ? 0 : 3;
}

CommandRunner Setup(CLI::App& app) {
  auto o = std::make_shared<Options>();
  CLI::App* calibrate = SubcommandGroup(app, "calibrate", "calibrate the rig");
  CLI::App* lights = calibrate->add_subcommand("lights", "light directions (mirror sphere) and intensities (white sphere)");
  auto* run = lights->add_option("--run", o->run_dir, "run directory with one frame per LED")->check(CLI::ExistingDirectory);
  lights->add_option("--images", o->images, "mirror-sphere images, one per light")->check(CLI::ExistingFile)->excludes(run);
  lights->add_option("--silhouette", o->silhouette, "image showing the sphere's silhouette")->check(CLI::ExistingFile);
  lights->add_option("--circle", o->circle, "sphere circle CX CY R in pixels")->expected(3)->delimiter(',');
  lights->add_option("--camera", o->camera, "orthographic | pinhole")->check(CLI::IsMember({"orthographic", "pinhole"}));
  lights->add_option("--fx", o->fx, "pinhole focal length (px)");
  lights->add_option("--fy", o->fy, "pinhole focal length y (px; default fx)");
  lights->add_option("--cx", o->cx, "pinhole principal point x (px)");
  lights->add_option("--cy", o->cy, "pinhole principal point y (px)");
  lights->add_option("--white-images", o->white_images, "white-sphere images, one per light")->check(CLI::ExistingFile);
  lights->add_option("--rig", o->rig, "rig YAML to update")->check(CLI::ExistingFile);
  lights->add_option("--out-rig", o->out_rig, "new rig YAML to write");
  lights->add_option("--out", o->out, "output directory");
  return {lights, [o] {
            try {
              return Execute(*o);
            } catch (const std::exception& e) {
              std::cerr << "error: " << e.what() << "\n";
              return 1;
            }
          }};
}

const bool registered = RegisterCommand(Setup);

}  // namespace
}  // namespace photorig::app
