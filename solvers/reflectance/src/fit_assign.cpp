// The reflectance fit's materials for the pixels that did not choose them:
// those that saw no highlight, and the mixed ones.
#include "fit_stages.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace photorig::solvers::reflectance::internal {
namespace {

// The material whose lobe explains pixel p best (its chi-square), with the
// pixel's normal-equation sums under it; -1 when there is none.
int LowestCostMaterial(const Samples& s, int p, const std::vector<MaterialFit>& materials, PixelSums* sums) {
  int best = -1;
  double best_cost = std::numeric_limits<double>::infinity();
  for (std::size_t m = 0; m < materials.size(); ++m) {
    const PixelSums trial = SumsOf(s, p, {materials[m].model, materials[m].shape}, {});
    double cost = 0.0, rho;
    for (int ch = 0; ch < s.channels; ++ch) cost += PixelCost(trial.c[ch], materials[m].specular[ch], &rho);
    if (cost < best_cost) {
      best_cost = cost;
      best = static_cast<int>(m);
      *sums = trial;
    }
  }
  return best;
}

// The colour stacks' half of AssignUnseen.
bool AssignUnseenByColour(const Samples& s, const std::vector<Eigen::Vector2d>& chroma, const std::vector<int>& unseen,
                          double alpha, const std::vector<MaterialFit>& materials,
                          std::vector<std::vector<int>>* groups) {
  // An unseen pixel's own colour (its albedo fitted with a lobe of its own,
  // which it cannot show) keeps whatever tail of its paint's lobe reached
  // it: a glossy paint's pixels beyond every highlight look paler than
  // those that saw one, and would pass for another paint. So an unseen
  // pixel is compared with material m in the colour of its albedo under
  // m's lobe, under[m][p], and so are m's own pixels (one estimator on
  // both sides, or its bias would pass for a second colour).
  const std::size_t materials_count = groups->size();
  std::vector<std::vector<Eigen::Vector2d>> under(materials_count, chroma);
  for (std::size_t m = 0; m < materials_count; ++m) {
    std::vector<int> pixels = (*groups)[m];
    pixels.insert(pixels.end(), unseen.begin(), unseen.end());
#pragma omp parallel for schedule(static)
    for (std::size_t i = 0; i < pixels.size(); ++i) {
      const int p = pixels[i];
      const PixelSums sums = SumsOf(s, p, {materials[m].model, materials[m].shape}, {});
      Eigen::Vector3d rho = Eigen::Vector3d::Zero();
      for (int ch = 0; ch < 3; ++ch) PixelCost(sums.c[ch], materials[m].specular[ch], &rho[ch]);
      const double total = std::max(rho.sum(), 1e-6);
      under[m][p] = {3.0 * rho[0] / total, 3.0 * rho[1] / total};
    }
  }
  std::vector<Eigen::Vector2d> centre;
  for (std::size_t m = 0; m < materials_count; ++m) centre.push_back(MeanChroma(under[m], (*groups)[m]));
  auto nearest = [&](int p) {
    int best = 0;
    for (std::size_t m = 1; m < materials_count; ++m)
      if ((under[m][p] - centre[m]).squaredNorm() < (under[best][p] - centre[best]).squaredNorm())
        best = static_cast<int>(m);
    return best;
  };
  std::vector<int> parent(s.pixels, -1);
  std::vector<std::vector<int>> near(materials_count);
  for (int p : unseen) near[parent[p] = nearest(p)].push_back(p);
  // Per material: its own pixels and the unseen ones nearest it, cut in
  // two colours (2-means); where the cut is real (ColourIsOneGroup) and
  // one side is mostly pixels that saw no highlight, that side's unseen
  // pixels are another paint.
  std::vector<int> apart;
  for (std::size_t m = 0; m < near.size(); ++m) {
    if (near[m].empty()) continue;
    std::vector<int> pixels = (*groups)[m];
    const std::size_t own = pixels.size();
    pixels.insert(pixels.end(), near[m].begin(), near[m].end());
    std::vector<Eigen::VectorXd> x;
    for (int p : pixels) x.push_back(under[m][p]);
    std::vector<int> labels;
    KMeans(x, 2, 4321u + static_cast<unsigned>(m), &labels);
    std::vector<int> side[2];
    int seen_on[2] = {0, 0};
    for (std::size_t i = 0; i < pixels.size(); ++i) {
      side[labels[i]].push_back(pixels[i]);
      seen_on[labels[i]] += i < own;
    }
    if (side[0].empty() || side[1].empty() || ColourIsOneGroup(under[m], side[0], side[1], alpha)) continue;
    const int other = seen_on[0] * side[1].size() < seen_on[1] * side[0].size() ? 0 : 1;
    if (2 * seen_on[other] >= static_cast<int>(side[other].size())) continue;
    for (std::size_t i = own; i < pixels.size(); ++i)
      if (labels[i] == other) apart.push_back(pixels[i]);
  }
  // The new paint's colour: its pixels' under the material they were cut from.
  Eigen::Vector2d apart_centre = Eigen::Vector2d::Zero();
  for (int p : apart) apart_centre += under[parent[p]][p] / static_cast<double>(apart.size());
  if (!apart.empty()) groups->emplace_back();
  for (int p : unseen) {
    const int m = nearest(p);
    const bool to_new = !apart.empty() && (under[parent[p]][p] - apart_centre).squaredNorm() <
                                              (under[m][p] - centre[m]).squaredNorm();
    (*groups)[to_new ? materials_count : m].push_back(p);
  }
  bool formed = !apart.empty();
  if (formed && groups->back().empty()) {
    groups->pop_back();
    formed = false;
  }
  return formed;
}

// The monochrome stacks' half of AssignUnseen.
void AssignUnseenByPosition(const Samples& s, const std::vector<int>& unseen, const std::vector<MaterialFit>& materials,
                            std::vector<std::vector<int>>* groups) {
  std::vector<int> label(static_cast<std::size_t>(s.width) * s.height, -1), gathered(label.size(), -1);
  for (int p = 0; p < s.pixels; ++p) gathered[s.pixel_index[p]] = p;
  std::vector<int> queue;
  for (std::size_t m = 0; m < groups->size(); ++m)
    for (int p : (*groups)[m]) {
      label[s.pixel_index[p]] = static_cast<int>(m);
      queue.push_back(s.pixel_index[p]);
    }
  std::vector<std::uint8_t> waiting(label.size(), 0);
  for (int p : unseen) waiting[s.pixel_index[p]] = 1;
  for (std::size_t head = 0; head < queue.size(); ++head) {
    const int r = queue[head] / s.width, c = queue[head] % s.width;
    for (int dr = -1; dr <= 1; ++dr)
      for (int dc = -1; dc <= 1; ++dc) {
        const int rr = r + dr, cc = c + dc;
        if (rr < 0 || cc < 0 || rr >= s.height || cc >= s.width) continue;
        const int i = rr * s.width + cc;
        if (!waiting[i]) continue;
        waiting[i] = 0;
        label[i] = label[queue[head]];
        (*groups)[label[i]].push_back(gathered[i]);
        queue.push_back(i);
      }
  }
  for (int p : unseen) {
    PixelSums sums;
    if (waiting[s.pixel_index[p]]) (*groups)[LowestCostMaterial(s, p, materials, &sums)].push_back(p);
  }
}

}  // namespace

