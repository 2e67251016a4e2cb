#include "photorig/solvers/reflectance/relighting.h"

#include "photorig/solvers/core/names.h"
#include "samples.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace photorig::solvers::reflectance {

namespace {

// RenderReflectance with the view of pixel (r, c) from view_of(r, c).
template <typename ViewOf>
core::Summary Render(const ReflectanceMaps& maps, const Eigen::Vector3d& light_direction, const Eigen::Vector3d& intensity,
                     ViewOf view_of, cv::Mat* image) {
  if (maps.albedo.empty() || maps.flags.size() != maps.albedo.size() || maps.normals.size() != maps.albedo.size())
    return core::Ended(core::Termination::kInvalidInput, "the reflectance maps are empty or differ in size");
  if (image == nullptr) return core::Ended(core::Termination::kInvalidInput, "no output image given");
  const int C = maps.albedo.channels();
  *image = cv::Mat(maps.albedo.size(), CV_32FC(C), cv::Scalar::all(0));
  const Eigen::Vector3d w = light_direction.normalized();
  for (int r = 0; r < image->rows; ++r)
    for (int c = 0; c < image->cols; ++c) {
      const std::uint8_t m = maps.material.at<std::uint8_t>(r, c);
      if (m >= maps.materials.size()) continue;
      const MaterialFit& fit = maps.materials[m];
      const cv::Vec3f nf = maps.normals.at<cv::Vec3f>(r, c);
      const Eigen::Vector3d n = Eigen::Vector3d(nf[0], nf[1], nf[2]).normalized();
      const Eigen::Vector3d wi = internal::ToLocal(n, w), wo = internal::ToLocal(n, view_of(r, c));
      brdf::ModelParams params{fit.model, Eigen::Vector3d::Zero(), fit.specular, fit.shape};
      const float* albedo = maps.albedo.ptr<float>(r) + c * C;
      for (int ch = 0; ch < C; ++ch) params.diffuse[ch] = albedo[ch];
      const Eigen::Vector3d f = brdf::Evaluate(params, wi, wo);
      float* out = image->ptr<float>(r) + c * C;
      for (int ch = 0; ch < C; ++ch) out[ch] = static_cast<float>(intensity[ch] * f[ch] * std::max(0.0, wi.z()));
    }
  return core::Ended(core::Termination::kSuccess, "");
}

}  // namespace

core::Summary RenderReflectance(const ReflectanceMaps& maps, const Eigen::Vector3d& light_direction,
                          const Eigen::Vector3d& intensity, const Eigen::Vector3d& view_direction, cv::Mat* image) {
  const Eigen::Vector3d v = view_direction.normalized();
  return Render(maps, light_direction, intensity, [&](int, int) { return v; }, image);
}

core::Summary RenderReflectance(const ReflectanceMaps& maps, const Eigen::Vector3d& light_direction,
                                const Eigen::Vector3d& intensity, const cv::Mat& views, cv::Mat* image) {
  if (views.type() != CV_32FC3 || views.size() != maps.albedo.size())
    return core::Ended(core::Termination::kInvalidInput, "views must be CV_32FC3 of the maps' size");
  return Render(maps, light_direction, intensity,
                [&](int r, int c) -> Eigen::Vector3d {
                  const cv::Vec3f v = views.at<cv::Vec3f>(r, c);
                  return Eigen::Vector3d(v[0], v[1], v[2]).normalized();
                },
                image);
}

namespace {

constexpr core::NameTable<Method, 3> kMethodNames = {{
    {Method::kLambertian, "lambertian"}, {Method::kPerPixelLobe, "per_pixel_lobe"}, {Method::kPerMaterial, "per_material"},
}};

}  // namespace

const char* MethodName(Method method) { return core::NameOf(kMethodNames, method); }

bool RelightingOptions::IsValid(std::string* why) const {
  if (held_out_lights < 0) return core::Refuse(why, "held_out_lights must be >= 0 (0 = every light)");
  if (methods.empty()) return core::Refuse(why, "methods must name at least one method");
  for (int j : lights)
    if (j < 0) return core::Refuse(why, "a held-out light index is negative: " + std::to_string(j));
  return fit.IsValid(why);
}

