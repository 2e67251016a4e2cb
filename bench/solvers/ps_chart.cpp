// photorig-ps-chart: every photometric-stereo method on the simulated rig's
// scenes, captured on the 96-LED dome (config/rigs/sim-dome-96.yaml) and solved
// with all 96 lights and with every 2nd, 4th and 8th of them (and on DiLiGenT
// folders given as arguments), written as CSV rows
//   source,scene,lights,relative_noise,method,mean_deg,median_deg,under_15deg_pct,solve_ms,lambertian_pct,trimmed_pct,irls_pct,blinn_phong_pct
// for scripts/chart-ps.sh; solve_ms is the fastest of three runs. Captures go
// through the same code as `photorig run`.
//
//   photorig-ps-chart SOURCE_DIR OUT.csv [DILIGENT_DIR...]

#include "photorig/daemon/diligent.h"
#include "photorig/daemon/ps_pipeline.h"
#include "photorig/daemon/run.h"
#include "photorig/ps/evaluation.h"
#include "photorig/ps/photometric_stereo.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <regex>
#include <sstream>

namespace {

namespace fs = std::filesystem;
using namespace photorig;

const ps::Method kMethods[] = {ps::Method::kL2, ps::Method::kLambertian, ps::Method::kRobust, ps::Method::kBlinnPhong,
                               ps::Method::kAuto};

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
  for (ps::Method method : kMethods) {
    daemon::PhotometricStereoRequest request;  // the thresholds `photorig solve ps` uses
    request.method = ps::MethodName(method);
    const ps::PhotometricStereoOptions options = daemon::MakeSolverOptions(request, input.saturation_level);
    ps::PhotometricStack stack = input.stack;
    if (!input.object_mask.empty()) stack.mask = input.object_mask;
    ps::NormalMap map;
    ps::SolverSummary summary;
    // The fastest of three runs: on a shared machine one run can be slowed
    // several-fold by other work; the solves themselves are deterministic.
    double ms = std::numeric_limits<double>::infinity();
    for (int run = 0; run < kRuns; ++run) {
      const auto start = std::chrono::steady_clock::now();
      summary = ps::SolvePhotometricStereo(options, stack, &map);
      ms = std::min(ms, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
    }
    if (!summary.IsSolutionUsable()) {
      spdlog::warn("{} {} {}: {}", scene, stack.light_count(), ps::MethodName(method), summary.message);
      continue;
    }
    const ps::AngularErrorStats error = ps::CompareNormals(map.normals, input.truth_normals, stack.mask);
    const double solved = std::max<std::size_t>(1, summary.pixels_solved);
    csv << source << ',' << scene << ',' << stack.light_count() << ',' << relative_noise << ','
        << ps::MethodName(method) << ',' << error.mean_deg << ',' << error.median_deg << ','
        << 100.0 * error.fraction_under_15deg << ',' << ms << ',' << 100.0 * summary.pixels_lambertian / solved << ','
        << 100.0 * summary.pixels_trimmed / solved << ','
        << 100.0 * summary.pixels_irls / solved << ',' << 100.0 * summary.pixels_blinn_phong / solved << '\n';
    std::fprintf(stderr, "%-16s %2d lights noise x%-4g %-12s mean %7.3f deg  %8.1f ms\n", scene.c_str(),
                 stack.light_count(), relative_noise, ps::MethodName(method), error.mean_deg, ms);
  }
}

// Captures `recipe` on the rig `rig` with its exposure divided by `dimming`
// (shot noise relative to the signal grows as sqrt(dimming); read noise as
// dimming).
daemon::PhotometricStereoInput Capture(const fs::path& recipe, const fs::path& rig, double dimming,
                                       const fs::path& scratch) {
  std::ifstream in(recipe);
  std::stringstream text;
  text << in.rdbuf();
  std::string yaml = text.str();
  std::smatch match;
  const std::regex exposure("exposure_us: *([0-9.]+)");
  if (!std::regex_search(yaml, match, exposure)) throw std::runtime_error(recipe.string() + ": no exposure_us");
  const double exposure_us = std::stod(match[1]) / dimming;
  yaml = std::regex_replace(yaml, exposure, "exposure_us: " + std::to_string(exposure_us), std::regex_constants::format_first_only);
  const std::regex rig_line("rig: *[^\\n]*");
  if (!std::regex_search(yaml, rig_line)) throw std::runtime_error(recipe.string() + ": no rig");
  yaml = std::regex_replace(yaml, rig_line, "rig: " + fs::absolute(rig).string(), std::regex_constants::format_first_only);
  const fs::path modified = scratch / (recipe.stem().string() + ".yaml");
  std::ofstream(modified) << yaml;
  daemon::RunRequest request;
  request.recipe_path = modified.string();
  request.output_directory = (scratch / (recipe.stem().string() + "-" + std::to_string(int(dimming)))).string();
  request.solve = false;
  request.show_progress = false;
  fs::remove_all(request.output_directory);
  const daemon::RunOutcome outcome = daemon::ExecuteRun(request);
  if (outcome.capture.status != "complete") throw std::runtime_error("capture failed: " + outcome.capture.reason);
  return daemon::LoadRunStack(outcome.directory);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s SOURCE_DIR OUT.csv [DILIGENT_DIR...]\n", argv[0]);
    return 2;
  }
  spdlog::set_level(spdlog::level::warn);
  const fs::path source(argv[1]);
  std::ofstream csv(argv[2]);
  csv << "source,scene,lights,relative_noise,method,mean_deg,median_deg,under_15deg_pct,solve_ms,lambertian_pct,"
         "trimmed_pct,irls_pct,blinn_phong_pct\n";
  const fs::path scratch = fs::temp_directory_path() / "photorig-ps-chart";
  fs::create_directories(scratch);
  try {
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
    for (int i = 3; i < argc; ++i) {
      const daemon::PhotometricStereoInput input = daemon::LoadDiligent(argv[i]);
      if (input.truth_normals.empty()) continue;
      Evaluate(csv, "diligent", fs::path(argv[i]).filename().string(), 1.0, input);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "photorig-ps-chart: %s\n", e.what());
    return 1;
  }
  fs::remove_all(scratch);
  return 0;
}