// Gives each pixel that saw no highlight a material by what it does show.
// Colour stacks: the material of the nearest mean chromaticity; where a
// material's pixels together with the unseen ones nearest it fall into two
// colours (2-means, the cut tested by ColourIsOneGroup) and one side is
// mostly unseen pixels, that side's unseen pixels are a paint whose
// highlights no light reached. Together they become one material of their
// own (appended to *groups, returned true) before every unseen pixel takes
// the nearest colour again. Monochrome
// stacks: nothing but position tells paints apart, so the material of the
// nearest pixel that has one (8-neighbour flood); pixels no flood reaches
// take the material whose lobe explains them best.
bool AssignUnseen(const Samples& s, const std::vector<Eigen::Vector2d>& chroma, const std::vector<int>& unseen,
                  double alpha, const std::vector<MaterialFit>& materials, std::vector<std::vector<int>>* groups) {
  if (unseen.empty() || groups->empty()) return false;
  if (!chroma.empty()) return AssignUnseenByColour(s, chroma, unseen, alpha, materials, groups);
  AssignUnseenByPosition(s, unseen, materials, groups);
  return false;
}

void AssignMixed(const ReflectanceOptions& options, const Samples& s, const std::vector<int>& mixed,
                 FittedPixels* fitted, cv::Mat* flags, ReflectanceMaps* maps, ReflectanceSummary* summary) {
  // Mixed pixels: the material that explains each best, if it explains it as
  // well as the poor-fit test asks of its own pixels; otherwise none. Either
  // way the flag stays: a blend's albedo is not either paint's.
  for (int p : mixed) {
    const int r = s.pixel_index[p] / s.width, c = s.pixel_index[p] % s.width;
    flags->at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(PixelFlag::kMixed);
    ++summary->pixels_mixed;
    PixelSums best_sums;
    const int best_m = LowestCostMaterial(s, p, maps->materials, &best_sums);
    if (best_m < 0) continue;
    double rho[3];
    const double rms = ResidualOf(s, p, best_sums, maps->materials[best_m], rho).rms;
    if (rms > options.poor_fit_ratio * fitted->typical_rms[best_m] && rms > 0.0) continue;
    WritePixel(s, p, best_m, best_sums, maps->materials[best_m], maps, fitted);
    ++summary->pixels_mixed_assigned;
  }
}

}  // namespace photorig::solvers::reflectance::internal
