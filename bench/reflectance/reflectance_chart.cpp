// Writes the CSV behind docs/charts/reflectance_error_vs_time.png: for the
// simulated three-material colour scene at several sizes, each method's
// held-out relighting RMSE and fit time (EvaluateHeldOutLights, 4 stratified
// lights), and the per-material fit's reflectance errors against truth. Two
// more rows per size: the per-material fit on normals tilted 2 degrees (as
// photometric stereo's might be), and the same after the joint refinement of
// normals and reflectance, with their normals' error.
// Usage: photorig-reflectance-chart OUT.csv
#include "photorig/solvers/reflectance/normal_refinement.h"
#include "svbrdf_scene.h"

#include <algorithm>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

using namespace photorig::testing;

// Reflectance errors of a per-material fit against the scene's truth, as
// CSV text: the median relative albedo error, and the largest lobe-parameter
// error (1 where a lobe's model is wrong).
std::pair<std::string, std::string> ReflectanceErrors(const SvbrdfScene& scene, const refl::ReflectanceMaps& fit) {
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
  return {std::to_string(albedo[albedo.size() / 2]), std::to_string(lobe)};
}

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
  std::fprintf(out, "size,pixels,method,fit_ms,heldout_rmse,albedo_error,lobe_error,materials,normal_error_deg\n");
  for (int size : {24, 32, 48, 64}) {
    SceneSpec spec = ThreeMaterials();
    spec.size = size;
    const SvbrdfScene scene = MakeScene(spec);
    refl::RelightingOptions options;
    options.held_out_lights = 4;
    const auto relit = refl::EvaluateHeldOutLights(options, scene.stack, scene.truth.normals, scene.mask);
    refl::ReflectanceMaps fit;
    const auto summary = refl::FitReflectance({}, scene.stack, scene.truth.normals, scene.mask, &fit);
    for (int method = 0; method < 3; ++method) {
      const bool material = method == static_cast<int>(refl::Method::kPerMaterial);
      std::fprintf(out, "%d,%d,%s,%.3f,%.6g,%s,%s,%d,0\n", size, cv::countNonZero(scene.mask),
                   refl::MethodName(static_cast<refl::Method>(method)),
                   material ? summary.total_ms : relit.mean_fit_ms[method], relit.mean_rmse[method],
                   material ? ReflectanceErrors(scene, fit).first.c_str() : "",
                   material ? ReflectanceErrors(scene, fit).second.c_str() : "", material ? summary.materials : 0);
    }
    // Tilted normals, then refined.
    const cv::Mat tilted = TiltedNormals(scene, 2.0, 17);
    refl::ReflectanceMaps on_tilted;
    const auto tilted_summary = refl::FitReflectance({}, scene.stack, tilted, scene.mask, &on_tilted);
    const auto tilted_relit = refl::EvaluateHeldOutLights(options, scene.stack, tilted, scene.mask, on_tilted, tilted_summary);
    const auto [tilted_albedo, tilted_lobe] = ReflectanceErrors(scene, on_tilted);
    std::fprintf(out, "%d,%d,per_material_tilted_normals,%.3f,%.6g,%s,%s,%d,%.4f\n", size,
                 cv::countNonZero(scene.mask), tilted_summary.total_ms,
                 tilted_relit.mean_rmse[static_cast<int>(refl::Method::kPerMaterial)], tilted_albedo.c_str(),
                 tilted_lobe.c_str(), tilted_summary.materials, MeanNormalErrorDeg(scene, tilted));
    refl::NormalRefinementOptions refine;
    cv::Mat refined;
    refl::ReflectanceMaps on_refined;
    const auto refined_summary = refl::RefineNormalsAndReflectance(refine, scene.stack, tilted, scene.mask, &refined, &on_refined);
    const auto refined_relit =
        refl::EvaluateHeldOutLights(options, scene.stack, refined, scene.mask, on_refined, refined_summary.reflectance);
    const auto [refined_albedo, refined_lobe] = ReflectanceErrors(scene, on_refined);
    std::fprintf(out, "%d,%d,per_material_refined_normals,%.3f,%.6g,%s,%s,%d,%.4f\n", size,
                 cv::countNonZero(scene.mask), refined_summary.total_ms,
                 refined_relit.mean_rmse[static_cast<int>(refl::Method::kPerMaterial)], refined_albedo.c_str(),
                 refined_lobe.c_str(), refined_summary.reflectance.materials, MeanNormalErrorDeg(scene, refined));
    std::fprintf(stderr, "size %d done\n", size);
  }
  std::fclose(out);
  return 0;
}
