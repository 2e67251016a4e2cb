
#include "photorig/daemon/pipelines/ps_pipeline.h"
#include "photorig/daemon/capture/frame_health.h"

#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/io/lens_json.h"
#include "photorig/daemon/io/internal/mesh_io.h"
#include "photorig/daemon/io/internal/previews.h"
#include "photorig/daemon/pipelines/internal/results_folder.h"
#include "photorig/config/rig.h"
#include "photorig/config/sim.h"
#include "photorig/config/yaml_node.h"
#include "photorig/daemon/capture/run_store.h"
#include "photorig/solvers/ps/evaluation.h"
#include "photorig/solvers/ps/integration.h"
#include "photorig/solvers/ps/photometric_stereo.h"
#include "photorig/solvers/ps/channel_albedo.h"
#include "photorig/solvers/color/colorimetry.h"
#include "photorig/solvers/core/summary_json.h"

#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace photorig::daemon {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

double Ms(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - since).count();
}

// Dark noise in DN: temporal when there are several darks (the honest
// measure), else a robust spatial estimate (median absolute deviation).
double DarkNoiseSigma(const std::vector<cv::Mat>& darks, const cv::Mat& mean_dark) {
  if (darks.size() >= 2) {
    cv::Mat variance = cv::Mat::zeros(mean_dark.size(), CV_32F);
    for (const cv::Mat& dark : darks) {
      cv::Mat diff = dark - mean_dark;
      variance += diff.mul(diff);
    }
    variance /= static_cast<double>(darks.size() - 1);
    cv::Mat sigma;
    cv::sqrt(variance, sigma);
    return cv::mean(sigma)[0];
  }
  return RobustSigma(mean_dark);
}

json MetricsJson(const solvers::ps::AngularErrorStats& stats) {
  return {{"pixels_with_truth", stats.pixels_with_truth},
          {"pixels_evaluated", stats.pixels_evaluated},
          {"pixels_unresolved", stats.pixels_unresolved},
          {"mean_angular_error_deg", stats.mean_deg},
          {"median_angular_error_deg", stats.median_deg},
          {"max_angular_error_deg", stats.max_deg},
          {"percent_under_5deg", 100.0 * stats.fraction_under_5deg},
          {"percent_under_10deg", 100.0 * stats.fraction_under_10deg},
          {"percent_under_15deg", 100.0 * stats.fraction_under_15deg}};
}

// B, G, R 8-bit: each channel of the linear albedo over `top`, clipped to
// [0, 1] and sRGB-encoded; unsolved pixels black.
cv::Mat ColorAlbedoPreview(const cv::Mat& albedo_rgb, const cv::Mat& solved, double top) {
  cv::Mat out(albedo_rgb.size(), CV_8UC3, cv::Scalar::all(0));
  for (int r = 0; r < albedo_rgb.rows; ++r) {
    const auto* a = albedo_rgb.ptr<cv::Vec3f>(r);
    const auto* m = solved.ptr<std::uint8_t>(r);
    auto* o = out.ptr<cv::Vec3b>(r);
    for (int c = 0; c < albedo_rgb.cols; ++c) {
      if (!m[c]) continue;
      for (int k = 0; k < 3; ++k) {
        const double v = std::isfinite(a[c][k]) ? std::clamp(a[c][k] / top, 0.0, 1.0) : 0.0;
        o[c][2 - k] = cv::saturate_cast<std::uint8_t>(255.0 * solvers::color::SrgbEncode(v));
      }
    }
  }
  return out;
}

// A one-channel mask repeated for the three interleaved channels of an image
// reshaped to one channel (rows x cols*3 values as one column).
cv::Mat RepeatMask3(const cv::Mat& mask) {
  cv::Mat three;
  cv::merge(std::vector<cv::Mat>{mask, mask, mask}, three);
  return three.reshape(1, mask.rows * mask.cols * 3);
}

// Per-channel albedo with the normals fixed (solvers::ps::SolveRgbAlbedo): R, G, B
// as CV_32FC3, NaN where a channel has too few usable samples.
cv::Mat SolveColorAlbedo(const ColorImageStack& color, const cv::Mat& normals, double shadow_sigmas,
                         PhotometricStereoResult* result) {
  std::array<solvers::ps::ChannelAlbedoOptions, 3> options;
  for (int c = 0; c < 3; ++c) {
    // Clipped samples are +infinity in a colour stack; shadows sit at zero
    // after the dark, within the channel's noise.
    options[c].shadow_threshold = std::max(1.0, shadow_sigmas * color.read_sigma[c]);
    options[c].saturation_level = std::numeric_limits<double>::infinity();
  }
  cv::Mat albedo;
  const std::array<solvers::ps::SolverSummary, 3> summaries =
      solvers::ps::SolveRgbAlbedo(options, color.images, color.light_directions, color.light_scales, normals, &albedo);
  result->color_albedo_summary = summaries[1];
  for (int c = 0; c < 3; ++c)
    if (!summaries[c].IsSolutionUsable())
      spdlog::warn("{}: channel {} albedo: {}", result->source, "RGB"[c], summaries[c].message);
  if (albedo.empty()) albedo = cv::Mat(normals.size(), CV_32FC3, cv::Scalar::all(std::numeric_limits<float>::quiet_NaN()));
  result->color = color.provenance;
  return albedo;
}

PhotometricStereoResult::ColorError Summarise(std::vector<double> errors) {
  PhotometricStereoResult::ColorError out;
  out.pixels = static_cast<int>(errors.size());
  if (errors.empty()) return out;
  double sum = 0.0;
  for (double e : errors) sum += e;
  out.mean = sum / static_cast<double>(errors.size());
  std::sort(errors.begin(), errors.end());
  out.median = errors[errors.size() / 2];
  out.p95 = errors[std::min(errors.size() - 1, errors.size() * 95 / 100)];
  return out;
}

