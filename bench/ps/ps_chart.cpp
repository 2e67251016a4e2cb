// photorig-ps-chart: every photometric-stereo method on the simulated rig's
// scenes, captured on the 96-LED dome (config/rigs/sim-dome-96.yaml) and solved
// with all 96 lights and with every 2nd, 4th and 8th of them (and on DiLiGenT
// folders given as arguments), written as CSV rows
//   source,scene,lights,relative_noise,method,mean_deg,median_deg,under_15deg_pct,solve_ms,lambertian_pct,trimmed_pct,irls_pct,blinn_phong_pct,ggx_pct,
//   low_frequency_pct,lobe_shift_sample_shifted,lobe_shift_sample_tested
// for scripts/chart-ps.sh; solve_ms is the fastest of three runs; the last
// two: `auto`'s lobe-shift test on its sample of lobes (0,0 where it did not run). Captures go
// through the same code as `photorig run`.
//
// With --realistic: the shiny sphere (ps-shiny-sphere) on the 96-LED dome with
// what a real capture has and the simulated one lacks, each effect alone and
// all together, and the same sphere painted metal (kEffects below), every
// method solved once, written as rows
//   scene,method,mean_deg,median_deg,pixels_with_truth,unresolved,unresolved_usable3,too_few_lights,
//   ill_conditioned,rejected_by_model,lambertian_pct,trimmed_pct,irls_pct,blinn_phong_pct,ggx_pct,low_frequency_pct,
//   mean_confidence,
//   read_sigma,shot_gain,noise_estimated,shadow_threshold,saturation_level,solve_ms,
//   lobe_shift_sample_shifted,lobe_shift_sample_tested
// (unresolved: pixels with a true normal but no estimate; unresolved_usable3:
// those of them that had three or more usable samples; the three flag counts
// split `unresolved`).
//
// With --materials: the same sphere and dome with measured reflectance, one
// capture per table given (MERL .binary or RGL .bsdf, `brdf: {model:
// tabulated}`), every method solved once, rows as --realistic's with the
// table's name as the scene. Each capture is exposed as a person at the bench
// would: a first capture at the recipe's exposure, then the exposure scaled so
// that the median lit sample matches the shiny sphere's (MaterialExposure).
//
//   photorig-ps-chart SOURCE_DIR OUT.csv [DILIGENT_DIR...]
//   photorig-ps-chart SOURCE_DIR --realistic OUT.csv
//   photorig-ps-chart SOURCE_DIR --materials OUT.csv TABLE...

#include "photorig/daemon/pipelines/diligent.h"
#include "photorig/daemon/pipelines/ps_pipeline.h"
#include "photorig/daemon/service/run.h"
#include "photorig/solvers/ps/evaluation.h"
#include "photorig/solvers/ps/photometric_stereo.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <regex>
#include <sstream>

#include <unistd.h>