std::vector<int> StratifiedLights(const std::vector<Eigen::Vector3d>& directions, int count) {
  const int n = static_cast<int>(directions.size());
  std::vector<int> chosen;
  if (count <= 0 || count >= n) {
    for (int j = 0; j < n; ++j) chosen.push_back(j);
    return chosen;
  }
  // Start with the light nearest the zenith, then keep adding the light farthest from all chosen.
  int first = 0;
  for (int j = 1; j < n; ++j)
    if (directions[j].z() > directions[first].z()) first = j;
  chosen.push_back(first);
  std::vector<double> nearest(n, std::numeric_limits<double>::infinity());
  while (static_cast<int>(chosen.size()) < count) {
    const Eigen::Vector3d& last = directions[chosen.back()];
    int far = -1;
    for (int j = 0; j < n; ++j) {
      nearest[j] = std::min(nearest[j], std::acos(std::clamp(directions[j].dot(last), -1.0, 1.0)));
      if (std::find(chosen.begin(), chosen.end(), j) == chosen.end() && (far < 0 || nearest[j] > nearest[far])) far = j;
    }
    chosen.push_back(far);
  }
  return chosen;
}

namespace {

// Per pixel: the lobe, weights and albedo a method predicts with.
struct Prediction {
  std::vector<internal::Lobe> lobe;
  std::vector<Eigen::Vector3d> weight, rho;
};

// `method` fitted to the lights `enabled` on `pixels` (for kPerMaterial, on
// each material's pixels in `groups` with the full fit's lobe model).
Prediction FitMethod(Method method, const internal::Samples& s, const std::vector<int>& pixels,
                     const std::vector<std::vector<int>>& groups, const ReflectanceMaps& full,
                     const std::vector<std::uint8_t>& enabled, int shape_search_pixels) {
  Prediction out{std::vector<internal::Lobe>(s.pixels),
                 std::vector<Eigen::Vector3d>(s.pixels, Eigen::Vector3d::Zero()),
                 std::vector<Eigen::Vector3d>(s.pixels, Eigen::Vector3d::Zero())};
  if (method == Method::kLambertian) {
    const auto albedo = internal::FitLambertian(s, pixels, enabled);
    for (std::size_t i = 0; i < pixels.size(); ++i) out.rho[pixels[i]] = albedo[i];
  } else if (method == Method::kPerPixelLobe) {
    const auto own = internal::FitPixelLobes(s, pixels, enabled, {});
    for (std::size_t i = 0; i < pixels.size(); ++i) {
      const int p = pixels[i];
      out.lobe[p] = {own[i].exponent > 0.0 ? brdf::Model::kBlinnPhong : brdf::Model::kLambertian, own[i].exponent};
      out.weight[p] = own[i].weight;
      out.rho[p] = own[i].rho;
    }
  } else {
    for (std::size_t m = 0; m < groups.size(); ++m) {
      if (groups[m].empty()) continue;
      const internal::MaterialResult refit =
          internal::FitMaterial(s, groups[m], {full.materials[m].model}, enabled, shape_search_pixels);
      const auto albedo = internal::FitAlbedo(s, groups[m], refit.fit, enabled);
      for (std::size_t i = 0; i < groups[m].size(); ++i) {
        const int p = groups[m][i];
        out.lobe[p] = {refit.fit.model, refit.fit.shape};
        out.weight[p] = refit.fit.specular;
        out.rho[p] = albedo[i];
      }
    }
  }
  return out;
}

// True, ending *summary kInvalidOptions with the reason, when the options fail IsValid.
// Invalid options, or more held-out lights than the stack has (taken as
// given, the count would silently become "every light": one full fit per
// light and method).
bool RefusedOptions(const RelightingOptions& options, const ReflectanceStack& stack, RelightingSummary* summary) {
  std::string why;
  if (!options.IsValid(&why)) {
    summary->End(core::Termination::kInvalidOptions, why);
    return true;
  }
  if (options.lights.empty() && options.held_out_lights > stack.light_count() && stack.light_count() > 0) {
    summary->End(core::Termination::kInvalidOptions,
                 "held_out_lights " + std::to_string(options.held_out_lights) + " exceeds the stack's " +
                     std::to_string(stack.light_count()) + " lights (0 holds out every light)");
    return true;
  }
  return false;
}

}  // namespace