// Photometric stereo needs frames each lit by one LED of a surface; a
// gonioreflectometer or tomography run has poses instead, and a
// light-calibration run the highlights of a mirror sphere: each has its own solver.
void RequirePhotometricStereoRun(const std::string& run_directory, const RunManifest& manifest) {
  const auto stage = [&manifest](const char* name) {
    return std::find(manifest.solve_stages.begin(), manifest.solve_stages.end(), name) != manifest.solve_stages.end();
  };
  const bool lights = stage("light_calibration"), leds = stage("led_positions");
  if ((lights || leds) && !stage("photometric_stereo") && !stage("svbrdf"))
    throw std::invalid_argument(run_directory + " was captured to calibrate the lights (recipe " +
                                manifest.recipe_name +
                                "): its frames show one highlight of each calibration sphere per LED, not a surface "
                                "photometric stereo can solve; `photorig calibrate " + (leds ? "leds" : "lights") +
                                " --run " + run_directory + "` solves it");
  bool tomograph = false;
  for (const FrameRecord& record : manifest.frames) {
    if (record.kind == config::CaptureStep::Kind::kLight && record.led >= 0) return;
    // A tomograph's flat fields move the sample out of the beam; a
    // gonioreflectometer's changer only brings in its reference target.
    tomograph = tomograph || (record.pose && record.pose->sample_changer_deg.value_or(0.0) != 0.0 &&
                              record.group_kind != config::Recipe::Group::Kind::kReferenceTarget);
  }
  const bool posed = std::any_of(manifest.frames.begin(), manifest.frames.end(),
                                 [](const FrameRecord& record) { return record.pose.has_value(); });
  std::string instead = "capture one frame per LED (a dome recipe's each_led step)";
  if (posed)
    instead = std::string("this is a ") + (tomograph ? "tomography" : "gonioreflectometer") + " run: solve it with `photorig solve " +
              (tomograph ? "tomography" : "brdf") + " --run " + run_directory + "`";
  throw std::invalid_argument(run_directory + ": no frame lit by a single LED among its " +
                              std::to_string(manifest.frames.size()) +
                              " frames, and photometric stereo needs one per LED; " + instead);
}

// The near LEDs of a run whose rig gives every LED's position, one per
// image. Empty when an LED has only a direction.
std::vector<solvers::camera::NearLight> NearLightsOf(const std::vector<const config::LedConfig*>& leds) {
  std::vector<solvers::camera::NearLight> lights;
  for (const config::LedConfig* led : leds) {
    if (!led->position_mm) return {};
    lights.push_back({*led->position_mm, led->EmissionAxis(), led->cos_exponent});
  }
  return lights;
}

}  // namespace

PhotometricStereoResult::ColorErrors CompareColorAlbedo(const cv::Mat& albedo_rgb, const cv::Mat& truth_rgb,
                                                        const cv::Mat& solved) {
  // Interior: the truth's 5 x 5 range is zero in every channel (NaN off the object counts as a change).
  cv::Mat truth = truth_rgb.clone();
  cv::patchNaNs(truth, -1.0);
  cv::Mat high, low;
  const cv::Mat box = cv::Mat::ones(5, 5, CV_8U);
  cv::dilate(truth, high, box);
  cv::erode(truth, low, box);
  cv::Mat range;
  cv::transform(high - low, range, cv::Matx13f(1, 1, 1));
  std::vector<double> all, interior;
  for (int r = 0; r < albedo_rgb.rows; ++r)
    for (int c = 0; c < albedo_rgb.cols; ++c) {
      if (!solved.at<std::uint8_t>(r, c)) continue;
      const cv::Vec3f a = albedo_rgb.at<cv::Vec3f>(r, c), t = truth_rgb.at<cv::Vec3f>(r, c);
      if (!std::isfinite(a[0] + a[1] + a[2]) || !std::isfinite(t[0] + t[1] + t[2])) continue;
      const double e = Ciede2000OfLinearSrgb(Eigen::Vector3d(a[0], a[1], a[2]), Eigen::Vector3d(t[0], t[1], t[2]));
      all.push_back(e);
      if (range.at<float>(r, c) == 0.0f) interior.push_back(e);
    }
  return {Summarise(std::move(all)), Summarise(std::move(interior))};
}

double Ciede2000OfLinearSrgb(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Matrix3d& to_xyz = solvers::color::LinearSrgbToXyzD65();
  const Eigen::Vector3d white = to_xyz * Eigen::Vector3d::Ones();
  return solvers::color::Ciede2000(solvers::color::XyzToLab(to_xyz * a, white), solvers::color::XyzToLab(to_xyz * b, white));
}

solvers::ps::PhotometricStereoOptions MakeSolverOptions(const config::PhotometricStereoRequest& request, double saturation_level) {
  solvers::ps::PhotometricStereoOptions options;
  options.method = request.method;
  solvers::ps::UseDerivative(request.derivative, &options.blinn_phong);
  // Never below one DN: quantisation alone leaves values within 1 DN of black
  // in shadow. Above that, a multiple of the read noise: the stack's (which
  // includes the subtracted dark's) or, for a data set without dark frames,
  // the solver's estimate.
  options.lambertian.shadow_threshold = 1.0;
  options.shadow_threshold_read_sigmas = request.shadow_threshold_sigma;
  options.lambertian.saturation_level = saturation_level;
  options.lambertian.max_condition_number = request.max_condition_number;
  options.progress = request.progress;
  return options;
}

