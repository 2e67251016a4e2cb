// The reflectance fit's warnings: where the data cannot support what was
// fitted (ReflectanceSummary::warnings).
#include "fit_stages.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

namespace photorig::solvers::reflectance::internal {
namespace {

// Half width (angle between n and h at half the peak) of a fitted lobe, radians.
double LobeHalfWidth(const MaterialFit& m) {
  const double exponent = m.model == brdf::Model::kGgx ? std::max(1.0, 2.0 / (m.shape * m.shape) - 2.0) : m.shape;
  return std::acos(std::pow(0.5, 1.0 / exponent));
}

}  // namespace

void AddWarning(std::vector<Warning>* list, Warning w) {
  if (std::find(list->begin(), list->end(), w) == list->end()) list->push_back(w);
}

void DescribeLighting(const ReflectanceOptions& options, const Samples& s, const std::vector<int>& group,
                      const PixelClasses& classes, MaterialFit* fit) {
  std::vector<double> min_angle;
  std::set<int> highlight_lights;
  long long saturated = 0, lit = 0;
  const double half_width = fit->model == brdf::Model::kLambertian ? 0.0 : LobeHalfWidth(*fit);
  fit->pixels = static_cast<int>(group.size());
  fit->highlight_pixels = 0;
  for (int p : group) {
    for (int j = 0; j < s.lights; ++j) {
      const std::size_t cell = s.At(p, j);
      saturated += s.saturated[cell];
      lit += s.saturated[cell] + s.usable[cell];
      if (!s.usable[cell] || half_width <= 0.0) continue;
      if (std::acos(std::clamp(s.geometry[cell].cos_h, -1.0, 1.0)) < half_width) highlight_lights.insert(j);
    }
    min_angle.push_back(classes.smallest_half_angle[p]);
    fit->highlight_pixels += classes.seen[p];
  }
  fit->min_half_angle_deg = Median(min_angle) * 180.0 / M_PI;
  fit->highlight_lights = static_cast<int>(highlight_lights.size());
  if (fit->model != brdf::Model::kLambertian && fit->highlight_lights < options.min_highlight_lights)
    AddWarning(&fit->warnings, Warning::kTooFewHighlightLights);
  // Most pixels saw no highlight: whatever lobe (or none) the few that did
  // show, the material's lobe is not measured where it lies.
  if (2 * fit->highlight_pixels < fit->pixels) AddWarning(&fit->warnings, Warning::kHighlightsUnobserved);
  if (lit > 0 && static_cast<double>(saturated) / lit > options.max_saturated_fraction)
    AddWarning(&fit->warnings, Warning::kSaturatedHighlights);
}

void CheckLightIntensities(const ReflectanceOptions& options, const Samples& s, const std::vector<int>& active,
                           const FittedPixels& fitted, const ReflectanceMaps& maps, ReflectanceSummary* summary) {
  const int C = s.channels;
  summary->light_intensity_ratio.assign(s.lights, std::numeric_limits<double>::quiet_NaN());
  for (int j = 0; j < s.lights; ++j) {
    std::vector<double> ratios;
    for (int p : active) {
      const std::size_t cell = s.At(p, j);
      if (!s.usable[cell] || fitted.material_of[p] < 0) continue;
      const MaterialFit& fit = maps.materials[fitted.material_of[p]];
      const int r = s.pixel_index[p] / s.width, c = s.pixel_index[p] % s.width;
      const float* albedo = maps.albedo.ptr<float>(r) + c * C;
      double measured = 0.0, predicted = 0.0, diffuse = 0.0;
      for (int ch = 0; ch < C; ++ch) {
        const double e = s.Irradiance(cell, j, ch);
        measured += s.value[cell * C + ch];
        predicted += Predict(s, cell, {fit.model, fit.shape}, fit.specular[ch], albedo[ch], e);
        diffuse += e * s.geometry[cell].cos_i * albedo[ch] / M_PI;
      }
      if (predicted > 0.0 && diffuse > 0.9 * predicted && predicted > 4.0 * fitted.rms[p])
        ratios.push_back(measured / predicted);
    }
    if (ratios.size() >= 20) summary->light_intensity_ratio[j] = Median(ratios);
    if (std::isfinite(summary->light_intensity_ratio[j]) &&
        std::abs(summary->light_intensity_ratio[j] - 1.0) > options.max_intensity_error)
      summary->inconsistent_lights.push_back(j);
  }
  if (!summary->inconsistent_lights.empty()) AddWarning(&summary->warnings, Warning::kInconsistentIntensities);
}

}  // namespace photorig::solvers::reflectance::internal
