// The reflectance fit's first stages: which pixels can be fitted, the
// noise model the fit weights by, and which pixels choose the materials.
#include "fit_stages.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace photorig::solvers::reflectance::internal {
namespace {

// Pixels whose colour mixes two paints, or a paint and the background: a
// colour camera's demosaicing fills each pixel's missing channels from its
// neighbourhood, so a pixel next to a paint edge holds a blend of both paints
// (and a blend's lobe is a fraction of the glossy one). Left in, such pixels
// form a material of their own before anything else can reject them: a blend
// is explained well by its own albedo and lobe, and fits no material badly
// until the materials exist. The test is the geometry of a blend: its
// chromaticity lies between those of the pixels on either side of the edge,
// where a pure pixel next to the edge equals the pixels on its own side. For
// each line (a, p, b) through p (four directions; a and b one and two pixels
// away, as the blend is up to two pixels wide), p is mixed when a and b
// differ, p differs from both by more than the chi-square (2 dof) quantile
// at `alpha`, and p projects inside the segment ab. (Not on it: each channel
// is interpolated from different neighbours, so a blend's channels mix in
// different proportions.) Distances are in units of the noise of a
// chromaticity difference, measured on the object (MAD of neighbour
// differences; most neighbours show one paint). A pixel whose 3 x 3 window
// reaches off the object blends in the background: mixed as well.
std::vector<std::uint8_t> MixedPixels(const Samples& s, const std::vector<int>& active,
                                      const std::vector<Eigen::Vector2d>& chroma, double alpha) {
  std::vector<std::uint8_t> mixed(s.pixels, 0);
  if (chroma.empty() || alpha <= 0.0) return mixed;
  std::vector<int> gathered(static_cast<std::size_t>(s.width) * s.height, -1), lit(gathered.size(), -1);
  for (int p = 0; p < s.pixels; ++p) gathered[s.pixel_index[p]] = p;
  for (int p : active) lit[s.pixel_index[p]] = p;
  auto at = [&](const std::vector<int>& grid, int r, int c) {
    return r < 0 || c < 0 || r >= s.height || c >= s.width ? -1 : grid[static_cast<std::size_t>(r) * s.width + c];
  };
  std::vector<double> dx, dy;
  for (int p : active) {
    const int r = s.pixel_index[p] / s.width, c = s.pixel_index[p] % s.width;
    for (const int q : {at(lit, r, c + 1), at(lit, r + 1, c)})
      if (q >= 0) {
        dx.push_back(std::abs(chroma[p].x() - chroma[q].x()));
        dy.push_back(std::abs(chroma[p].y() - chroma[q].y()));
      }
  }
  if (dx.empty()) return mixed;
  const Eigen::Vector2d scale(std::max(1.4826 * Median(dx), 1e-9), std::max(1.4826 * Median(dy), 1e-9));
  const double threshold = -2.0 * std::log(alpha);  // chi-square quantile, 2 dof
  auto d2 = [&](const Eigen::Vector2d& u, const Eigen::Vector2d& v) { return (u - v).cwiseQuotient(scale).squaredNorm(); };
  for (int p : active) {
    const int r = s.pixel_index[p] / s.width, c = s.pixel_index[p] % s.width;
    bool rim = false;
    for (int dr = -1; dr <= 1 && !rim; ++dr)
      for (int dc = -1; dc <= 1 && !rim; ++dc) rim = at(gathered, r + dr, c + dc) < 0;
    if (rim) {
      mixed[p] = 1;
      continue;
    }
    for (int span = 1; span <= 2 && !mixed[p]; ++span)
      for (const auto& [dr, dc] : {std::pair{0, 1}, std::pair{1, 0}, std::pair{1, 1}, std::pair{1, -1}}) {
        const int a = at(lit, r - span * dr, c - span * dc), b = at(lit, r + span * dr, c + span * dc);
        if (a < 0 || b < 0) continue;
        const Eigen::Vector2d pa = (chroma[p] - chroma[a]).cwiseQuotient(scale);
        const Eigen::Vector2d ba = (chroma[b] - chroma[a]).cwiseQuotient(scale);
        if (ba.squaredNorm() <= threshold || d2(chroma[p], chroma[a]) <= threshold ||
            d2(chroma[p], chroma[b]) <= threshold)
          continue;
        const double t = pa.dot(ba) / ba.squaredNorm();
        if (t > 0.0 && t < 1.0) {
          mixed[p] = 1;
          break;
        }
      }
  }
  return mixed;
}

// Per gathered pixel: the smallest angle between its normal and the half
// vector of a usable (lit, unclipped) sample, radians; pi when none.
std::vector<double> SmallestHalfAngles(const Samples& s) {
  std::vector<double> smallest(s.pixels, M_PI);
  for (int p = 0; p < s.pixels; ++p)
    for (int j = 0; j < s.lights; ++j) {
      const std::size_t cell = s.At(p, j);
      if (!s.usable[cell]) continue;
      smallest[p] = std::min(smallest[p], std::acos(std::clamp(s.geometry[cell].cos_h, -1.0, 1.0)));
    }
  return smallest;
}

}  // namespace