PhotometricStereoInput LoadRunStack(const std::string& run_directory, const ColorStackOptions& color,
                                    FailedCapture failed) {
  const RunManifest manifest = LoadRunManifest(run_directory);
  PhotometricStereoInput input;
  input.source = run_directory;
  input.capture = CheckCaptureForSolve(run_directory, manifest, failed);
  input.loading = {{"demosaic", solvers::color::DemosaicMethodName(color.demosaic)},
                   {"color_model", color.color_model_path},
                   {"accept_failed_capture", failed == FailedCapture::kAccept}};
  RequirePhotometricStereoRun(run_directory, manifest);
  solvers::ps::PhotometricStack& stack = input.stack;
  // Samples at the clipping level are dropped per pixel; a sensor whose full
  // well fills first clips below the ADC's top code.
  const double top_code = static_cast<double>((1u << manifest.bit_depth) - 1u);
  const double saturation = manifest.saturation_dn > 0.0 ? std::min(manifest.saturation_dn, top_code) : top_code;
  const bool colour = manifest.mosaic != "mono";
  // Not ignored: a report must not name a model that touched no pixel.
  if (!colour && !color.color_model_path.empty())
    throw std::invalid_argument("--color-model " + color.color_model_path + ": " + run_directory +
                                " is a monochrome run, and a colour model applies only to colour runs: drop the option");
  // Only darks and single-LED frames enter the stack: flats, patterns and
  // gonioreflectometer poses (led -1) light several LEDs or none on their own.
  // Bracketed and repeated frames of one LED are extra rows, each scaled by
  // its own exposure; the solver drops their saturated samples, so a bracket
  // merges into one least-squares fit.
  std::vector<const FrameRecord*> records;
  std::vector<int> slots;  // a light frame's place in the stack; -1 for a dark
  int lit = 0;
  for (const FrameRecord& record : manifest.frames) {
    const bool dark = record.kind == config::CaptureStep::Kind::kDark;
    if (!dark && (record.kind != config::CaptureStep::Kind::kLight || record.led < 0)) continue;
    records.push_back(&record);
    slots.push_back(dark ? -1 : lit++);
  }
  // A monochrome stack's frames go straight into one slab (AllocateFrameSlab).
  const cv::Mat slab = colour || lit == 0 ? cv::Mat() : AllocateFrameSlab(lit, {manifest.width, manifest.height}, CV_32F);
  // A colour frame's luminance stand-in is the sum of its camera channels
  // (after demosaicing); a pixel any clipped raw sample reached is clipped in it.
  auto to_float = [&](const cv::Mat& raw, cv::Mat out) {
    if (!colour) {
      raw.convertTo(out, CV_32F);
      return out;
    }
    cv::Mat clipped = raw >= saturation;
    cv::Mat rgb = raw;
    if (IsBayerPattern(manifest.mosaic)) {
      cv::dilate(clipped, clipped, cv::Mat::ones(3, 3, CV_8U));
      rgb = DemosaicToRgb(raw, manifest.mosaic, color.demosaic);
    } else {
      cv::transform(clipped, clipped, cv::Matx13f(1, 1, 1));
    }
    rgb.convertTo(rgb, CV_32F);
    cv::transform(rgb, out, cv::Matx13f(1, 1, 1));
    out.setTo(3.0 * saturation, clipped);
    return out;
  };
  // Decoding and checking the frames is most of a load: on all cores, then
  // taken in the manifest's order, so a fault is reported where that order meets it.
  std::vector<cv::Mat> frames(records.size());
  const std::vector<std::exception_ptr> failures = LoadOnEveryCore(records.size(), [&](std::size_t i) {
    const cv::Mat into = slab.empty() || slots[i] < 0 ? cv::Mat() : FrameOfSlab(slab, slots[i], manifest.height);
    frames[i] = to_float(LoadFrame(run_directory, *records[i]), into);
  });
  std::vector<cv::Mat> darks;
  std::vector<const config::LedConfig*> stack_leds;  // the LED of each image
  for (std::size_t i = 0; i < records.size(); ++i) {
    const FrameRecord& record = *records[i];
    if (failures[i]) std::rethrow_exception(failures[i]);
    const cv::Mat& frame = frames[i];
    if (frame.cols != manifest.width || frame.rows != manifest.height)
      throw std::runtime_error(run_directory + "/" + record.file + ": frame is " + std::to_string(frame.cols) + "x" +
                               std::to_string(frame.rows) + ", the run is " + std::to_string(manifest.width) + "x" +
                               std::to_string(manifest.height));
    if (record.kind == config::CaptureStep::Kind::kDark) {
      darks.push_back(frame);
      continue;
    }
    if (record.led >= static_cast<int>(manifest.lights.size()))
      throw std::runtime_error(run_directory + "/manifest.json: frame " + record.file + " names LED index " +
                               std::to_string(record.led) + " outside the rig's " +
                               std::to_string(manifest.lights.size()) + " LEDs");
    const config::LedConfig& led = manifest.lights[record.led];
    stack_leds.push_back(&led);
    input.image_leds.push_back(record.led);
    stack.images.push_back(frame);
    stack.light_directions.push_back(led.direction);
    const double gain = std::pow(10.0, record.gain_db / 20.0);
    stack.light_scales.push_back(led.intensity * record.level * manifest.dn_per_radiance_per_us *
                                 record.exposure_us * gain);
  }
  input.dark_frames = static_cast<int>(darks.size());
  if (manifest.pixel_pitch_mm > 0.0) input.pixel_pitch = manifest.pixel_pitch_mm;
  input.camera = solvers::camera::Camera{manifest.projection, manifest.width, manifest.height, input.pixel_pitch,
                                         manifest.pinhole};
  input.near_lights = NearLightsOf(stack_leds);
  input.run_leds = manifest.lights;
  // Photon noise in DN^2 per DN of signal: gain / (electrons per DN). All frames
  // of a run share the gain in practice; the first light frame's is used.
  if (manifest.e_per_dn > 0.0) {
    for (const FrameRecord& record : manifest.frames)
      if (record.kind == config::CaptureStep::Kind::kLight) {
        stack.noise.shot_gain = std::pow(10.0, record.gain_db / 20.0) / manifest.e_per_dn;
        break;
      }
  }
  input.saturation_level = colour ? 3.0 * saturation : saturation;
  if (!darks.empty()) {
    stack.dark = cv::Mat::zeros(darks.front().size(), CV_32F);
    for (const cv::Mat& dark : darks) stack.dark += dark;
    stack.dark /= static_cast<double>(darks.size());
    stack.noise.read_sigma = DarkNoiseSigma(darks, stack.dark) * std::sqrt(1.0 + 1.0 / darks.size());
  } else {
    spdlog::warn("{}: no dark frame; the solver assumes a zero black level", run_directory);
  }
  // A volume scene's truth has no surface (RunWriter::WriteVolumeGroundTruth).
  if (const fs::path truth = fs::path(run_directory) / "ground_truth";
      manifest.has_ground_truth && fs::exists(truth / "normals.tiff")) {
    input.truth_normals = ReadFloatTiff((truth / "normals.tiff").string());
    input.truth_albedo = ReadFloatTiff((truth / "albedo.tiff").string());
    if (fs::exists(truth / "material.png")) input.truth_material = ReadImage((truth / "material.png").string());
    if (fs::exists(truth / "height.tiff")) input.truth_height = ReadFloatTiff((truth / "height.tiff").string());
    if (fs::exists(truth / "albedo_rgb.tiff"))
      input.truth_albedo_rgb = ReadFloatTiff((truth / "albedo_rgb.tiff").string());
  }
  if (colour) input.color = LoadRunColorStack(run_directory, color);
  return input;
}