RelightingSummary EvaluateHeldOutLights(const RelightingOptions& options, const ReflectanceStack& stack,
                                        const cv::Mat& normals, const cv::Mat& mask) {
  // Before the fit on every light, which invalid options would waste.
  if (RelightingSummary refused; RefusedOptions(options, stack, &refused)) return refused;
  // Materials and their lobes chosen once, on every light.
  ReflectanceMaps full;
  const ReflectanceSummary fitted = FitReflectance(options.fit, stack, normals, mask, &full);
  if (!fitted.IsSolutionUsable()) {
    RelightingSummary summary;
    summary.End(fitted.termination, fitted.message);
    return summary;
  }
  return EvaluateHeldOutLights(options, stack, normals, mask, full, fitted);
}

RelightingSummary EvaluateHeldOutLights(const RelightingOptions& options, const ReflectanceStack& stack,
                                        const cv::Mat& normals, const cv::Mat& mask, const ReflectanceMaps& full,
                                        const ReflectanceSummary& fitted) {
  core::SolveTimer timer;
  RelightingSummary summary;
  if (RefusedOptions(options, stack, &summary)) return summary;
  if (!fitted.IsSolutionUsable() || full.material.size() != cv::Size(stack.width(), stack.height()) ||
      static_cast<int>(full.materials.size()) != fitted.materials) {
    summary.End(core::Termination::kInvalidInput, "the full fit is not a usable fit of this stack");
    return summary;
  }
  if (stack.light_count() < options.fit.min_samples + 1) {
    summary.End(core::Termination::kFailure, "too few lights to hold one out");
    return summary;
  }
  summary.materials = fitted.materials;
  cv::Mat flags;
  long long saturated = 0;
  internal::Samples s = internal::Gather(stack, normals, mask, options.fit.min_cosine, &flags, &saturated);
  // Pixels the full fit resolved, grouped by material.
  std::vector<int> pixels;
  std::vector<std::vector<int>> groups(full.materials.size());
  for (int p = 0; p < s.pixels; ++p) {
    const int r = s.pixel_index[p] / s.width, c = s.pixel_index[p] % s.width;
    if (full.flags.at<std::uint8_t>(r, c) != static_cast<std::uint8_t>(PixelFlag::kFitted)) continue;
    pixels.push_back(p);
    groups[full.material.at<std::uint8_t>(r, c)].push_back(p);
  }
  // Every method weights the samples by the noise model of the full fit, at
  // the signal each pixel's own lobe predicts (as FitReflectance does).
  internal::WeightSamples(fitted.noise, pixels, internal::FitPixelLobes(s, pixels, {}, nullptr), &s);
  summary.held_out = options.lights.empty() ? StratifiedLights(stack.light_directions, options.held_out_lights)
                                            : options.lights;
  for (int j : summary.held_out)
    if (j >= stack.light_count()) {
      summary.End(core::Termination::kInvalidOptions, "held-out light " + std::to_string(j) + " is not one of the stack's " +
                                                    std::to_string(stack.light_count()) + " lights");
      return summary;
    }
  timer.SetupDone(&summary);
  std::vector<int> material_of(s.pixels, -1);
  for (std::size_t m = 0; m < groups.size(); ++m)
    for (int p : groups[m]) material_of[p] = static_cast<int>(m);
  std::vector<std::array<double, 3>> material_sum(groups.size(), {0.0, 0.0, 0.0});
  std::vector<long long> material_count(groups.size(), 0);
  core::ProgressThrottle throttle(options.progress, "held-out",
                            static_cast<std::int64_t>(summary.held_out.size() * options.methods.size()));
  const int C = s.channels;
  int done = 0;
  for (int j : summary.held_out) {
    std::vector<std::uint8_t> enabled(s.lights, 1);
    enabled[j] = 0;
    // Values of the held-out light that the sensor measured (not clipped), and the peak for PSNR.
    std::vector<double> measured_values;
    for (int p : pixels)
      if (!s.saturated[s.At(p, j)])
        for (int ch = 0; ch < C; ++ch) measured_values.push_back(s.value[s.At(p, j) * C + ch]);
    double peak = 1.0;
    if (!measured_values.empty()) {
      auto it = measured_values.begin() + static_cast<std::ptrdiff_t>(0.999 * (measured_values.size() - 1));
      std::nth_element(measured_values.begin(), it, measured_values.end());
      peak = std::max(*it, 1e-12);
    }
    for (Method method : options.methods) {
      core::SolveTimer fit_timer;
      const Prediction prediction =
          FitMethod(method, s, pixels, groups, full, enabled, options.fit.shape_search_pixels);
      const std::vector<internal::Lobe>& lobe = prediction.lobe;
      const std::vector<Eigen::Vector3d>& weight = prediction.weight;
      const std::vector<Eigen::Vector3d>& rho = prediction.rho;
      const double fit_ms = fit_timer.ElapsedMs();
      cv::Mat image;
      if (options.keep_predictions)
        image = cv::Mat(s.height, s.width, CV_32FC(C), cv::Scalar::all(std::numeric_limits<float>::quiet_NaN()));
      double sum = 0.0;
      long long count = 0;
      for (int p : pixels) {
        const std::size_t cell = s.At(p, j);
        for (int ch = 0; ch < C && !image.empty(); ++ch)
          image.ptr<float>()[static_cast<std::size_t>(s.pixel_index[p]) * C + ch] = static_cast<float>(
              internal::Predict(s, cell, lobe[p], weight[p][ch], rho[p][ch], s.Irradiance(cell, j, ch)));
        if (s.saturated[cell]) continue;
        for (int ch = 0; ch < C; ++ch) {
          const double predicted =
              internal::Predict(s, cell, lobe[p], weight[p][ch], rho[p][ch], s.Irradiance(cell, j, ch));
          const double d = predicted - s.value[cell * C + ch];
          sum += d * d;
          ++count;
          material_sum[material_of[p]][static_cast<int>(method)] += d * d;
          if (method == options.methods.front()) ++material_count[material_of[p]];
        }
      }
      HeldOutError error;
      error.light = j;
      error.method = method;
      error.rmse = count > 0 ? std::sqrt(sum / count) : 0.0;
      error.psnr_db = error.rmse > 0.0 ? 20.0 * std::log10(peak / error.rmse) : 99.0;
      error.fit_ms = fit_ms;
      summary.errors.push_back(error);
      if (!image.empty()) summary.predictions.push_back({j, method, image});
      const int mi = static_cast<int>(method);
      summary.mean_rmse[mi] += error.rmse / summary.held_out.size();
      summary.mean_psnr_db[mi] += error.psnr_db / summary.held_out.size();
      summary.mean_fit_ms[mi] += fit_ms / summary.held_out.size();
      throttle.Update(++done);
    }
  }
  throttle.Finish();
  for (std::size_t m = 0; m < groups.size(); ++m) {
    std::array<double, 3> rmse{0.0, 0.0, 0.0};
    for (int mi = 0; mi < 3; ++mi)
      rmse[mi] = material_count[m] > 0 ? std::sqrt(material_sum[m][mi] / static_cast<double>(material_count[m])) : 0.0;
    summary.material_rmse.push_back(rmse);
  }
  summary.termination = core::Termination::kSuccess;
  summary.message = fitted.message;
  timer.Finish(&summary);
  return summary;
}

}  // namespace photorig::solvers::reflectance
