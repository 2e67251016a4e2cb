// The reflectance fit's choice of materials: k-means clusters of the
// pixels that saw a highlight, each k scored by the BIC of the fit it leads
// to, then the materials that are one paint cut in two merged.
#include "fit_stages.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace photorig::solvers::reflectance::internal {
namespace {

// Groups the indices (into `active`) by label, dropping empty groups.
std::vector<std::vector<int>> Groups(const std::vector<int>& active, const std::vector<int>& labels, int k) {
  std::vector<std::vector<int>> groups(k);
  for (std::size_t i = 0; i < active.size(); ++i) groups[labels[i]].push_back(active[i]);
  groups.erase(std::remove_if(groups.begin(), groups.end(), [](const auto& g) { return g.empty(); }), groups.end());
  return groups;
}

// chi^2 + parameters ln(samples) of a set of materials (the costs are chi-square values).
double PooledBic(const std::vector<MaterialResult>& materials, int channels) {
  double chi_square = 0.0;
  long long n = 0;
  int parameters = 0;
  for (const auto& m : materials) {
    chi_square += m.cost;
    n += m.residuals;
    // The material's label and lobe choice count as one parameter; a lobe adds its weights and shape.
    parameters += 1 + (m.fit.model == brdf::Model::kLambertian ? 0 : channels + 1);
  }
  return chi_square + parameters * std::log(static_cast<double>(std::max<long long>(n, 1)));
}

// Each pixel to the material whose lobe explains it best; returns whether any moved.
bool Reassign(const Samples& s, const std::vector<Eigen::Vector2d>& chroma, Partition* part) {
  std::vector<int> pixels;
  for (const auto& g : part->groups) pixels.insert(pixels.end(), g.begin(), g.end());
  const int count = static_cast<int>(pixels.size());
  const int k = static_cast<int>(part->materials.size());
  std::vector<double> cost(static_cast<std::size_t>(count) * k);
  std::vector<int> previous(s.pixels, -1);
  for (int m = 0; m < k; ++m)
    for (int p : part->groups[m]) previous[p] = m;
  for (int m = 0; m < k; ++m) {
    const MaterialFit& fit = part->materials[m].fit;
#pragma omp parallel for schedule(static)
    for (int i = 0; i < count; ++i) {
      const PixelSums sums = SumsOf(s, pixels[i], {fit.model, fit.shape}, {});
      double c = 0.0, rho;
      for (int ch = 0; ch < s.channels; ++ch) c += PixelCost(sums.c[ch], fit.specular[ch], &rho);
      cost[static_cast<std::size_t>(i) * k + m] = c;
    }
  }
  // Mean chromaticity per material: what decides between materials whose lobes explain a pixel equally.
  std::vector<Eigen::Vector2d> centre(k, Eigen::Vector2d::Zero());
  if (!chroma.empty())
    for (int m = 0; m < k; ++m) {
      for (int p : part->groups[m]) centre[m] += chroma[p];
      centre[m] /= static_cast<double>(part->groups[m].size());
    }
  std::vector<std::vector<int>> groups(k);
  bool moved = false;
  for (int i = 0; i < count; ++i) {
    const double* c = &cost[static_cast<std::size_t>(i) * k];
    const int argmin = static_cast<int>(std::min_element(c, c + k) - c);
    int best = previous[pixels[i]];
    if (c[argmin] < 0.98 * c[best]) {
      best = argmin;
    } else if (!chroma.empty()) {
      // No lobe tells the materials apart here (no highlight seen): the nearest colour among the near-equal costs.
      double nearest = std::numeric_limits<double>::infinity();
      for (int m = 0; m < k; ++m) {
        const double d = (chroma[pixels[i]] - centre[m]).squaredNorm();
        if (c[m] <= c[argmin] / 0.98 && d < nearest) {
          nearest = d;
          best = m;
        }
      }
    }
    moved = moved || best != previous[pixels[i]];
    groups[best].push_back(pixels[i]);
  }
  groups.erase(std::remove_if(groups.begin(), groups.end(), [](const auto& g) { return g.empty(); }), groups.end());
  part->groups = std::move(groups);
  return moved;
}

// Whether two of the partition's materials of one lobe model are one cut in
// two (two without a lobe always are), judged at the first one's lobe.
bool CutsOneMaterial(const Samples& s, const Partition& part, double alpha) {
  for (std::size_t a = 0; a < part.groups.size(); ++a)
    for (std::size_t b = a + 1; b < part.groups.size(); ++b) {
      const MaterialFit& fa = part.materials[a].fit;
      if (fa.model != part.materials[b].fit.model) continue;
      if (fa.model == brdf::Model::kLambertian || SplitIsChance(s, part.groups[a], part.groups[b], fa, alpha)) return true;
    }
  return false;
}

void FitPartition(const Samples& s, const std::vector<brdf::Model>& candidates, int search_pixels, Partition* part) {
  part->materials.clear();
  for (const auto& g : part->groups) part->materials.push_back(FitMaterial(s, g, candidates, {}, search_pixels));
  part->bic = PooledBic(part->materials, s.channels);
}

}  // namespace