void ApplyRigCalibration(const std::string& rig_path, PhotometricStereoInput* input) {
  auto refuse = [&rig_path](const std::string& why) { throw config::ConfigError(rig_path, 0, 0, "", why); };
  if (input->image_leds.empty()) refuse("a rig's calibration applies to a run's frames, not to " + input->source);
  const config::RigConfig rig = config::LoadRigConfig(rig_path);
  const std::vector<config::LedConfig>& leds = rig.lights.leds;
  if (leds.size() != input->run_leds.size())
    refuse("the rig has " + std::to_string(leds.size()) + " LEDs, the run " + input->source + " " +
           std::to_string(input->run_leds.size()));
  for (std::size_t i = 0; i < leds.size(); ++i)
    if (leds[i].id != input->run_leds[i].id)
      refuse("LED " + std::to_string(i) + " has id " + std::to_string(leds[i].id) + ", the run's " +
             std::to_string(input->run_leds[i].id));
  const cv::Size images = input->stack.images.front().size();
  if (rig.camera.width != images.width || rig.camera.height != images.height)
    refuse("the rig's camera takes " + std::to_string(rig.camera.width) + "x" + std::to_string(rig.camera.height) +
           " frames, the run's are " + std::to_string(images.width) + "x" + std::to_string(images.height));
  solvers::ps::PhotometricStack& stack = input->stack;
  std::vector<const config::LedConfig*> image_leds;
  for (std::size_t k = 0; k < input->image_leds.size(); ++k) {
    const config::LedConfig& now = leds[input->image_leds[k]];
    const config::LedConfig& then = input->run_leds[input->image_leds[k]];
    image_leds.push_back(&now);
    stack.light_directions[k] = now.direction;
    // A frame's scale is the LED's intensity times what the capture set (level, exposure, gain).
    stack.light_scales[k] *= now.intensity / then.intensity;
    if (input->color)
      input->color->light_scales[k] = input->color->light_scales[k].cwiseProduct(
          (now.intensity * now.rgb_intensity).cwiseQuotient(then.intensity * then.rgb_intensity));
  }
  input->near_lights = NearLightsOf(image_leds);
  if (rig.camera.pixel_pitch_mm > 0.0) input->pixel_pitch = rig.camera.pixel_pitch_mm;
  input->camera = solvers::camera::Camera{rig.camera.projection, rig.camera.width, rig.camera.height,
                                          input->pixel_pitch, rig.camera.pinhole};
  input->run_leds = leds;
  input->loading["rig"] = std::filesystem::absolute(rig_path).string();
}

void SetObjectMaskFromFile(const std::string& path, PhotometricStereoInput* input) {
  cv::Mat mask = ReadInputImage(path);
  if (mask.channels() > 1) cv::extractChannel(mask, mask, 0);
  const cv::Size images = input->stack.images.empty() ? mask.size() : input->stack.images.front().size();
  if (mask.size() != images)
    throw config::ConfigError(path, 0, 0, "", "the mask is " + std::to_string(mask.cols) + "x" + std::to_string(mask.rows) +
                                          ", the images of " + input->source + " are " + std::to_string(images.width) +
                                          "x" + std::to_string(images.height));
  input->object_mask = mask != 0;
  input->mask_source = path;
  input->loading["mask"] = std::filesystem::absolute(path).string();
}

cv::Mat AutomaticObjectMask(const solvers::ps::PhotometricStack& stack, double sigmas) {
  if (stack.dark.empty() || stack.images.empty()) return {};
  cv::Mat brightest = stack.images.front().clone();
  for (const cv::Mat& image : stack.images) cv::max(brightest, image, brightest);
  const double threshold_dn = std::max(1.0, sigmas * stack.noise.read_sigma);
  return (brightest - stack.dark) > threshold_dn;
}