namespace {

namespace fs = std::filesystem;
using namespace photorig;

const solvers::ps::Method kMethods[] = {solvers::ps::Method::kL2,         solvers::ps::Method::kLambertian,
                                        solvers::ps::Method::kRobust,     solvers::ps::Method::kBlinnPhong,
                                        solvers::ps::Method::kAuto,       solvers::ps::Method::kLowFrequency};

constexpr int kRuns = 3;

// Every `step`-th light of the stack.
daemon::PhotometricStereoInput SubsetLights(const daemon::PhotometricStereoInput& input, int step) {
  daemon::PhotometricStereoInput subset = input;
  subset.stack.images.clear();
  subset.stack.light_directions.clear();
  subset.stack.light_scales.clear();
  for (int k = 0; k < input.stack.light_count(); k += step) {
    subset.stack.images.push_back(input.stack.images[k]);
    subset.stack.light_directions.push_back(input.stack.light_directions[k]);
    subset.stack.light_scales.push_back(input.stack.light_scales[k]);
  }
  return subset;
}

void Evaluate(std::ostream& csv, const std::string& source, const std::string& scene, double relative_noise,
              const daemon::PhotometricStereoInput& input) {
  for (solvers::ps::Method method : kMethods) {
    config::PhotometricStereoRequest request;  // the thresholds `photorig solve ps` uses
    request.method = method;
    const solvers::ps::PhotometricStereoOptions options = daemon::MakeSolverOptions(request, input.saturation_level);
    solvers::ps::PhotometricStack stack = input.stack;
    if (!input.object_mask.empty()) stack.mask = input.object_mask;
    solvers::ps::NormalMap map;
    solvers::ps::SolverSummary summary;
    // The fastest of three runs: on a shared machine one run can be slowed
    // several-fold by other work; the solves themselves are deterministic.
    double ms = std::numeric_limits<double>::infinity();
    for (int run = 0; run < kRuns; ++run) {
      const auto start = std::chrono::steady_clock::now();
      summary = solvers::ps::SolvePhotometricStereo(options, stack, &map);
      ms = std::min(ms, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
    }
    if (!summary.IsSolutionUsable()) {
      spdlog::warn("{} {} {}: {}", scene, stack.light_count(), solvers::ps::MethodName(method), summary.message);
      continue;
    }
    const solvers::ps::AngularErrorStats error = solvers::ps::CompareNormals(map.normals, input.truth_normals, stack.mask);
    const double solved = std::max<std::size_t>(1, summary.pixels_solved);
    csv << source << ',' << scene << ',' << stack.light_count() << ',' << relative_noise << ','
        << solvers::ps::MethodName(method) << ',' << error.mean_deg << ',' << error.median_deg << ','
        << 100.0 * error.fraction_under_15deg << ',' << ms << ',' << 100.0 * summary.pixels_lambertian / solved << ','
        << 100.0 * summary.pixels_trimmed / solved << ','
        << 100.0 * summary.pixels_irls / solved << ',' << 100.0 * summary.pixels_blinn_phong / solved << ','
        << 100.0 * summary.pixels_ggx / solved << ',' << 100.0 * summary.pixels_low_frequency / solved << ','
        << summary.lobe_shift_sample_shifted << ',' << summary.lobe_shift_sample_tested << '\n';
    std::fprintf(stderr, "%-16s %2d lights noise x%-4g %-12s mean %7.3f deg  %8.1f ms\n", scene.c_str(),
                 stack.light_count(), relative_noise, solvers::ps::MethodName(method), error.mean_deg, ms);
  }
}

std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read " + path.string());
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// `pattern` must occur in `text`; its first occurrence is replaced.
std::string ReplaceFirst(const std::string& text, const std::string& pattern, const std::string& replacement,
                         const std::string& what) {
  const std::regex re(pattern);
  if (!std::regex_search(text, re)) throw std::runtime_error(what + ": no match for '" + pattern + "'");
  return std::regex_replace(text, re, replacement, std::regex_constants::format_first_only);
}

// Captures the recipe text `recipe` on the rig text `rig` (both written to
// `scratch` under `name`) through the code of `photorig run`; returns the run directory.
std::string CaptureRun(const std::string& recipe, const std::string& rig, const std::string& name,
                       const fs::path& scratch) {
  const fs::path rig_path = scratch / (name + "-rig.yaml");
  std::ofstream(rig_path) << rig;
  const fs::path recipe_path = scratch / (name + ".yaml");
  std::ofstream(recipe_path) << ReplaceFirst(recipe, "rig: *[^\\n]*", "rig: " + fs::absolute(rig_path).string(), name);
  daemon::RunRequest request;
  request.recipe_path = recipe_path.string();
  request.output_directory = (scratch / name).string();
  request.solve = false;
  fs::remove_all(request.output_directory);
  const daemon::RunOutcome outcome = daemon::ExecuteRun(request);
  if (outcome.capture.status != daemon::CaptureStatus::kComplete) throw std::runtime_error("capture failed: " + outcome.capture.reason);
  return outcome.directory;
}

// The recipe's exposure_us scaled by `factor`.
std::string ScaleExposure(const std::string& recipe, double factor, const std::string& what) {
  std::smatch match;
  const std::regex exposure("exposure_us: *([0-9.]+)");
  if (!std::regex_search(recipe, match, exposure)) throw std::runtime_error(what + ": no exposure_us");
  const long exposure_us = std::lround(std::stod(match[1]) * factor);
  return match.prefix().str() + "exposure_us: " + std::to_string(exposure_us) + match.suffix().str();
}

// Captures `recipe` on the rig `rig` with its exposure divided by `dimming`
// (shot noise relative to the signal grows as sqrt(dimming); read noise as
// dimming).
daemon::PhotometricStereoInput Capture(const fs::path& recipe, const fs::path& rig, double dimming,
                                       const fs::path& scratch) {
  const std::string yaml = ScaleExposure(ReadText(recipe), 1.0 / dimming, recipe.string());
  const std::string name = recipe.stem().string() + "-" + std::to_string(int(dimming));
  return daemon::LoadRunStack(CaptureRun(yaml, ReadText(rig), name, scratch));
}

// What a real capture has that the simulated shiny sphere lacks, each as an
// edit of the recipe or rig text (docs/photometric-stereo.md, "Realistic scenes").
struct Effect {
  const char* name;
  bool light_error = false;  // the dome as built: LEDs 1 deg (RMS) off their stated directions, 3 % off their intensities
  bool ggx_lobe = false;     // a GGX lobe with Fresnel of the Blinn-Phong lobe's width, not Blinn-Phong
  bool ambient = false;      // the dome's walls send back 2 % of each LED's light as an even sky
  bool gamma = false;        // camera response DN ~ S^(1/1.1) instead of linear
  bool dataset = false;      // exported as a DiLiGenT folder and read back: no dark frames, no noise model, no saturation code
  // Not an effect but another material: a metal-like paint, GGX of roughness 0.3 and F0 0.9 over a dark diffuse
  // term (rho_d 0.04-0.08), whose lobe every pixel's samples see (so every pixel keeps a lobe of its own).
  bool metal = false;
};

const Effect kEffects[] = {
    {"shiny"},
    {"+light-error", true},
    {"+ggx-lobe", false, true},
    {"+ambient", false, false, true},
    {"+gamma", false, false, false, true},
    {"+no-darks", false, false, false, false, true},
    {"all", true, true, true, true, true},
    {"metal", false, false, false, false, false, true},
};

// Every method once on `input`, with the counts that say what was left unresolved and why.
void EvaluateRealistic(std::ostream& csv, const std::string& scene, const daemon::PhotometricStereoInput& input) {
  for (solvers::ps::Method method : kMethods) {
    config::PhotometricStereoRequest request;
    request.method = method;
    const double saturation = daemon::EffectiveSaturationLevel(input);
    const solvers::ps::PhotometricStereoOptions options = daemon::MakeSolverOptions(request, saturation);
    solvers::ps::PhotometricStack stack = input.stack;
    if (!input.object_mask.empty()) stack.mask = input.object_mask;
    solvers::ps::NormalMap map;
    const auto start = std::chrono::steady_clock::now();
    const solvers::ps::SolverSummary summary = solvers::ps::SolvePhotometricStereo(options, stack, &map);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    if (!summary.IsSolutionUsable()) {
      spdlog::warn("{} {}: {}", scene, solvers::ps::MethodName(method), summary.message);
      continue;
    }
    const solvers::ps::AngularErrorStats error = solvers::ps::CompareNormals(map.normals, input.truth_normals, stack.mask);
    std::size_t usable3 = 0, flag_counts[5] = {};
    for (int r = 0; r < map.normals.rows; ++r)
      for (int c = 0; c < map.normals.cols; ++c) {
        const cv::Vec3f truth = input.truth_normals.at<cv::Vec3f>(r, c);
        const bool has_truth = std::isfinite(truth[0]) && (truth[0] != 0 || truth[1] != 0 || truth[2] != 0) &&
                               (stack.mask.empty() || stack.mask.at<std::uint8_t>(r, c));
        if (!has_truth || std::isfinite(map.normals.at<cv::Vec3f>(r, c)[0])) continue;
        ++flag_counts[std::min<int>(4, map.flags.at<std::uint8_t>(r, c))];
        usable3 += map.usable_lights.at<std::uint16_t>(r, c) >= 3;
      }
    const cv::Mat solved = map.flags == static_cast<int>(solvers::ps::PixelFlag::kSolved);
    const double pixels = std::max<std::size_t>(1, summary.pixels_solved);
    csv << scene << ',' << solvers::ps::MethodName(method) << ',' << error.mean_deg << ',' << error.median_deg << ','
        << error.pixels_with_truth << ',' << error.pixels_unresolved << ',' << usable3 << ','
        << flag_counts[static_cast<int>(solvers::ps::PixelFlag::kTooFewLights)] << ','
        << flag_counts[static_cast<int>(solvers::ps::PixelFlag::kIllConditioned)] << ','
        << flag_counts[static_cast<int>(solvers::ps::PixelFlag::kRejectedByModel)] << ','
        << 100.0 * summary.pixels_lambertian / pixels << ',' << 100.0 * summary.pixels_trimmed / pixels << ','
        << 100.0 * summary.pixels_irls / pixels << ','
        << 100.0 * summary.pixels_blinn_phong / pixels << ',' << 100.0 * summary.pixels_ggx / pixels << ','
        << 100.0 * summary.pixels_low_frequency / pixels << ',' << cv::mean(map.confidence, solved)[0] << ','
        << summary.noise_read_sigma << ',' << summary.noise_shot_gain << ',' << summary.noise_estimated << ','
        << summary.shadow_threshold << ',' << (std::isfinite(saturation) ? saturation : -1.0) << ',' << ms << ','
        << summary.lobe_shift_sample_shifted << ',' << summary.lobe_shift_sample_tested << '\n';
    std::fprintf(stderr, "%-13s %-12s mean %6.3f deg  median %6.3f deg  unresolved %5zu (%zu with >= 3 usable)\n",
                 scene.c_str(), solvers::ps::MethodName(method), error.mean_deg, error.median_deg, error.pixels_unresolved,
                 usable3);
  }
}

void WriteRealisticHeader(std::ostream& csv) {
  csv << "scene,method,mean_deg,median_deg,pixels_with_truth,unresolved,unresolved_usable3,too_few_lights,"
         "ill_conditioned,rejected_by_model,lambertian_pct,trimmed_pct,irls_pct,blinn_phong_pct,ggx_pct,"
         "low_frequency_pct,mean_confidence,"
         "read_sigma,"
         "shot_gain,noise_estimated,shadow_threshold,saturation_level,solve_ms,lobe_shift_sample_shifted,"
         "lobe_shift_sample_tested\n";
}

void RunRealistic(const fs::path& source, const fs::path& out, const fs::path& scratch) {
  std::ofstream csv(out);
  WriteRealisticHeader(csv);
  const std::string base_recipe = ReadText(source / "config" / "recipes" / "ps-shiny-sphere.yaml");
  const std::string base_rig = ReadText(source / "config" / "rigs" / "sim-dome-96.yaml");
  for (const Effect& effect : kEffects) {
    std::string recipe = base_recipe, rig = base_rig;
    std::string sim_keys;
    if (effect.light_error) sim_keys += "  led_direction_error_deg: 1.0\n  led_intensity_error_pct: 3.0\n";
    if (effect.ambient) sim_keys += "  ambient: {dome_fraction: 0.02}\n";
    if (!sim_keys.empty()) rig = ReplaceFirst(rig, "\nsim:\n", "\nsim:\n" + sim_keys, effect.name);
    if (effect.gamma) rig = ReplaceFirst(rig, "\n  sensor:\n", "\n  sensor:\n    response_gamma: 1.1\n", effect.name);
    // Roughness 0.18 is the Blinn-Phong lobe's width (a^2 = 2 / (e + 2) for e = 60); F0 0.3 keeps the
    // peak near the Blinn-Phong one (0.74 against 0.99 /sr).
    if (effect.ggx_lobe)
      recipe = ReplaceFirst(recipe, "brdf: *\\{[^}]*\\}", "brdf: {model: ggx, roughness: 0.18, f0: 0.3}", effect.name);
    if (effect.metal) {
      recipe = ReplaceFirst(recipe, "brdf: *\\{[^}]*\\}", "brdf: {model: ggx, roughness: 0.3, f0: 0.9}", effect.name);
      recipe = ReplaceFirst(recipe, "albedo: *\\{[^}]*\\}", "albedo: {pattern: checker, low: 0.04, high: 0.08, period_mm: 6}",
                            effect.name);
    }
    const std::string name = std::string("realistic-") + (effect.name[0] == '+' ? effect.name + 1 : effect.name);
    const std::string run = CaptureRun(recipe, rig, name, scratch);
    if (effect.dataset) {
      const fs::path folder = scratch / (name + "-diligent");
      fs::remove_all(folder);
      daemon::ExportDiligent(run, folder.string());
      EvaluateRealistic(csv, effect.name, daemon::LoadDiligent(folder.string()));
    } else {
      EvaluateRealistic(csv, effect.name, daemon::LoadRunStack(run));
    }
  }
}

// The median over the object of the samples above the shadows (dark
// subtracted, more than 10 DN): the level a person at the bench exposes for.
double MedianLitSample(const daemon::PhotometricStereoInput& input) {
  std::vector<float> lit;
  const solvers::ps::PhotometricStack& stack = input.stack;
  for (const cv::Mat& image : stack.images)
    for (int r = 0; r < image.rows; ++r)
      for (int c = 0; c < image.cols; ++c) {
        if (!input.object_mask.empty() && !input.object_mask.at<std::uint8_t>(r, c)) continue;
        if (input.truth_normals.empty() || !std::isfinite(input.truth_normals.at<cv::Vec3f>(r, c)[0])) continue;
        const float signal = image.at<float>(r, c) - (stack.dark.empty() ? 0.0f : stack.dark.at<float>(r, c));
        if (signal > 10.0f) lit.push_back(signal);
      }
  if (lit.empty()) return 0.0;
  auto middle = lit.begin() + static_cast<std::ptrdiff_t>(lit.size() / 2);
  std::nth_element(lit.begin(), middle, lit.end());
  return *middle;
}

// Measured materials on the shiny sphere's shape and dome. A table's diffuse
// level spans two decades between materials (dark felts to white paint), so
// one exposure for all would test the read noise, not the reflectance: each
// is captured at the exposure that puts its median lit sample where the
// shiny sphere's is (at most 64x either way), shortened by 1.5x steps while
// the capture's health check finds a frame overexposed; highlights then clip
// where they exceed the camera's range, as on a real dome. The rim seen
// beyond 80 deg is masked: a table holds least there.
void RunMaterials(const fs::path& source, const fs::path& out, const std::vector<fs::path>& tables,
                  const fs::path& scratch) {
  std::ofstream csv(out);
  WriteRealisticHeader(csv);
  const std::string base_recipe = ReadText(source / "config" / "recipes" / "ps-shiny-sphere.yaml");
  const std::string rig = ReadText(source / "config" / "rigs" / "sim-dome-96.yaml");
  const double reference = MedianLitSample(daemon::LoadRunStack(CaptureRun(base_recipe, rig, "materials-reference", scratch)));
  for (const fs::path& table : tables) try {
    const std::string name = table.stem().string();
    // A recipe names files inside its own folder only.
    const fs::path copy = scratch / ("material" + table.extension().string());
    fs::copy_file(table, copy, fs::copy_options::overwrite_existing);
    const std::string recipe = ReplaceFirst(base_recipe, "brdf: *\\{[^}]*\\}",
                                            "brdf: {model: tabulated, table: " + copy.filename().string() + "}", name);
    const double first = MedianLitSample(daemon::LoadRunStack(CaptureRun(recipe, rig, "material-first", scratch)));
    double factor = first > 0.0 ? std::clamp(reference / first, 1.0 / 64.0, 64.0) : 64.0;
    std::string run;
    // The capture's health check refuses a frame with more than 2 % of its
    // pixels clipped: shorten the exposure, as the bench would.
    for (int attempt = 0; run.empty(); ++attempt) {
      try {
        run = CaptureRun(ScaleExposure(recipe, factor, name), rig, "material", scratch);
      } catch (const std::runtime_error& e) {
        if (attempt == 8 || std::string(e.what()).find("overexposed") == std::string::npos) throw;
        factor /= 1.5;
      }
    }
    std::fprintf(stderr, "%s: exposure x%.3g\n", name.c_str(), factor);
    daemon::PhotometricStereoInput input = daemon::LoadRunStack(run);
    // Measured tables are least reliable at grazing angles (TableSampling's
    // max_theta_deg): the sphere's rim seen beyond 80 deg is left out.
    const double min_view_cosine = std::cos(80.0 * std::numbers::pi / 180.0);
    cv::Mat measured(input.truth_normals.size(), CV_8U);
    for (int r = 0; r < measured.rows; ++r)
      for (int c = 0; c < measured.cols; ++c) {
        const cv::Vec3f n = input.truth_normals.at<cv::Vec3f>(r, c);
        const bool inside = input.object_mask.empty() || input.object_mask.at<std::uint8_t>(r, c);
        const Eigen::Vector3d normal(n[0], n[1], n[2]);
        measured.at<std::uint8_t>(r, c) = inside && normal.dot(input.stack.view_direction) >= min_view_cosine ? 255 : 0;
      }
    input.object_mask = measured;
    EvaluateRealistic(csv, name, input);
    csv.flush();
  } catch (const std::exception& e) {
    throw std::runtime_error(table.string() + ": " + e.what());
  }
}

// The simulated scenes at every light subset and noise level, then the
// DiLiGenT folders given (those with ground truth), into `out`.
void RunScenes(const fs::path& source, const fs::path& out, const std::vector<fs::path>& diligent,
               const fs::path& scratch) {
  std::ofstream csv(out);
  csv << "source,scene,lights,relative_noise,method,mean_deg,median_deg,under_15deg_pct,solve_ms,lambertian_pct,"
         "trimmed_pct,irls_pct,blinn_phong_pct,ggx_pct,low_frequency_pct,lobe_shift_sample_shifted,"
         "lobe_shift_sample_tested\n";
  const fs::path rig = source / "config" / "rigs" / "sim-dome-96.yaml";
  for (const char* scene : {"ps-sphere", "ps-shiny-sphere", "ps-ggx-bumps"}) {
    const fs::path recipe = source / "config" / "recipes" / (std::string(scene) + ".yaml");
    for (double dimming : {1.0, 4.0, 16.0}) {
      const daemon::PhotometricStereoInput input = Capture(recipe, rig, dimming, scratch);
      if (dimming == 1.0) {
        for (int step : {8, 4, 2}) Evaluate(csv, "sim", scene, 1.0, SubsetLights(input, step));
      }
      Evaluate(csv, "sim", scene, std::sqrt(dimming), input);
    }
  }
  for (const fs::path& folder : diligent) {
    const daemon::PhotometricStereoInput input = daemon::LoadDiligent(folder.string());
    if (input.truth_normals.empty()) continue;
    Evaluate(csv, "diligent", folder.filename().string(), 1.0, input);
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3 || (std::string(argv[2]) == "--realistic" && argc != 4) ||
      (std::string(argv[2]) == "--materials" && argc < 5)) {
    std::fprintf(stderr,
                 "usage: %s SOURCE_DIR OUT.csv [DILIGENT_DIR...]\n       %s SOURCE_DIR --realistic OUT.csv\n"
                 "       %s SOURCE_DIR --materials OUT.csv TABLE...\n",
                 argv[0], argv[0], argv[0]);
    return 2;
  }
  spdlog::set_level(spdlog::level::warn);
  const fs::path source(argv[1]);
  const std::string mode = argv[2];
  // One per process: two charts run at once must not remove each other's captures.
  const fs::path scratch = fs::temp_directory_path() / ("photorig-ps-chart-" + std::to_string(::getpid()));
  fs::create_directories(scratch);
  int status = 0;
  try {
    if (mode == "--realistic") {
      RunRealistic(source, argv[3], scratch);
    } else if (mode == "--materials") {
      RunMaterials(source, argv[3], std::vector<fs::path>(argv + 4, argv + argc), scratch);
    } else {
      RunScenes(source, argv[2], std::vector<fs::path>(argv + 3, argv + argc), scratch);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "photorig-ps-chart: %s\n", e.what());
    status = 1;
  }
  fs::remove_all(scratch);
  return status;
}
