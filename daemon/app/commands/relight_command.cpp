// photorig relight --run RUN (--envmap MAP.hdr | --light X,Y,Z[,INTENSITY]... [--model lambertian|svbrdf]
//                  | --held-out LIGHT [--model lambertian|per_pixel_lobe|svbrdf]) --out IMAGE.tiff
// photorig envmap --ball IMAGE --circle CX CY R [--dark FILE | --black-level DN] [--width W] --out MAP.hdr

#include "../command.h"
#include "../command_output.h"
#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/pipelines/ps_pipeline.h"
#include "photorig/daemon/capture/frame_health.h"
#include "photorig/config/rig.h"
#include "photorig/config/sim.h"
#include "photorig/config/yaml_node.h"
#include "photorig/daemon/capture/run_store.h"
#include "photorig/daemon/pipelines/svbrdf_pipeline.h"
#include "photorig/solvers/codecs/image_codecs.h"
#include "photorig/solvers/lighting/envmap.h"
#include "photorig/solvers/lighting/relight.h"
#include "photorig/solvers/lighting/sphere.h"

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace photorig::app {
namespace {

namespace fs = std::filesystem;

// --model's names: the per-material fit is the svbrdf solve's result.
constexpr solvers::core::NameTable<solvers::reflectance::Method, 3> kModelNames = {
    {{solvers::reflectance::Method::kLambertian, "lambertian"},
     {solvers::reflectance::Method::kPerMaterial, "svbrdf"},
     {solvers::reflectance::Method::kPerPixelLobe, "per_pixel_lobe"}}};

struct RelightOptions {
  std::string run_dir, envmap, out;
  std::vector<std::vector<double>> lights;  // x, y, z[, intensity]
  // With --light: lambertian (results/ps) | svbrdf (results/svbrdf).
  solvers::reflectance::Method model = solvers::reflectance::Method::kLambertian;
  int held_out = -1;                          // a light index: predict it from the others, beside the measured frame
};

// The 99.5th percentile of a float image's grey values: the white of its 8-bit view.
double ViewWhite(const cv::Mat& image) {
  cv::Mat grey = image.channels() == 1 ? image : cv::Mat();
  if (grey.empty()) cv::cvtColor(image, grey, cv::COLOR_RGB2GRAY);
  std::vector<float> values(grey.begin<float>(), grey.end<float>());
  std::nth_element(values.begin(), values.begin() + values.size() * 995 / 1000, values.end());
  return std::max(1e-12, double(values[values.size() * 995 / 1000]));
}

// An 8-bit view of a float image with `white` at 255.
void WriteView(const std::string& png, const cv::Mat& image, double white) {
  cv::Mat view;
  image.convertTo(view, CV_8U, 255.0 / white);
  if (view.channels() == 3) cv::cvtColor(view, view, cv::COLOR_RGB2BGR);  // images are R, G, B; files want B, G, R
  daemon::WriteImage(png, view);
}

// Writes the float result and an 8-bit view scaled to its 99.5th percentile.
void WriteRelit(const std::string& path, const cv::Mat& image) {
  daemon::WriteFloatTiff(path, image);
  WriteView(fs::path(path).replace_extension(".png").string(), image, ViewWhite(image));
}

// --held-out: the light's frame predicted by the fit on the other lights
// (daemon::PredictHeldOutLight), written beside the measured frame, and a
// preview of measured | predicted | 4 x |difference| on one scale.
int RelightHeldOut(const RelightOptions& options) {
  namespace refl = solvers::reflectance;
  const fs::path svbrdf = fs::path(options.run_dir) / "results" / "svbrdf";
  if (!fs::exists(svbrdf / "report.json"))
    return Fail(kExitUsage, (svbrdf / "report.json").string() + " not found: run `photorig solve svbrdf --run " +
                                options.run_dir + "` first");
  const refl::Method method = options.model;
  std::fprintf(stderr, "relight: fitting every method without light %d ...\n", options.held_out);
  const daemon::HeldOutLightImages held = daemon::PredictHeldOutLight(options.run_dir, svbrdf.string(), options.held_out);
  if (!held.summary.IsSolutionUsable())
    return Fail(kExitFailed, svbrdf.string() + ": " + held.summary.message);
  nlohmann::json methods = nlohmann::json::object();
  const refl::HeldOutError* chosen = nullptr;
  for (const refl::HeldOutError& e : held.summary.errors) {
    methods[refl::MethodName(e.method)] = {{"rmse", e.rmse}, {"psnr_db", e.psnr_db}, {"fit_ms", e.fit_ms}};
    if (e.method == method) chosen = &e;
  }
  cv::Mat predicted;
  for (const refl::HeldOutPrediction& p : held.summary.predictions)
    if (p.method == method) predicted = p.image;
  if (!chosen || predicted.empty()) return Fail(kExitFailed, std::string("no prediction for ") + solvers::core::NameOf(kModelNames, method));
  const fs::path out(options.out);
  const std::string measured_path = (out.parent_path() / (out.stem().string() + "-measured.tiff")).string();
  daemon::WriteFloatTiff(options.out, predicted);
  daemon::WriteFloatTiff(measured_path, held.measured);
  // One scale for all three panels: the measured frame's 99.5th percentile.
  // Pixels the check did not evaluate (no prediction) or that the sensor
  // clipped (no measurement) show 0 difference.
  cv::Mat measured = held.measured.clone(), guess = predicted.clone();
  const cv::Mat unknown = (measured != measured) | (guess != guess);
  cv::patchNaNs(measured, 0.0);
  cv::patchNaNs(guess, 0.0);
  cv::Mat difference = cv::abs(measured - guess) * 4.0, panels;
  difference.setTo(cv::Scalar::all(0.0), unknown);
  cv::hconcat(std::vector<cv::Mat>{measured, guess, difference}, panels);
  const std::string preview = fs::path(options.out).replace_extension(".png").string();
  WriteView(preview, panels, ViewWhite(measured));
  std::printf("light %d held out: %s RMSE %.4g (PSNR %.1f dB); wrote %s, %s and %s (measured | predicted | 4 x difference)\n",
              options.held_out, refl::MethodName(method), chosen->rmse, chosen->psnr_db, options.out.c_str(),
              measured_path.c_str(), preview.c_str());
  for (const auto& [name, e] : methods.items())
    std::printf("  %-15s RMSE %.4g  PSNR %.1f dB\n", name.c_str(), e["rmse"].get<double>(), e["psnr_db"].get<double>());
  ResultFields()["out"] = options.out;
  ResultFields()["measured"] = measured_path;
  ResultFields()["preview"] = preview;
  ResultFields()["light"] = options.held_out;
  ResultFields()["method"] = refl::MethodName(method);
  ResultFields()["rmse"] = chosen->rmse;
  ResultFields()["psnr_db"] = chosen->psnr_db;
  ResultFields()["methods"] = methods;
  ResultFields()["width"] = predicted.cols;
  ResultFields()["height"] = predicted.rows;
  return kExitOk;
}

// Each pixel's surface point for a near dome's relighting, in the dome's
// frame: on the surface a near-light photometric-stereo solve placed in
// millimetres (results/ps depth.tiff, report.json depth.from_near_lights)
// where it has one, else on the sample plane (z = 0).
cv::Mat SurfacePoints(const std::string& run_dir, const daemon::PhotometricStereoInput& input, std::string* source) {
  const solvers::camera::Camera camera =
      input.camera ? *input.camera
                   : solvers::camera::Camera::Orthographic(input.stack.width(), input.stack.height(), input.pixel_pitch);
  const solvers::camera::PixelRays rays(camera);
  const fs::path ps = fs::path(run_dir) / "results" / "ps";
  cv::Mat depth;
  *source = "sample plane";
  if (fs::exists(ps / "report.json") && fs::exists(ps / "depth.tiff")) {
    std::ifstream in(ps / "report.json");
    const nlohmann::json report = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
    if (report.contains("depth") && report["depth"].value("from_near_lights", false)) {
      depth = daemon::ReadFloatTiff((ps / "depth.tiff").string());
      *source = (ps / "depth.tiff").string();
    }
  }
  cv::Mat points(input.stack.height(), input.stack.width(), CV_32FC3);
  for (int r = 0; r < points.rows; ++r)
    for (int c = 0; c < points.cols; ++c) {
      const float z = depth.empty() ? 0.0f : depth.at<float>(r, c);
      const Eigen::Vector3d p = rays.Point(r, c, std::isfinite(z) ? z : 0.0);
      points.at<cv::Vec3f>(r, c) = cv::Vec3f(float(p.x()), float(p.y()), float(p.z()));
    }
  return points;
}

// Image-based: the captured one-light frames, weighted so the dome
// approximates the map; per pixel on a dome of near LEDs.
solvers::core::Summary RelightFromEnvironment(const RelightOptions& options, cv::Mat* relit) {
  const daemon::PhotometricStereoInput input = daemon::LoadRunStack(options.run_dir);
  const cv::Mat map = daemon::ReadInputImage(options.envmap);
  if (map.depth() != CV_32F) throw std::invalid_argument(options.envmap + ": expected a float (HDR) lat-long map (.hdr or float .tiff)");
  std::vector<cv::Mat> frames;
  for (const cv::Mat& frame : input.stack.images) frames.push_back(input.stack.dark.empty() ? frame : frame - input.stack.dark);
  if (!input.near_lights.empty()) {
    std::string points_from;
    const cv::Mat points = SurfacePoints(options.run_dir, input, &points_from);
    ResultFields()["light_model"] = "near";
    ResultFields()["points"] = points_from;
    return solvers::lighting::RelightNearFromEnvironment({}, map, input.near_lights, input.stack.light_scales, frames,
                                                         points, relit);
  }
  ResultFields()["light_model"] = "distant";
  Eigen::MatrixXd weights;
  const solvers::core::Summary done =
      solvers::lighting::LatLongToLedWeights(map, input.stack.light_directions, input.stack.light_scales, &weights);
  return done.IsSolutionUsable() ? solvers::lighting::RelightFromFrames(frames, weights, relit) : done;
}

int Relight(const RelightOptions& options) {
  // Every form reads a run: a folder that is not one is named as such, not
  // sent to solve first.
  daemon::LoadRunManifest(options.run_dir);
  if (options.held_out >= 0) {
    if (!options.envmap.empty() || !options.lights.empty()) return Fail(kExitUsage, "--held-out takes neither --envmap nor --light");
    return RelightHeldOut(options);
  }
  if (options.model == solvers::reflectance::Method::kPerPixelLobe) return Fail(kExitUsage, "--model per_pixel_lobe is only for --held-out");
  if (options.envmap.empty() == options.lights.empty()) return Fail(kExitUsage, "give either --envmap, --light or --held-out");
  cv::Mat relit;
  if (!options.envmap.empty()) {
    const solvers::core::Summary done = RelightFromEnvironment(options, &relit);
    if (!done.IsSolutionUsable())
      return Fail(kExitFailed, options.run_dir + " with " + options.envmap + ": " + done.message);
  } else if (options.model == solvers::reflectance::Method::kPerMaterial) {
    // Model-based with the fitted reflectance: per-pixel albedo and the materials' lobes.
    const fs::path svbrdf = fs::path(options.run_dir) / "results" / "svbrdf";
    if (!fs::exists(svbrdf / "report.json"))
      return Fail(kExitUsage, (svbrdf / "report.json").string() + " not found: run `photorig solve svbrdf --run " +
                                  options.run_dir + "` first");
    const solvers::reflectance::ReflectanceMaps maps = daemon::ReadSvbrdfResult(svbrdf.string());
    // Seen as the run was: through a pinhole each pixel has its own line of sight.
    const daemon::RunManifest manifest = daemon::LoadRunManifest(options.run_dir);
    const cv::Mat views =
        manifest.projection == solvers::camera::Projection::kPinhole
            ? solvers::camera::PixelRays({manifest.projection, manifest.width, manifest.height, manifest.pixel_pitch_mm,
                                          manifest.pinhole})
                  .ViewDirections()
            : cv::Mat();
    for (const auto& light : options.lights) {
      if (light.size() != 3 && light.size() != 4) throw std::invalid_argument("--light takes X,Y,Z or X,Y,Z,INTENSITY");
      const Eigen::Vector3d d(light[0], light[1], light[2]);
      if (!(d.norm() > 0)) throw std::invalid_argument("--light: zero direction");
      cv::Mat one;
      const Eigen::Vector3d intensity = Eigen::Vector3d::Constant(light.size() == 4 ? light[3] : 1.0);
      const solvers::core::Summary rendered =
          views.empty() ? solvers::reflectance::RenderReflectance(maps, d.normalized(), intensity, Eigen::Vector3d::UnitZ(), &one)
                        : solvers::reflectance::RenderReflectance(maps, d.normalized(), intensity, views, &one);
      if (!rendered.IsSolutionUsable()) return Fail(kExitFailed, svbrdf.string() + ": " + rendered.message);
      if (relit.empty()) relit = one; else relit += one;
    }
  } else {
    // Model-based: the normals and albedo photometric stereo recovered.
    const fs::path ps = fs::path(options.run_dir) / "results" / "ps";
    for (const char* file : {"normals.tiff", "albedo.tiff"})
      if (!fs::exists(ps / file))
        return Fail(kExitUsage, (ps / file).string() + " not found: relighting with --light renders the normals and "
                                "albedo of a photometric-stereo result; run `photorig solve ps --run " +
                                    options.run_dir + "` first");
    const cv::Mat normals = daemon::ReadFloatTiff((ps / "normals.tiff").string());
    const cv::Mat albedo = daemon::ReadFloatTiff((ps / "albedo.tiff").string());
    std::vector<Eigen::Vector3d> directions;
    std::vector<double> intensities;
    for (const auto& light : options.lights) {
      if (light.size() != 3 && light.size() != 4)
        throw std::invalid_argument("--light takes X,Y,Z or X,Y,Z,INTENSITY");
      const Eigen::Vector3d d(light[0], light[1], light[2]);
      if (!(d.norm() > 0)) throw std::invalid_argument("--light: zero direction");
      directions.push_back(d.normalized());
      intensities.push_back(light.size() == 4 ? light[3] : 1.0);
    }
    cv::Mat clean_normals = normals.clone(), clean_albedo = albedo.clone();
    cv::patchNaNs(clean_normals, 0.0);  // unsolved pixels render black
    cv::patchNaNs(clean_albedo, 0.0);
    const solvers::core::Summary rendered =
        solvers::lighting::RenderDirectionalLights(clean_normals, clean_albedo, directions, intensities, &relit);
    if (!rendered.IsSolutionUsable()) return Fail(kExitFailed, ps.string() + ": " + rendered.message);
  }
  WriteRelit(options.out, relit);
  std::printf("wrote %s\n", options.out.c_str());
  ResultFields()["out"] = options.out;
  ResultFields()["preview"] = fs::path(options.out).replace_extension(".png").string();
  ResultFields()["width"] = relit.cols;
  ResultFields()["height"] = relit.rows;
  return kExitOk;
}

CLI::App* SetupRelight(CLI::App& app, RelightOptions* options) {
  CLI::App* sub = app.add_subcommand("relight", "render a captured object under new lighting");
  sub->add_option("--run", options->run_dir, "run directory (with results/ps for --light)")->required()->check(CLI::ExistingDirectory);
  sub->add_option("--envmap", options->envmap, "lat-long HDR map: image-based relighting from the one-light frames")
      ->check(CLI::ExistingFile);
  sub->add_option("--light", options->lights, "X,Y,Z[,INTENSITY] directional light (repeatable): from normals and albedo")
      ->delimiter(',')
      ->allow_extra_args(false);
  sub->add_option("--held-out", options->held_out,
                  "light index: predict that light's frame from a fit to the other lights (results/svbrdf), "
                  "written beside the measured frame, with each method's error")
      ->check(CLI::NonNegativeNumber);
  AddChoice(sub, "--model", &options->model, kModelNames,
            "lambertian (with --light: results/ps normals and albedo), svbrdf (results/svbrdf: "
            "albedo and the materials' lobes), per_pixel_lobe (--held-out only)");
  sub->add_option("--out", options->out, "output float TIFF (an 8-bit PNG view is written beside it)")->required();
  return sub;
}

struct EnvmapOptions {
  std::string ball, dark, out;
  std::vector<double> circle;
  double black_level_dn = -1.0;  // < 0: not given
  double noise_floor_sigmas = 5.0;
  int width = 512;
};

// The sensor's offset under the ball: --dark, --black-level, or, for a frame
// inside a run directory (RUN/frames/NAME), the mean of the run's dark frames.
// Empty when none is known. `said` is what was subtracted, for stderr.
cv::Mat BallOffset(const EnvmapOptions& options, cv::Size size, std::string* said) {
  if (!options.dark.empty()) {
    cv::Mat dark;
    daemon::ReadInputImage(options.dark).convertTo(dark, CV_32F);
    if (dark.channels() > 1) cv::cvtColor(dark, dark, cv::COLOR_BGR2GRAY);
    if (dark.size() != size)
      throw config::ConfigError(options.dark, 0, 0, "", "the dark frame is " + std::to_string(dark.cols) + "x" +
                                                            std::to_string(dark.rows) + ", the ball image is " +
                                                            std::to_string(size.width) + "x" + std::to_string(size.height));
    *said = "the dark frame " + options.dark;
    return dark;
  }
  if (options.black_level_dn >= 0.0) {
    *said = "a black level of " + std::to_string(options.black_level_dn) + " DN";
    return cv::Mat(size, CV_32F, cv::Scalar(options.black_level_dn));
  }
  const fs::path frames = fs::absolute(options.ball).parent_path();
  const fs::path run = frames.parent_path();
  if (frames.filename() != "frames" || !fs::exists(run / "manifest.json")) return {};
  cv::Mat sum;
  int count = 0;
  for (const daemon::FrameRecord& record : daemon::LoadRunManifest(run.string()).frames) {
    if (record.kind != config::CaptureStep::Kind::kDark) continue;
    cv::Mat dark;
    daemon::LoadFrame(run.string(), record).convertTo(dark, CV_32F);
    if (dark.size() != size) continue;
    if (sum.empty()) sum = cv::Mat::zeros(size, CV_32F);
    sum += dark;
    *said = (count == 0 ? "the run's dark frame " : *said + ", ") + (run / record.file).string();
    ++count;
  }
  if (count == 0) return {};
  return sum / count;
}

int Envmap(const EnvmapOptions& options) {
  // The map is float radiance: refuse an 8- or 16-bit format before the unwrap, not after it.
  const auto encoding = solvers::codecs::EncodingOfPath(options.out);
  if (!encoding || *encoding == solvers::codecs::ImageEncoding::kPng)
    return Fail(kExitUsage, "--out " + options.out + ": the map is float radiance; name a .hdr, .exr or .tiff file");
  cv::Mat ball;
  daemon::ReadInputImage(options.ball).convertTo(ball, CV_32F);
  const double cx = options.circle[0], cy = options.circle[1], r = options.circle[2];
  // Pixel centres are at integer coordinates: the image covers -0.5 .. cols - 0.5.
  if (!(r > 0) || cx - r < -0.5 || cy - r < -0.5 || cx + r > ball.cols - 0.5 || cy + r > ball.rows - 0.5) {
    char why[512];
    std::snprintf(why, sizeof(why),
                  "the circle (%g, %g) radius %g spans x %g..%g, y %g..%g, which does not fit inside the "
                  "%dx%d image %s: give the ball's circle in that image's pixels",
                  cx, cy, r, cx - r, cx + r, cy - r, cy + r, ball.cols, ball.rows, options.ball.c_str());
    return Fail(kExitUsage, why);
  }
  std::string said;
  const cv::Mat offset = BallOffset(options, ball.size(), &said);
  if (offset.empty()) {
    std::fprintf(stderr, "envmap: no dark frame or black level for %s: the map includes the sensor's offset "
                         "(give --dark FILE or --black-level DN)\n", options.ball.c_str());
  } else {
    cv::Mat channels = offset;
    if (ball.channels() == 3) cv::merge(std::vector<cv::Mat>{offset, offset, offset}, channels);
    ball -= channels;
    // A point LED's highlight covers a few pixels of the ball, its noise all
    // of them: left in, the noise's positive half outweighs the light. So
    // what does not rise above the noise (robust sigma of the whole
    // difference, mostly noise) counts as no light.
    const double floor_dn = options.noise_floor_sigmas * daemon::RobustSigma(ball);
    cv::threshold(ball, ball, floor_dn, 0.0, cv::THRESH_TOZERO);
    std::fprintf(stderr, "envmap: subtracting %s; values under %g noise sigmas (%.1f DN) count as no light\n",
                 said.c_str(), options.noise_floor_sigmas, floor_dn);
  }
  solvers::lighting::CameraModel camera;
  const solvers::lighting::SphereGeometry sphere = solvers::lighting::LocateSphere(camera, {cx, cy, r});
  if (!sphere.valid) return Fail(kExitUsage, sphere.message);
  solvers::lighting::UnwrapOptions unwrap;
  unwrap.width = options.width;
  solvers::lighting::LatLongMap map;
  const solvers::core::Summary unwrapped = solvers::lighting::MirrorBallToLatLong(ball, sphere, unwrap, &map);
  if (!unwrapped.IsSolutionUsable()) return Fail(kExitFailed, options.ball + ": " + unwrapped.message);
  daemon::WriteImage(options.out, map.radiance);
  const double seen = double(cv::countNonZero(map.valid)) / double(map.valid.total());
  std::printf("wrote %s (%d x %d, %d%% of directions seen)\n", options.out.c_str(), map.radiance.cols,
              map.radiance.rows, int(100.0 * seen));
  ResultFields() = {{"out", options.out},
                    {"width", map.radiance.cols},
                    {"height", map.radiance.rows},
                    {"directions_seen_fraction", seen},
                    {"offset_subtracted", !offset.empty()}};
  return kExitOk;
}

CLI::App* SetupEnvmap(CLI::App& app, EnvmapOptions* options) {
  CLI::App* sub = app.add_subcommand("envmap", "unwrap a mirror-ball image into a lat-long environment map");
  sub->add_option("--ball", options->ball, "mirror-ball image (orthographic)")->required()->check(CLI::ExistingFile);
  sub->add_option("--circle", options->circle, "ball circle CX CY R in pixels")->expected(3)->required();
  auto* dark = sub->add_option("--dark", options->dark,
                               "dark frame to subtract (default: the run's darks when the ball is a run's frame)")
                   ->check(CLI::ExistingFile);
  sub->add_option("--black-level", options->black_level_dn, "sensor offset in DN to subtract, instead of a dark frame")
      ->check(CLI::NonNegativeNumber)
      ->excludes(dark);
  sub->add_option("--noise-floor", options->noise_floor_sigmas,
                  "after the dark or black level: values under this many noise sigmas count as no light (default 5)")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--width", options->width, "map width (height is half)")->check(CLI::Range(16, 16384));
  sub->add_option("--out", options->out, "output .hdr")->required();
  return sub;
}

const bool registered_relight = RegisterCommand<RelightOptions, SetupRelight, Relight>();
const bool registered_envmap = RegisterCommand<EnvmapOptions, SetupEnvmap, Envmap>();

}  // namespace
}  // namespace photorig::app