double EffectiveSaturationLevel(const PhotometricStereoInput& input) {
  if (std::isfinite(input.saturation_level)) return input.saturation_level;
  double max_value = 0.0;
  for (const cv::Mat& image : input.stack.images) {
    double image_max = 0.0;
    cv::minMaxLoc(image, nullptr, &image_max);
    max_value = std::max(max_value, image_max);
  }
  // Clipped samples sit at the largest code the data reach when that is a
  // full-scale code (2^n - 1); otherwise nothing is treated as clipped.
  const double full_scale = std::exp2(std::ceil(std::log2(max_value + 1.0))) - 1.0;
  return max_value >= full_scale ? full_scale : input.saturation_level;
}

json ToJson(const PhotometricStereoResult& result) {
  const solvers::ps::SolverSummary& summary = result.summary;
  const double saturation = result.saturation_level;
  json report = solvers::core::ToJson(summary);
  report.update({{"source", result.source},
                 {"method", summary.method},
                 {"lights", summary.light_count},
                 {"dark_frames", result.dark_frames},
                 {"condition_number", summary.condition_number},
                 {"noise",
                  {{"read_sigma", summary.noise_read_sigma > 0 ? summary.noise_read_sigma : result.noise_sigma_dn},
                   {"shot_gain", summary.noise_shot_gain},
                   {"estimated", summary.noise_estimated}}},
                 {"noise_sigma_dn", result.noise_sigma_dn},
                 {"shadow_threshold", summary.shadow_threshold},
                 {"saturation_level", std::isfinite(saturation) ? json(saturation) : json(nullptr)},
                 {"mask",
                  {{"source", result.mask_source.empty() ? json(nullptr) : json(result.mask_source)},
                   {"pixels", result.mask_pixels}}},
                 {"pixels",
                  {{"total", summary.pixels_total},
                   {"solved", summary.pixels_solved},
                   {"outside_mask", summary.pixels_outside_mask},
                   {"too_few_lights", summary.pixels_too_few_lights},
                   {"ill_conditioned", summary.pixels_ill_conditioned},
                   {"rejected_by_model", summary.pixels_rejected_by_model},
                   {"fell_back", summary.pixels_fell_back},
                   // of models.blinn_phong: auto's step 5, with the lobe of its region or
                   // nearest glossy pixels
                   {"shared_lobe", summary.pixels_shared_lobe}}},
                 {"models",
                  {{"lambertian", summary.pixels_lambertian},
                   {"trimmed", summary.pixels_trimmed},
                   {"irls", summary.pixels_irls},
                   {"blinn_phong", summary.pixels_blinn_phong},
                   {"ggx", summary.pixels_ggx},
                   {"low_frequency", summary.pixels_low_frequency}}},
                 // auto's step 7: the lobe-shift test on a sample of the lobes, and
                 // whether it went on to every lobe
                 {"lobe_shift_test",
                  {{"sample_tested", summary.lobe_shift_sample_tested},
                   {"sample_shifted", summary.lobe_shift_sample_shifted},
                   {"every_lobe", summary.lobe_shift_every_lobe}}},
                 // of models.low_frequency (auto): the step-7 rule that took each
                 {"low_frequency_rules",
                  {{"lobe_shifted", summary.low_frequency_rules.lobe_shifted},
                   {"explains_apart", summary.low_frequency_rules.explains_apart},
                   {"region_rejects_shape", summary.low_frequency_rules.region_rejects_shape},
                   {"strong_evidence", summary.low_frequency_rules.strong_evidence}}},
                 {"samples_rejected", summary.samples_rejected},
                 {"pixels_on_light_subsets", summary.pixels_on_light_subsets}});
  // The solve's steps, of its `solve`.
  report["timings_ms"].update({{"tiles", summary.tiles_ms},
                               {"shared_lobe", summary.shared_lobe_ms},
                               {"low_frequency", summary.low_frequency_ms}});
  // The stage's total: reading the frames and writing the results included.
  report["timings_ms"]["total"] = result.total_ms;
  const LightModelReport& lights = result.light_model;
  report["light_model"] = {{"model", lights.near ? "near" : "distant"}};
  if (lights.near)
    report["light_model"].update({{"rounds", lights.rounds},
                                  {"normal_change_deg", lights.normal_change_deg},
                                  {"depth_offset_mm", lights.depth_offset_mm},
                                  {"depth_ms", lights.depth_ms}});
  if (lights.predicted_distant_bias_deg)
    report["light_model"]["predicted_distant_bias_deg"] = *lights.predicted_distant_bias_deg;
  report["camera_model"] = {{"projection", solvers::camera::ProjectionName(result.camera.projection)}};
  if (result.camera.IsPinhole()) {
    report["camera_model"].update(PinholeLensJson(result.camera.pinhole));
    report["camera_model"]["field_of_view_deg"] = result.camera.HorizontalFieldOfViewDeg();
  } else {
    report["camera_model"]["pixel_pitch_mm"] = result.camera.pixel_pitch_mm;
  }
  if (lights.predicted_view_bias_deg) report["camera_model"]["predicted_view_bias_deg"] = *lights.predicted_view_bias_deg;
  if (lights.per_pixel_views) report["camera_model"]["lobe_views"] = "per_pixel";
  if (result.capture) report["capture"] = result.capture->ToJson();
  report["provenance"] = result.provenance.ToJson();
  if (result.mean_confidence) report["mean_confidence"] = *result.mean_confidence;
  if (!result.previews.is_null()) report["previews"] = result.previews;
  if (result.depth) {
    const solvers::ps::IntegrationSummary& integrated = result.depth->summary;
    report["depth"] = {{"integrator", solvers::ps::IntegratorName(result.depth->integrator)},
                       {"success", integrated.IsSolutionUsable()},
                       {"message", integrated.message},
                       {"pixels", integrated.pixels},
                       {"pixels_dropped", integrated.pixels_dropped},
                       {"residual_rms", integrated.residual_rms},
                       {"iterations", integrated.iterations},
                       {"pixel_pitch", result.depth->pixel_pitch},
                       {"perspective", result.depth->perspective},
                       {"from_near_lights", result.depth->from_near_lights}};
    if (result.depth->rms_error_vs_truth) report["depth"]["rms_error_vs_truth"] = *result.depth->rms_error_vs_truth;
    report["timings_ms"]["integrate"] = integrated.solve_ms;
  }
  if (result.color) {
    report["color"] = ToJson(*result.color);
    report["color"]["albedo"] = "per channel with the normals fixed (solved on the sum of the camera channels)";
    if (result.color_albedo_summary)
      report["color"]["green_channel_pixels_solved"] = result.color_albedo_summary->pixels_solved;
  }
  if (result.fill) {
    const solvers::ps::FillSummary& fill = *result.fill;
    report["fill"] = solvers::core::ToJson(fill);
    report["fill"].update({{"pixels_filled", fill.pixels_filled},
                           {"pixels_left", fill.pixels_left},
                           {"max_distance_px", fill.max_distance_px},
                           {"mean_confidence", fill.mean_confidence}});
    report["timings_ms"]["fill"] = fill.total_ms;
  }
  if (result.normals_vs_truth) {
    report["ground_truth"] = MetricsJson(*result.normals_vs_truth);
    if (result.filled_vs_truth) report["ground_truth"]["filled"] = MetricsJson(*result.filled_vs_truth);
    if (result.albedo_ciede2000_vs_truth)
      for (const auto& [name, e] : {std::pair{"all", result.albedo_ciede2000_vs_truth->all},
                                    std::pair{"interior", result.albedo_ciede2000_vs_truth->interior}})
        report["ground_truth"]["albedo_ciede2000"][name] = {
            {"mean", e.mean}, {"median", e.median}, {"p95", e.p95}, {"pixels", e.pixels}};
    if (result.mean_relative_albedo_error)
      report["ground_truth"]["mean_relative_albedo_error"] = *result.mean_relative_albedo_error;
  }
  return report;
}