Partition ChooseMaterials(const ReflectanceOptions& options, const Samples& s, const PixelClasses& classes,
                          const std::vector<brdf::Model>& candidates, std::vector<double>* bic_by_materials) {
  Partition best;
  const int max_k = std::min<int>(options.max_materials, static_cast<int>(classes.clustered.size()));
  for (int k = 1; k <= max_k; ++k) {
    core::ProgressThrottle throttle(options.progress, "materials", max_k);
    throttle.Update(k - 1);
    std::vector<int> labels, best_labels;
    double best_inertia = std::numeric_limits<double>::infinity();
    for (int r = 0; r < options.kmeans_restarts; ++r) {
      const double inertia = KMeans(classes.features, k, 1234u + 17u * r + 101u * k, &labels);
      if (inertia < best_inertia) {
        best_inertia = inertia;
        best_labels = labels;
      }
    }
    Partition part;
    part.groups = Groups(classes.clustered, best_labels, k);
    FitPartition(s, candidates, options.shape_search_pixels, &part);
    // A clustering that cuts one material in two says the data hold fewer
    // than k materials; larger k only cut further, so the search ends.
    if (k > 1 && CutsOneMaterial(s, part, options.split_alpha)) break;
    for (int it = 0; it < 4 && part.groups.size() > 1; ++it) {
      if (!Reassign(s, classes.chroma, &part)) break;
      FitPartition(s, candidates, options.shape_search_pixels, &part);
    }
    bic_by_materials->push_back(part.bic);
    if (part.bic < best.bic) best = std::move(part);
    if (k == max_k) throttle.Finish();
  }
  return best;
}

int MergeOnePaintSplits(const ReflectanceOptions& options, const Samples& s, const std::vector<brdf::Model>& candidates,
                        Partition* best) {
  // Materials the clustering split but one paint explains are merged (the
  // albedo is per pixel anyway). Comparing the two fits by chi^2 or by their
  // parameters' errors cannot tell: the pixels were sorted into the two by
  // those very fits, and cutting any spread of pixels in two yields two
  // "significantly" different means. So the test is whether the pixels'
  // own lobe weights form two groups at all (SplitIsChance).
  int merges = 0;
  for (bool merged = true; merged && best->groups.size() > 1;) {
    merged = false;
    for (std::size_t a = 0; a < best->groups.size() && !merged; ++a)
      for (std::size_t b = a + 1; b < best->groups.size() && !merged; ++b) {
        if (best->materials[a].fit.model != best->materials[b].fit.model) continue;
        std::vector<int> joint = best->groups[a];
        joint.insert(joint.end(), best->groups[b].begin(), best->groups[b].end());
        MaterialResult fit = FitMaterial(s, joint, candidates, {}, options.shape_search_pixels);
        if (fit.fit.model != brdf::Model::kLambertian &&
            !SplitIsChance(s, best->groups[a], best->groups[b], fit.fit, options.split_alpha))
          continue;
        best->groups[a] = std::move(joint);
        best->groups.erase(best->groups.begin() + static_cast<std::ptrdiff_t>(b));
        best->materials.erase(best->materials.begin() + static_cast<std::ptrdiff_t>(b));
        best->materials[a] = std::move(fit);
        ++merges;
        merged = true;
      }
  }
  return merges;
}

}  // namespace photorig::solvers::reflectance::internal
