#include "photorig/daemon/ps_pipeline.h"

#include "photorig/daemon/image_io.h"
#include "photorig/daemon/run_store.h"
#include "photorig/ps/evaluation.h"
#include "photorig/ps/lambertian.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <filesystem>

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
  std::vector<float> values(mean_dark.begin<float>(), mean_dark.end<float>());
  auto middle = values.begin() + values.size() / 2;
  std::nth_element(values.begin(), middle, values.end());
  const float median = *middle;
  for (float& v : values) v = std::abs(v - median);
  std::nth_element(values.begin(), middle, values.end());
  return 1.4826 * *middle;
}

}  // namespace

json SolvePhotometricStereoRun(const std::string& run_directory, const PhotometricStereoRequest& request,
                               const std::string& output_directory) {
  const auto start = std::chrono::steady_clock::now();
  const RunManifest manifest = LoadRunManifest(run_directory);

  ps::PhotometricStack stack;
  std::vector<cv::Mat> darks;
  int bit_depth = manifest.bit_depth;
  for (const FrameRecord& record : manifest.frames) {
    cv::Mat frame;
    LoadFrame(run_directory, record).convertTo(frame, CV_32F);
    if (frame.cols != manifest.width || frame.rows != manifest.height)
      throw std::runtime_error(run_directory + "/" + record.file + ": frame is " + std::to_string(frame.cols) + "x" +
                               std::to_string(frame.rows) + ", the run is " + std::to_string(manifest.width) + "x" +
                               std::to_string(manifest.height));
    if (record.kind == "dark") {
      darks.push_back(frame);
      continue;
    }
    if (record.led < 0 || record.led >= static_cast<int>(manifest.lights.size()))
      throw std::runtime_error(run_directory + "/manifest.json: frame " + record.file + " names LED index " +
                               std::to_string(record.led) + " outside the rig's " +
                               std::to_string(manifest.lights.size()) + " LEDs");
    const LedConfig& led = manifest.lights[record.led];
    stack.images.push_back(frame);
    stack.light_directions.push_back(led.direction);
    const double gain = std::pow(10.0, record.gain_db / 20.0);
    stack.light_scales.push_back(led.intensity * record.level * manifest.dn_per_radiance_per_us *
                                 record.exposure_us * gain);
  }
  const double load_ms = Ms(start);

  double noise_sigma_dn = 0.0;
  if (!darks.empty()) {
    stack.dark = cv::Mat::zeros(darks.front().size(), CV_32F);
    for (const cv::Mat& dark : darks) stack.dark += dark;
    stack.dark /= static_cast<double>(darks.size());
    noise_sigma_dn = DarkNoiseSigma(darks, stack.dark);
  } else {
    spdlog::warn("{}: no dark frame; the solver assumes a zero black level", run_directory);
  }

  ps::LambertianOptions options;
  options.exclude_unusable_samples = request.method == "lambertian";
  // I - D carries the noise of the frame and of the averaged dark: sigma * sqrt(1 + 1/n).
  const double difference_sigma_dn =
      darks.empty() ? noise_sigma_dn : noise_sigma_dn * std::sqrt(1.0 + 1.0 / static_cast<double>(darks.size()));
  // Never below one DN: quantisation alone leaves values within 1 DN of black in shadow.
  options.shadow_threshold = std::max(1.0, request.shadow_threshold_sigma * difference_sigma_dn);
  options.saturation_level = static_cast<double>((1u << bit_depth) - 1u);
  options.max_condition_number = request.max_condition_number;

  ps::NormalMap map;
  const ps::SolverSummary summary = ps::SolveLambertian(options, stack, &map);

  fs::create_directories(output_directory);
  const fs::path out(output_directory);
  json report = {{"run", run_directory},
                 {"method", summary.method},
                 {"termination", summary.IsSolutionUsable() ? "success" : "failure"},
                 {"message", summary.message},
                 {"lights", summary.light_count},
                 {"dark_frames", darks.size()},
                 {"condition_number", summary.condition_number},
                 {"noise_sigma_dn", noise_sigma_dn},
                 {"shadow_threshold_dn", options.shadow_threshold},
                 {"saturation_level_dn", options.saturation_level},
                 {"pixels",
                  {{"total", summary.pixels_total},
                   {"solved", summary.pixels_solved},
                   {"outside_mask", summary.pixels_outside_mask},
                   {"too_few_lights", summary.pixels_too_few_lights},
                   {"ill_conditioned", summary.pixels_ill_conditioned},
                   {"rejected_by_model", summary.pixels_rejected_by_model}}},
                 {"samples_rejected", summary.samples_rejected},
                 {"distinct_light_subsets", summary.distinct_light_subsets},
                 {"timings_ms", {{"load", load_ms}, {"setup", summary.setup_ms}, {"solve", summary.solve_ms}}}};

  if (summary.IsSolutionUsable()) {
    WriteFloatTiff((out / "normals.tiff").string(), map.normals);
    WriteImage((out / "normals.png").string(), NormalsToBgr8(map.normals));
    WriteFloatTiff((out / "albedo.tiff").string(), map.albedo);
    WriteImage((out / "albedo.png").string(), ScalarToGray8(map.albedo, 1.0));
    cv::Mat solved = map.flags == static_cast<int>(ps::PixelFlag::kSolved);
    WriteImage((out / "mask.png").string(), solved);
    WriteImage((out / "flags.png").string(), map.flags);

    if (manifest.has_ground_truth) {
      const fs::path truth = fs::path(run_directory) / "ground_truth";
      const cv::Mat truth_normals = ReadFloatTiff((truth / "normals.tiff").string());
      const cv::Mat truth_albedo = ReadFloatTiff((truth / "albedo.tiff").string());
      cv::Mat error_deg;
      const ps::AngularErrorStats stats = ps::CompareNormals(map.normals, truth_normals, cv::Mat(), &error_deg);
      WriteFloatTiff((out / "angular_error.tiff").string(), error_deg);
      // Albedo error relative to truth, over pixels where both exist.
      cv::Mat valid = (map.flags == static_cast<int>(ps::PixelFlag::kSolved));
      cv::Mat relative;
      cv::absdiff(map.albedo, truth_albedo, relative);
      relative /= truth_albedo;
      cv::patchNaNs(relative, 0.0);
      const double albedo_error = cv::mean(relative, valid)[0];
      report["ground_truth"] = {{"pixels_with_truth", stats.pixels_with_truth},
                                {"pixels_evaluated", stats.pixels_evaluated},
                                {"pixels_unresolved", stats.pixels_unresolved},
                                {"mean_angular_error_deg", stats.mean_deg},
                                {"median_angular_error_deg", stats.median_deg},
                                {"max_angular_error_deg", stats.max_deg},
                                {"percent_under_5deg", 100.0 * stats.fraction_under_5deg},
                                {"percent_under_10deg", 100.0 * stats.fraction_under_10deg},
                                {"percent_under_15deg", 100.0 * stats.fraction_under_15deg},
                                {"mean_relative_albedo_error", albedo_error}};
    }
  }
  report["timings_ms"]["total"] = Ms(start);
  WriteFileDurably((out / "report.json").string(), report.dump(2) + "\n");
  return report;
}

}  // namespace photorig::daemon