namespace {

// RMS of depth - truth after removing their mean difference: integrated
// depth is known up to a constant (an orthographic camera's offset; a
// pinhole's scale moves a small object about as much).
double DepthErrorVsTruth(const cv::Mat& depth, const cv::Mat& truth) {
  const cv::Mat both = (depth == depth) & (truth == truth);
  cv::Mat difference = depth - truth;
  cv::patchNaNs(difference, 0.0);
  const double offset = cv::mean(difference, both)[0];
  cv::Mat centred = difference - offset;
  centred.setTo(0.0, ~both);
  const double pixels = std::max(1, cv::countNonZero(both));
  return std::sqrt(centred.dot(centred) / pixels);
}

// `why` and what else to do: a solve refused for its predicted bias.
solvers::ps::SolverSummary Refused(const solvers::ps::PhotometricStereoOptions& options,
                                   const solvers::ps::PhotometricStack& stack, const std::string& why) {
  solvers::ps::SolverSummary refused;
  refused.method = solvers::ps::MethodName(options.method);
  refused.light_count = stack.light_count();
  refused.End(solvers::core::Termination::kFailure, why + ", or raise --max-distant-bias");
  return refused;
}

std::string BiasAboveLimit(double bias_deg, const config::PhotometricStereoRequest& request) {
  char text[96];
  std::snprintf(text, sizeof(text), " by about %.2f deg, above max_distant_bias_deg %.2f", bias_deg,
                request.max_distant_bias_deg);
  return text;
}

// Half the mean angle between the object's lines of sight and the camera's
// axis: a specular lobe fitted with the view along the axis peaks at the
// half vector of the light and that axis, tilted from the true one by half
// the view's own tilt.
double PredictedViewBiasDeg(const solvers::camera::Camera& camera, const cv::Mat& mask) {
  const solvers::camera::PixelRays rays(camera);
  double sum = 0.0;
  std::size_t count = 0;
  for (int r = 0; r < camera.height_px; ++r)
    for (int c = 0; c < camera.width_px; ++c)
      if (mask.empty() || mask.at<std::uint8_t>(r, c))
        sum += std::acos(std::clamp(rays.ViewDirection(r, c).z(), -1.0, 1.0)), ++count;
  return count ? 0.5 * sum / count * 180.0 / 3.14159265358979323846 : 0.0;
}

// The normals under the rig's near LEDs when it gives their positions
// (every method, each pixel with its own light vectors and line of sight),
// unless the request assumes distant lights; else with the distant model,
// refused when the geometry predicts its bias on an object this size above
// the request's limit (a result a person at the bench would reject). The
// distant model's specular lobes take the view along the camera's axis;
// where a pinhole camera's lines of sight tilt too far for that, the lights
// go to the near-light solve as lights at infinity, which fits each pixel
// through its own line of sight. *near_height_mm, unless null: the near
// solve's surface, else left empty.
solvers::ps::SolverSummary SolveNormals(const PhotometricStereoInput& input, const config::PhotometricStereoRequest& request,
                                        const solvers::ps::PhotometricStereoOptions& options,
                                        const solvers::ps::PhotometricStack& stack, solvers::ps::NormalMap* map,
                                        LightModelReport* report, cv::Mat* near_height_mm) {
  using solvers::ps::Method;
  const solvers::camera::Camera camera = CameraOf(input);
  if (!input.near_lights.empty() && !request.assume_distant) {
    solvers::ps::NearLightOptions near;
    near.camera = camera;
    const solvers::ps::NearLightSummary summary =
        solvers::ps::SolveNearLightPhotometricStereo(options, near, stack, input.near_lights, map, near_height_mm);
    report->near = true;
    report->rounds = summary.rounds;
    report->normal_change_deg = summary.normal_change_deg;
    report->depth_offset_mm = summary.depth_offset_mm;
    report->depth_ms = summary.depth_ms;
    return summary;
  }
  if (!input.near_lights.empty()) {
    const int object_pixels = stack.mask.empty() ? stack.width() * stack.height() : cv::countNonZero(stack.mask);
    const double radius_mm = std::sqrt(object_pixels / 3.14159265358979323846) * camera.PixelSizeOnPlaneMm();
    const double bias_deg = solvers::ps::DistantModelBiasDeg(input.near_lights, stack.light_directions, radius_mm);
    report->predicted_distant_bias_deg = bias_deg;
    if (bias_deg > request.max_distant_bias_deg) {
      char size[96];
      std::snprintf(size, sizeof(size), "an object this size (radius %.1f mm) would be biased", radius_mm);
      return Refused(options, stack,
                     std::string("the rig's LEDs are near: solved as distant lights, ") + size +
                         BiasAboveLimit(bias_deg, request) +
                         "; drop --assume-distant (recipe key assume_distant) to solve with the near-light model");
    }
  }
  const bool views_matter = options.method == Method::kBlinnPhong || options.method == Method::kAuto ||
                            options.method == Method::kLowFrequency;
  if (camera.IsPinhole() && views_matter) {
    const double bias_deg = PredictedViewBiasDeg(camera, stack.mask);
    report->predicted_view_bias_deg = bias_deg;
    if (bias_deg > request.max_distant_bias_deg) {
      std::vector<solvers::camera::NearLight> at_infinity;
      for (const Eigen::Vector3d& direction : stack.light_directions)
        at_infinity.push_back(solvers::camera::NearLight::AtInfinity(direction));
      solvers::ps::NearLightOptions views;
      views.camera = camera;
      report->per_pixel_views = true;
      return solvers::ps::SolveNearLightPhotometricStereo(options, views, stack, at_infinity, map, nullptr);
    }
  }
  return solvers::ps::SolvePhotometricStereo(options, stack, map);
}

}  // namespace