std::vector<int> ActivePixels(const Samples& s, int min_samples, cv::Mat* flags) {
  std::vector<int> active;
  for (int p = 0; p < s.pixels; ++p) {
    if (s.usable_count[p] >= min_samples) {
      active.push_back(p);
    } else {
      flags->at<std::uint8_t>(s.pixel_index[p] / s.width, s.pixel_index[p] % s.width) =
          static_cast<std::uint8_t>(PixelFlag::kTooFewSamples);
    }
  }
  return active;
}

void CountUnfitted(const cv::Mat& flags, ReflectanceSummary* summary) {
  for (int i = 0; i < flags.rows * flags.cols; ++i) {
    switch (static_cast<PixelFlag>(flags.at<std::uint8_t>(i))) {
      case PixelFlag::kOutsideMask: ++summary->pixels_outside_mask; break;
      case PixelFlag::kNoNormal: ++summary->pixels_no_normal; break;
      case PixelFlag::kTooFewSamples: ++summary->pixels_too_few_samples; break;
      default: break;
    }
  }
}

OwnLobes WeightByNoise(const SensorNoise& given, const std::vector<int>& active, const core::ProgressCallback& progress,
                       Samples* s, ReflectanceSummary* summary) {
  OwnLobes own;
  own.equal_weights = FitPixelLobes(*s, active, {}, nullptr);
  summary->noise = EstimateNoise(*s, active, own.equal_weights, given, &summary->noise_source);
  WeightSamples(summary->noise, active, own.equal_weights, s);
  own.weighted = FitPixelLobes(*s, active, {}, progress);
  return own;
}

PixelClasses ClassifyPixels(const ReflectanceOptions& options, const Samples& s, const std::vector<int>& active,
                            const OwnLobes& own) {
  PixelClasses classes;
  const int chroma_dims = s.channels == 3 ? 2 : 0;
  classes.chroma.assign(chroma_dims ? s.pixels : 0, Eigen::Vector2d::Zero());
  if (chroma_dims)
    for (std::size_t i = 0; i < active.size(); ++i) {
      const Eigen::Vector3d& rho = own.equal_weights[i].rho;
      const double total = std::max(rho.sum(), 1e-6);
      classes.chroma[active[i]] = {3.0 * rho[0] / total, 3.0 * rho[1] / total};
    }
  // Mixed pixels are flagged before the materials are chosen, so that they
  // cannot form one of their own; they are assigned once the materials exist.
  const std::vector<std::uint8_t> is_mixed = MixedPixels(s, active, classes.chroma, options.mixed_pixel_alpha);
  // Which pixels saw a highlight (ReflectanceOptions::unobserved_half_angle_deg).
  // A pixel that saw none says nothing about any lobe: its own lobe is none
  // whatever its paint's is. Left among the others it would pull a glossy
  // paint's materials towards no lobe, and, a paint all of whose pixels saw
  // none, be absorbed into whichever material its colour sits beside (the
  // split test cannot tell lobes apart on pixels that show none). So only
  // pixels that saw a highlight choose the materials and their lobes; the
  // others are given one afterwards by their colour (AssignUnseen). When no
  // pixel saw one, all choose (and every material is flagged).
  classes.smallest_half_angle = SmallestHalfAngles(s);
  const double seen_within = options.unobserved_half_angle_deg * M_PI / 180.0;
  classes.seen.assign(s.pixels, 0);
  bool any_seen = false;
  for (int p : active) {
    classes.seen[p] = classes.smallest_half_angle[p] <= seen_within;
    any_seen = any_seen || (classes.seen[p] && !is_mixed[p]);
  }
  for (std::size_t i = 0; i < active.size(); ++i) {
    if (is_mixed[active[i]]) {
      classes.mixed.push_back(active[i]);
      continue;
    }
    if (any_seen && !classes.seen[active[i]]) {
      classes.unseen.push_back(active[i]);
      continue;
    }
    // The features for the clustering: chromaticity and the pixel's own lobe.
    const PixelLobe& pl = own.weighted[i];
    Eigen::VectorXd f(chroma_dims + 2);
    if (chroma_dims) f.head<2>() = classes.chroma[active[i]];
    // Bounded: a grazing pixel's own lobe can take any weight, and must not outweigh its colour.
    const double strength = std::min(1.0, std::sqrt(std::max(0.0, pl.weight.head(s.channels).mean())));
    f[chroma_dims] = strength;
    f[chroma_dims + 1] = pl.exponent > 0.0 ? strength * std::log10(pl.exponent) / 2.0 : 0.0;
    classes.clustered.push_back(active[i]);
    classes.features.push_back(f);
  }
  return classes;
}

}  // namespace photorig::solvers::reflectance::internal
