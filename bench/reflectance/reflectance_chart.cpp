// Writes the CSV behind docs/charts/reflectance_error_vs_time.png: for the
// simulated three-material colour scene at several sizes, each method's
// held-out relighting RMSE and fit time (EvaluateHeldOutLights, 4 stratified
// lights), and the per-material fit's reflectance errors against truth.
// Usage: photorig-reflectance-chart OUT.csv
#include "svbrdf_scene.h"

#include <cstdio>

using namespace photorig::testing;

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUT.csv\n", argv[0]);
    return 2;
  }
  std::FILE* out = std::fopen(argv[1], "w");
  if (!out) {
    std::perror(argv[1]);
    return 2;
  }
  std::fprintf(out, "size,pixels,method,fit_ms,heldout_rmse,albedo_error,lobe_error,materials\n");
  for (int size : {24, 32, 48, 64}) {
    SceneSpec spec = ThreeMaterials();
    spec.size = size;
    const SvbrdfScene scene = MakeScene(spec);
    refl::RelightingOptions options;
    options.held_out_lights = 4;
    const auto relit = refl::EvaluateHeldOutLights(options, scene.stack, scene.truth.normals, scene.mask);
    refl::ReflectanceMaps fit;
    const auto summary = refl::FitReflectance({}, scene.stack, scene.truth.normals, scene.mask, &fit);
    // Reflectance errors of the per-material fit: median relative albedo error, largest lobe-parameter error.
    std::vector<double> albedo;
    for (int i = 0; i < static_cast<int>(fit.flags.total()); ++i) {
      if (fit.flags.at<std::uint8_t>(i) != 0) continue;
      for (int ch = 0; ch < 3; ++ch) {
        const double t = scene.truth.albedo.ptr<float>()[3 * i + ch], f = fit.albedo.ptr<float>()[3 * i + ch];
        albedo.push_back(std::abs(f - t) / t);
      }
    }
    std::nth_element(albedo.begin(), albedo.begin() + albedo.size() / 2, albedo.end());
    double lobe = 0.0;
    for (std::size_t m = 0; m < scene.truth.materials.size(); ++m) {
      const auto& t = scene.truth.materials[m];
      if (t.model == brdf::Model::kLambertian) continue;
      // The fitted material holding most of the band's pixels.
      std::vector<int> votes(fit.materials.size(), 0);
      for (int i = 0; i < static_cast<int>(fit.material.total()); ++i)
        if (scene.truth.material.at<std::uint8_t>(i) == m && fit.material.at<std::uint8_t>(i) < fit.materials.size())
          ++votes[fit.material.at<std::uint8_t>(i)];
      const auto& f = fit.materials[std::max_element(votes.begin(), votes.end()) - votes.begin()];
      if (f.model != t.model) {
        lobe = std::max(lobe, 1.0);
        continue;
      }
      lobe = std::max(lobe, std::abs(f.shape / t.shape - 1.0));
      for (int ch = 0; ch < 3; ++ch) lobe = std::max(lobe, std::abs(f.specular[ch] / t.specular[ch] - 1.0));
    }
    for (int method = 0; method < 3; ++method) {
      const bool material = method == static_cast<int>(refl::Method::kPerMaterial);
      std::fprintf(out, "%d,%d,%s,%.3f,%.6g,%s,%s,%d\n", size, cv::countNonZero(scene.mask),
                   refl::MethodName(static_cast<refl::Method>(method)),
                   material ? summary.total_ms : relit.mean_fit_ms[method], relit.mean_rmse[method],
                   material ? std::to_string(albedo[albedo.size() / 2]).c_str() : "",
                   material ? std::to_string(lobe).c_str() : "", material ? summary.materials : 0);
    }
    std::fprintf(stderr, "size %d done\n", size);
  }
  std::fclose(out);
  return 0;
}