solvers::camera::Camera CameraOf(const PhotometricStereoInput& input) {
  if (input.camera) return *input.camera;
  return solvers::camera::Camera::Orthographic(input.stack.width(), input.stack.height(), input.pixel_pitch);
}

PhotometricStereoResult SolveToMaps(const PhotometricStereoInput& input, const config::PhotometricStereoRequest& request,
                                    PhotometricStereoMaps* maps) {
  if (std::string why; !request.IsValid(&why)) throw std::invalid_argument(why);
  solvers::ps::PhotometricStack stack = input.stack;
  PhotometricStereoResult result;
  if (!input.object_mask.empty()) {
    stack.mask = input.object_mask;
    result.mask_source = input.mask_source;
  } else if (!stack.dark.empty()) {
    stack.mask = AutomaticObjectMask(stack, kAutomaticMaskSigmas);
    char rule[96];
    std::snprintf(rule, sizeof(rule), "automatic: brightest lit frame above the dark by %g read-noise sigmas",
                  kAutomaticMaskSigmas);
    result.mask_source = rule;
  }
  if (!stack.mask.empty()) result.mask_pixels = cv::countNonZero(stack.mask);
  const double saturation = EffectiveSaturationLevel(input);
  const solvers::ps::PhotometricStereoOptions options = MakeSolverOptions(request, saturation);

  *maps = PhotometricStereoMaps();
  solvers::ps::NormalMap& map = maps->map;
  cv::Mat near_height_mm;
  // The near solve's full-resolution surface is made only where depth is asked for.
  result.summary = SolveNormals(input, request, options, stack, &map, &result.light_model,
                                request.integrator ? &near_height_mm : nullptr);
  result.source = input.source;
  result.camera = CameraOf(input);
  result.capture = input.capture;
  result.provenance = MakeProvenance("photometric_stereo", input.source, RequestJson(request), input.loading);
  result.dark_frames = input.dark_frames;
  result.noise_sigma_dn = stack.noise.read_sigma;
  result.saturation_level = saturation;
  if (!result.usable()) return result;

  const cv::Mat solved = map.flags == static_cast<int>(solvers::ps::PixelFlag::kSolved);
  result.mean_confidence = cv::mean(map.confidence, solved)[0];
  if (request.fill_unresolved) result.fill = solvers::ps::FillUnresolvedNormals({}, &map);
  const cv::Mat filled = map.flags == static_cast<int>(solvers::ps::PixelFlag::kFilled);
  const cv::Mat with_normal = solved | filled;  // what depth and the mesh are made of
  // Colour data: per-channel albedo with the normals fixed.
  if (input.color) maps->albedo_rgb = SolveColorAlbedo(*input.color, map.normals, request.shadow_threshold_sigma, &result);
  if (request.integrator) {
    const solvers::camera::Camera camera = result.camera;
    // Undistorting every pixel is worth doing once: integration and mesh share the rays.
    if (camera.IsPinhole()) maps->rays.emplace(camera);
    PhotometricStereoDepth& integrated = result.depth.emplace();
    integrated.integrator = *request.integrator;
    integrated.pixel_pitch = input.pixel_pitch;
    integrated.perspective = camera.IsPinhole();
    solvers::ps::IntegrationOptions integration;
    integration.integrator = *request.integrator;
    integration.pixel_pitch = input.pixel_pitch;
    cv::Mat& depth = maps->depth;
    if (!near_height_mm.empty()) {
      // The near-light rounds ended on a surface placed where the model fits
      // best: its heights are absolute, which integrating again would lose.
      integrated.from_near_lights = true;
      depth = near_height_mm;
      integrated.summary.pixels = static_cast<std::size_t>(cv::countNonZero(depth == depth));
      integrated.summary.End(solvers::core::Termination::kSuccess, "the near-light solve's surface");
    } else if (camera.IsPinhole()) {
      integrated.summary =
          solvers::ps::IntegrateNormalsPerspective(integration, *maps->rays, map.normals, with_normal, &depth);
    } else {
      integrated.summary = solvers::ps::IntegrateNormals(integration, map.normals, with_normal, &depth);
    }
    if (integrated.summary.IsSolutionUsable()) {
      if (!input.truth_height.empty()) integrated.rms_error_vs_truth = DepthErrorVsTruth(depth, input.truth_height);
    } else {
      depth.release();
    }
  }

  if (input.truth_normals.empty()) return result;
  const solvers::ps::AngularErrorStats vs_truth =
      solvers::ps::CompareNormals(map.normals, input.truth_normals, stack.mask, &maps->angular_error_deg);
  if (!vs_truth.IsSolutionUsable()) {
    spdlog::warn("{}: ground-truth normals not compared: {}", input.source, vs_truth.message);
    maps->angular_error_deg.release();
    return result;
  }
  result.normals_vs_truth = vs_truth;
  if (cv::countNonZero(filled) > 0)
    result.filled_vs_truth = solvers::ps::CompareNormals(map.normals, input.truth_normals, filled);
  if (!maps->albedo_rgb.empty() && !input.truth_albedo_rgb.empty()) {
    result.albedo_ciede2000_vs_truth = CompareColorAlbedo(maps->albedo_rgb, input.truth_albedo_rgb, solved);
  } else if (!input.truth_albedo.empty() && maps->albedo_rgb.empty()) {
    cv::Mat relative;
    cv::absdiff(map.albedo, input.truth_albedo, relative);
    relative /= input.truth_albedo;
    cv::patchNaNs(relative, 0.0);
    result.mean_relative_albedo_error = cv::mean(relative, solved)[0];
  }
  return result;
}

namespace {

// Every file of a usable solve but report.json; sets the result's previews.
void WriteMaps(const PhotometricStereoInput& input, const PhotometricStereoMaps& maps, const fs::path& out,
               PhotometricStereoResult* result) {
  const solvers::ps::NormalMap& map = maps.map;
  const cv::Mat solved = map.flags == static_cast<int>(solvers::ps::PixelFlag::kSolved);
  WriteFloatTiff((out / "normals.tiff").string(), map.normals);
  WriteFloatTiff((out / "albedo.tiff").string(), maps.albedo_rgb.empty() ? map.albedo : maps.albedo_rgb);
  WriteFloatTiff((out / "confidence.tiff").string(), map.confidence);
  cv::Mat specular;
  cv::Mat channels[] = {cv::Mat(), cv::Mat(), cv::Mat::zeros(map.specular.size(), CV_32F)};
  cv::split(map.specular, channels);
  cv::merge(channels, 3, specular);
  WriteFloatTiff((out / "specular.tiff").string(), specular);
  if (!maps.depth.empty()) {
    WriteFloatTiff((out / "depth.tiff").string(), maps.depth);
    if (maps.rays)
      WriteDepthMeshPly((out / "mesh.ply").string(), maps.depth, *maps.rays);
    else
      WriteDepthMeshPly((out / "mesh.ply").string(), maps.depth, input.pixel_pitch);
  }
  result->previews = WritePhotometricStereoPreviews(map, solved, maps.depth, out.string());
  if (!maps.albedo_rgb.empty()) {
    const bool calibrated = result->color->color_space == "linear-srgb";
    // Calibrated albedo is absolute: 1 is a perfect white. Camera RGB and
    // DiLiGenT's DN are not, so they map from their own 99.5th percentile.
    const cv::Mat& albedo_rgb = maps.albedo_rgb;
    const double top = calibrated ? 1.0 : std::max(1e-12, PercentileOverMask(albedo_rgb.reshape(1, albedo_rgb.rows * albedo_rgb.cols * 3),
                                                                               RepeatMask3(solved), 99.5));
    WriteImage((out / "albedo.png").string(), ColorAlbedoPreview(albedo_rgb, solved, top));
    result->previews["albedo.png"] = {{"low", 0.0},
                                      {"high", top},
                                      {"scale", "linear " + std::string(calibrated ? "sRGB" : "camera RGB") + " 0.." +
                                                    std::to_string(top) + " -> sRGB-encoded 0..255 per channel"}};
    if (!calibrated) result->previews["albedo.png"]["percentile"] = 99.5;
  }
  if (!maps.angular_error_deg.empty()) WriteFloatTiff((out / "angular_error.tiff").string(), maps.angular_error_deg);
}

}  // namespace

PhotometricStereoResult SolveAndWrite(const PhotometricStereoInput& input, const config::PhotometricStereoRequest& request,
                                      const std::string& output_directory, const std::function<void()>& before_commit) {
  const auto start = std::chrono::steady_clock::now();
  // Before the solve: a destination holding other files is refused at once, not after it.
  ResultsFolder folder(output_directory);
  PhotometricStereoMaps maps;
  PhotometricStereoResult result = SolveToMaps(input, request, &maps);
  try {  // a write that fails (a full disk) leaves no partial folder and says what to do
    if (result.usable()) WriteMaps(input, maps, folder.path(), &result);
    result.total_ms = Ms(start);
    WriteFileDurably((fs::path(folder.path()) / "report.json").string(), ToJson(result).dump(2) + "\n");
  } catch (...) {
    folder.Abandon(std::current_exception());
  }
  if (before_commit) before_commit();
  folder.Commit();
  return result;
}

}  // namespace photorig::daemon
