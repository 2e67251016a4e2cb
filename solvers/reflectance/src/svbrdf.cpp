#include "photorig/solvers/reflectance/fit.h"

#include "samples.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <set>

namespace photorig::solvers::reflectance {

using internal::Lobe;
using internal::Samples;

double SensorNoise::Variance(int channel, double signal) const {
  const double positive = std::max(signal, 0.0);
  return read_sigma[channel] * read_sigma[channel] + shot_gain[channel] * positive +
         relative[channel] * relative[channel] * positive * positive;
}

Eigen::Vector3d ReflectanceStack::Intensity(int light) const {
  return light_intensities.empty() ? Eigen::Vector3d::Ones() : light_intensities[light];
}

bool ReflectanceStack::IsValid(std::string* why) const {
  auto fail = [&](std::string text) {
    if (why) *why = std::move(text);
    return false;
  };
  if (images.size() < 3) return fail("the stack needs at least 3 images, has " + std::to_string(images.size()));
  if (light_directions.size() != images.size())
    return fail(std::to_string(images.size()) + " images but " + std::to_string(light_directions.size()) +
                " light directions");
  if (!light_intensities.empty() && light_intensities.size() != images.size())
    return fail(std::to_string(images.size()) + " images but " + std::to_string(light_intensities.size()) +
                " light intensities");
  for (std::size_t j = 0; j < images.size(); ++j) {
    const cv::Mat& m = images[j];
    if (m.type() != CV_32FC1 && m.type() != CV_32FC3)
      return fail("image " + std::to_string(j) + " is not CV_32FC1 or CV_32FC3");
    if (m.size() != images.front().size() || m.type() != images.front().type())
      return fail("image " + std::to_string(j) + " differs in size or channels from image 0");
    if (!m.isContinuous()) return fail("image " + std::to_string(j) + " is not continuous");
    if (std::abs(light_directions[j].norm() - 1.0) > 1e-3)
      return fail("light direction " + std::to_string(j) + " is not a unit vector");
    if (!light_intensities.empty() && !(light_intensities[j].minCoeff() > 0.0))
      return fail("light intensity " + std::to_string(j) + " is not positive");
  }
  if (std::abs(view_direction.norm() - 1.0) > 1e-3) return fail("the view direction is not a unit vector");
  if (!(noise.read_sigma.minCoeff() >= 0.0 && noise.shot_gain.minCoeff() >= 0.0 && noise.relative.minCoeff() >= 0.0) ||
      !noise.read_sigma.allFinite() || !noise.shot_gain.allFinite() || !noise.relative.allFinite())
    return fail("the noise model's terms must be finite and >= 0");
  return true;
}

const char* PixelFlagName(PixelFlag flag) {
  switch (flag) {
    case PixelFlag::kFitted: return "fitted";
    case PixelFlag::kOutsideMask: return "outside-mask";
    case PixelFlag::kNoNormal: return "no-normal";
    case PixelFlag::kTooFewSamples: return "too-few-samples";
    case PixelFlag::kPoorFit: return "poor-fit";
    case PixelFlag::kMixed: return "mixed";
  }
  return "?";
}

const char* WarningName(Warning warning) {
  switch (warning) {
    case Warning::kTooFewHighlightLights: return "too-few-highlight-lights";
    case Warning::kHighlightsUnobserved: return "highlights-unobserved";
    case Warning::kSaturatedHighlights: return "saturated-highlights";
    case Warning::kInconsistentIntensities: return "inconsistent-intensities";
  }
  return "?";
}

bool ReflectanceOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& text) {
    if (why) *why = text;
    return false;
  };
  if (max_materials < 1 || max_materials > 16) return fail("max_materials must be in [1, 16]");
  for (brdf::Model m : lobes) {
    if (m == brdf::Model::kLambertian) return fail("lobes lists specular lobes only (no lobe is always a candidate)");
    if (m != brdf::Model::kBlinnPhong && m != brdf::Model::kGgx)
      return fail(std::string("lobes may hold blinn_phong and ggx; ") + brdf::ModelName(m) +
                  " is fitted to whole tables (photorig brdf fit), not per material");
  }
  if (!(min_cosine >= 0.0 && min_cosine < 1.0)) return fail("min_cosine must be in [0, 1)");
  if (min_samples < 3) return fail("min_samples must be at least 3");
  if (!(poor_fit_ratio > 1.0)) return fail("poor_fit_ratio must exceed 1");
  if (!(mixed_pixel_alpha >= 0.0 && mixed_pixel_alpha < 1.0)) return fail("mixed_pixel_alpha must be in [0, 1)");
  if (!(split_alpha > 0.0 && split_alpha < 0.5)) return fail("split_alpha must be in (0, 0.5)");
  if (shape_search_pixels < 10) return fail("shape_search_pixels must be at least 10");
  if (kmeans_restarts < 1) return fail("kmeans_restarts must be at least 1");
  if (min_highlight_lights < 1) return fail("min_highlight_lights must be at least 1");
  if (!(unobserved_half_angle_deg > 0.0 && unobserved_half_angle_deg < 90.0))
    return fail("unobserved_half_angle_deg must be in (0, 90)");
  if (!(max_saturated_fraction >= 0.0 && max_saturated_fraction <= 1.0))
    return fail("max_saturated_fraction must be in [0, 1]");
  if (!(max_intensity_error > 0.0)) return fail("max_intensity_error must be positive");
  return true;
}

namespace internal {

std::vector<PixelLobe> FitPixelLobes(const Samples& s, const std::vector<int>& pixels,
                                     const std::vector<std::uint8_t>& enabled, const ProgressCallback& progress) {
  const std::vector<double>& grid = ShapeGrid(brdf::Model::kBlinnPhong);
  std::vector<PixelLobe> out(pixels.size());
  const int count = static_cast<int>(pixels.size());
  ProgressThrottle throttle(progress, "per-pixel", count);
  const int block = 256;
  for (int start = 0; start < count; start += block) {
    const int end = std::min(count, start + block);
#pragma omp parallel for schedule(dynamic, 16)
    for (int i = start; i < end; ++i) {
      const int p = pixels[i];
      // No lobe first: a lobe must lower the cost to be kept.
      const PixelSums flat = SumsOf(s, p, {brdf::Model::kLambertian, 0.0}, enabled);
      double best = 0.0;
      PixelLobe result;
      for (int ch = 0; ch < s.channels; ++ch) best += PixelCost(flat.c[ch], 0.0, &result.rho[ch]);
      // A lobe is kept only where it lowers the pixel's BIC by a wide margin
      // (three times the usual penalty, the best of the grid's shapes being
      // picked): otherwise the pixel's noise would pass for a lobe, and
      // materials grouped by these lobes would select that noise.
      const double n = std::max(1, flat.samples * s.channels);
      const double lobe_penalty = 3.0 * (s.channels + 1) * std::log(n);
      double best_bic = n * std::log(std::max(best, 1e-300) / n);
      for (double e : grid) {
        const PixelSums sums = SumsOf(s, p, {brdf::Model::kBlinnPhong, e}, enabled);
        PixelLobe trial;
        trial.exponent = e;
        double cost = 0.0;
        for (int ch = 0; ch < s.channels; ++ch) {
          const ChannelSums& cs = sums.c[ch];
          const double reduced = cs.uu > 0.0 ? cs.hh - cs.uh * cs.uh / cs.uu : 0.0;
          // A lobe the samples barely separate from the diffuse term (reduced
          // coefficient a vanishing part of the lobe's own) has no weight to
          // speak of; and its albedo at normal incidence cannot exceed 1.
          const double w = reduced > 1e-9 * cs.hh && reduced > 0.0
                               ? std::clamp((cs.hy - cs.uh * cs.uy / cs.uu) / reduced, 0.0, 1.0)
                               : 0.0;
          trial.weight[ch] = w;
          cost += PixelCost(cs, w, &trial.rho[ch]);
        }
        const double bic = n * std::log(std::max(cost, 1e-300) / n) + lobe_penalty;
        if (bic < best_bic) {
          best_bic = bic;
          result = trial;
        }
      }
      out[i] = result;
    }
    throttle.Update(end);
  }
  throttle.Finish();
  return out;
}

std::vector<Eigen::Vector3d> FitLambertian(const Samples& s, const std::vector<int>& pixels,
                                           const std::vector<std::uint8_t>& enabled) {
  MaterialFit none;
  return FitAlbedo(s, pixels, none, enabled);
}

std::vector<Eigen::Vector3d> FitAlbedo(const Samples& s, const std::vector<int>& pixels, const MaterialFit& material,
                                       const std::vector<std::uint8_t>& enabled) {
  std::vector<Eigen::Vector3d> rho(pixels.size(), Eigen::Vector3d::Zero());
  const int count = static_cast<int>(pixels.size());
  const Lobe lobe{material.model, material.shape};
#pragma omp parallel for schedule(static)
  for (int i = 0; i < count; ++i) {
    const PixelSums sums = SumsOf(s, pixels[i], lobe, enabled);
    for (int ch = 0; ch < s.channels; ++ch) PixelCost(sums.c[ch], material.specular[ch], &rho[i][ch]);
  }
  return rho;
}

}  // namespace internal

namespace {

// Lloyd's k-means with k-means++ seeding; returns labels and the inertia.
double KMeans(const std::vector<Eigen::VectorXd>& x, int k, unsigned seed, std::vector<int>* labels) {
  const int n = static_cast<int>(x.size());
  std::mt19937 rng(seed);
  std::vector<Eigen::VectorXd> centres;
  centres.push_back(x[std::uniform_int_distribution<int>(0, n - 1)(rng)]);
  std::vector<double> d2(n);
  while (static_cast<int>(centres.size()) < k) {
    double total = 0.0;
    for (int i = 0; i < n; ++i) {
      double best = std::numeric_limits<double>::infinity();
      for (const auto& c : centres) best = std::min(best, (x[i] - c).squaredNorm());
      d2[i] = best;
      total += best;
    }
    if (total <= 0.0) break;
    double pick = std::uniform_real_distribution<double>(0.0, total)(rng);
    int chosen = n - 1;
    for (int i = 0; i < n; ++i) {
      pick -= d2[i];
      if (pick <= 0.0) {
        chosen = i;
        break;
      }
    }
    centres.push_back(x[chosen]);
  }
  labels->assign(n, 0);
  double inertia = 0.0;
  for (int it = 0; it < 50; ++it) {
    bool changed = false;
    inertia = 0.0;
    for (int i = 0; i < n; ++i) {
      int best = 0;
      double best_d = std::numeric_limits<double>::infinity();
      for (std::size_t c = 0; c < centres.size(); ++c) {
        const double d = (x[i] - centres[c]).squaredNorm();
        if (d < best_d) {
          best_d = d;
          best = static_cast<int>(c);
        }
      }
      changed = changed || (*labels)[i] != best;
      (*labels)[i] = best;
      inertia += best_d;
    }
    if (!changed && it > 0) break;
    std::vector<Eigen::VectorXd> sums(centres.size(), Eigen::VectorXd::Zero(x[0].size()));
    std::vector<int> counts(centres.size(), 0);
    for (int i = 0; i < n; ++i) {
      sums[(*labels)[i]] += x[i];
      ++counts[(*labels)[i]];
    }
    for (std::size_t c = 0; c < centres.size(); ++c)
      if (counts[c] > 0) centres[c] = sums[c] / counts[c];
  }
  return inertia;
}

// Groups the indices (into `active`) by label, dropping empty groups.
std::vector<std::vector<int>> Groups(const std::vector<int>& active, const std::vector<int>& labels, int k) {
  std::vector<std::vector<int>> groups(k);
  for (std::size_t i = 0; i < active.size(); ++i) groups[labels[i]].push_back(active[i]);
  groups.erase(std::remove_if(groups.begin(), groups.end(), [](const auto& g) { return g.empty(); }), groups.end());
  return groups;
}

struct Partition {
  std::vector<std::vector<int>> groups;  // pixel indices (into Samples) per material
  std::vector<internal::MaterialResult> materials;
  double bic = std::numeric_limits<double>::infinity();
};

// chi^2 + parameters ln(samples) of a set of materials (the costs are chi-square values).
double PooledBic(const std::vector<internal::MaterialResult>& materials, int channels) {
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
      const internal::PixelSums sums = internal::SumsOf(s, pixels[i], {fit.model, fit.shape}, {});
      double c = 0.0, rho;
      for (int ch = 0; ch < s.channels; ++ch) c += internal::PixelCost(sums.c[ch], fit.specular[ch], &rho);
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

bool SplitIsChance(const Samples& s, const std::vector<int>& a, const std::vector<int>& b, const MaterialFit& joint,
                   double alpha);

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
  for (const auto& g : part->groups) part->materials.push_back(internal::FitMaterial(s, g, candidates, {}, search_pixels));
  part->bic = PooledBic(part->materials, s.channels);
}

double Median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto mid = v.begin() + v.size() / 2;
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

void AddWarning(std::vector<Warning>* list, Warning w) {
  if (std::find(list->begin(), list->end(), w) == list->end()) list->push_back(w);
}

// Half width (angle between n and h at half the peak) of a fitted lobe, radians.
double LobeHalfWidth(const MaterialFit& m) {
  const double exponent = m.model == brdf::Model::kGgx ? std::max(1.0, 2.0 / (m.shape * m.shape) - 2.0) : m.shape;
  return std::acos(std::pow(0.5, 1.0 / exponent));
}

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

// The standard normal's quantile p (bisection on the CDF; called a few times a fit).
double NormalQuantile(double p) {
  double lo = -40.0, hi = 40.0;
  for (int it = 0; it < 200; ++it) {
    const double mid = 0.5 * (lo + hi);
    (0.5 * std::erfc(-mid / std::sqrt(2.0)) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// Weighted moments of one group of values (a pixel's lobe weight, or its
// colour along one axis) with their precisions.
struct Moments {
  double weight = 0.0, sum = 0.0, squares = 0.0, weight_squared = 0.0;
  void Add(double value, double precision) {
    weight += precision;
    sum += precision * value;
    squares += precision * value * value;
    weight_squared += precision * precision;
  }
  void Add(const Moments& m) {
    weight += m.weight;
    sum += m.sum;
    squares += m.squares;
    weight_squared += m.weight_squared;
  }
  double Spread() const { return weight > 0.0 ? squares - sum * sum / weight : 0.0; }
};

// Whether two groups of values are one group cut in two. The split's
// cluster index, the within-group over the total weighted sum of squares,
// is compared with its value when one Gaussian spread is cut at its best
// point: 1 - 2/pi, with a standard deviation of about 0.35 / sqrt(n) for n
// values (simulated; n the effective count (sum A)^2 / sum A^2 of the
// precisions A). Two groups that are really two lie below by more than the
// one-sided normal quantile at `alpha` (SigClust, Liu, Hayes, Nobel and
// Marron 2008, in one dimension). A given cut has an index at least the
// best cut's, so the test errs towards one group.
bool IsOneGroup(const Moments& a, const Moments& b, double alpha) {
  Moments all = a;
  all.Add(b);
  const double total = all.Spread();
  if (!(total > 0.0) || !(all.weight_squared > 0.0)) return true;
  const double index = (a.Spread() + b.Spread()) / total;
  const double effective_count = all.weight * all.weight / all.weight_squared;
  const double z = -NormalQuantile(alpha);
  return index >= 1.0 - 2.0 / M_PI - z * 0.35 / std::sqrt(effective_count);
}

// Whether two groups of pixels of one lobe model are one group cut in two:
// each pixel's own weight w_i for the joint lobe (its reduced normal
// equation B_i / A_i, channels pooled) with precision A_i (IsOneGroup).
bool SplitIsChance(const Samples& s, const std::vector<int>& a, const std::vector<int>& b, const MaterialFit& joint,
                   double alpha) {
  auto moments_of = [&](const std::vector<int>& pixels) {
    Moments m;
    for (int p : pixels) {
      const internal::PixelSums sums = internal::SumsOf(s, p, {joint.model, joint.shape}, {});
      double precision = 0.0, score = 0.0;
      for (int ch = 0; ch < s.channels; ++ch) {
        const internal::ChannelSums& cs = sums.c[ch];
        if (cs.uu <= 0.0) continue;
        precision += cs.hh - cs.uh * cs.uh / cs.uu;
        score += cs.hy - cs.uh * cs.uy / cs.uu;
      }
      if (precision > 0.0) m.Add(score / precision, precision);
    }
    return m;
  };
  return IsOneGroup(moments_of(a), moments_of(b), alpha);
}

Eigen::Vector2d MeanChroma(const std::vector<Eigen::Vector2d>& chroma, const std::vector<int>& pixels) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (int p : pixels) mean += chroma[p];
  return pixels.empty() ? mean : Eigen::Vector2d(mean / static_cast<double>(pixels.size()));
}

// Whether two groups of pixels have one colour: their chromaticities along
// the line through the two groups' means, equally weighted (IsOneGroup).
bool ColourIsOneGroup(const std::vector<Eigen::Vector2d>& chroma, const std::vector<int>& a, const std::vector<int>& b,
                      double alpha) {
  const Eigen::Vector2d axis = MeanChroma(chroma, b) - MeanChroma(chroma, a);
  if (!(axis.norm() > 0.0)) return true;
  const Eigen::Vector2d unit = axis.normalized();
  Moments ma, mb;
  for (int p : a) ma.Add(chroma[p].dot(unit), 1.0);
  for (int p : b) mb.Add(chroma[p].dot(unit), 1.0);
  return IsOneGroup(ma, mb, alpha);
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

// The material whose lobe explains pixel p best (its chi-square), with the
// pixel's normal-equation sums under it; -1 when there is none.
int LowestCostMaterial(const Samples& s, int p, const std::vector<MaterialFit>& materials, internal::PixelSums* sums) {
  int best = -1;
  double best_cost = std::numeric_limits<double>::infinity();
  for (std::size_t m = 0; m < materials.size(); ++m) {
    const internal::PixelSums trial = internal::SumsOf(s, p, {materials[m].model, materials[m].shape}, {});
    double cost = 0.0, rho;
    for (int ch = 0; ch < s.channels; ++ch) cost += internal::PixelCost(trial.c[ch], materials[m].specular[ch], &rho);
    if (cost < best_cost) {
      best_cost = cost;
      best = static_cast<int>(m);
      *sums = trial;
    }
  }
  return best;
}

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
  bool formed = false;
  if (!chroma.empty()) {
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
        const internal::PixelSums sums = internal::SumsOf(s, p, {materials[m].model, materials[m].shape}, {});
        Eigen::Vector3d rho = Eigen::Vector3d::Zero();
        for (int ch = 0; ch < 3; ++ch) internal::PixelCost(sums.c[ch], materials[m].specular[ch], &rho[ch]);
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
    formed = !apart.empty();
    if (formed && groups->back().empty()) {
      groups->pop_back();
      formed = false;
    }
    return formed;
  }
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
    internal::PixelSums sums;
    if (waiting[s.pixel_index[p]]) (*groups)[LowestCostMaterial(s, p, materials, &sums)].push_back(p);
  }
  return false;
}

}  // namespace

ReflectanceSummary FitReflectance(const ReflectanceOptions& options, const ReflectanceStack& stack,
                                  const cv::Mat& normals, const cv::Mat& mask, ReflectanceMaps* maps) {
  SolveTimer timer;
  ReflectanceSummary summary;
  std::string why;
  if (!options.IsValid(&why)) {
    summary.End(Termination::kInvalidOptions, why);
    return summary;
  }
  if (!stack.IsValid(&why)) {
    summary.End(Termination::kInvalidInput, why);
    return summary;
  }
  if (normals.type() != CV_32FC3 || normals.size() != stack.images.front().size()) {
    summary.End(Termination::kInvalidInput, "normals must be CV_32FC3 of the stack's size");
    return summary;
  }
  if (!mask.empty() && (mask.type() != CV_8U || mask.size() != normals.size())) {
    summary.End(Termination::kInvalidInput, "mask must be CV_8U of the stack's size");
    return summary;
  }
  if (maps == nullptr) {
    summary.End(Termination::kInvalidInput, "no output maps given");
    return summary;
  }
  cv::Mat flags;
  Samples s = internal::Gather(stack, normals, mask, options.min_cosine, &flags, &summary.saturated_samples);
  std::vector<int> active;
  for (int p = 0; p < s.pixels; ++p) {
    if (s.usable_count[p] >= options.min_samples) {
      active.push_back(p);
    } else {
      flags.at<std::uint8_t>(s.pixel_index[p] / s.width, s.pixel_index[p] % s.width) =
          static_cast<std::uint8_t>(PixelFlag::kTooFewSamples);
    }
  }
  for (int i = 0; i < flags.rows * flags.cols; ++i) {
    switch (static_cast<PixelFlag>(flags.at<std::uint8_t>(i))) {
      case PixelFlag::kOutsideMask: ++summary.pixels_outside_mask; break;
      case PixelFlag::kNoNormal: ++summary.pixels_no_normal; break;
      case PixelFlag::kTooFewSamples: ++summary.pixels_too_few_samples; break;
      default: break;
    }
  }
  if (active.empty()) {
    summary.End(Termination::kFailure, "no pixel has a normal and " + std::to_string(options.min_samples) +
                                           " lit, unsaturated samples; check the mask, the normals and the exposure");
    return summary;
  }
  timer.SetupDone(&summary);

  // The noise model (given, or estimated from each pixel's own lobe fitted
  // with equal weights), then every sample weighted by it and the own lobes
  // refitted: the features for the clustering are chromaticity and these lobes.
  const std::vector<internal::PixelLobe> equal_weights = internal::FitPixelLobes(s, active, {}, nullptr);
  summary.noise = internal::EstimateNoise(s, active, equal_weights, stack.noise, &summary.noise_source);
  internal::WeightSamples(summary.noise, active, equal_weights, &s);
  const std::vector<internal::PixelLobe> own = internal::FitPixelLobes(s, active, {}, options.progress);
  const int chroma_dims = s.channels == 3 ? 2 : 0;
  std::vector<Eigen::Vector2d> chroma(chroma_dims ? s.pixels : 0, Eigen::Vector2d::Zero());
  if (chroma_dims)
    for (std::size_t i = 0; i < active.size(); ++i) {
      const double total = std::max(equal_weights[i].rho.sum(), 1e-6);
      chroma[active[i]] = {3.0 * equal_weights[i].rho[0] / total, 3.0 * equal_weights[i].rho[1] / total};
    }
  // Mixed pixels are flagged before the materials are chosen, so that they
  // cannot form one of their own; they are assigned once the materials exist.
  const std::vector<std::uint8_t> is_mixed = MixedPixels(s, active, chroma, options.mixed_pixel_alpha);
  // Which pixels saw a highlight (ReflectanceOptions::unobserved_half_angle_deg).
  // A pixel that saw none says nothing about any lobe: its own lobe is none
  // whatever its paint's is. Left among the others it would pull a glossy
  // paint's materials towards no lobe, and, a paint all of whose pixels saw
  // none, be absorbed into whichever material its colour sits beside (the
  // split test cannot tell lobes apart on pixels that show none). So only
  // pixels that saw a highlight choose the materials and their lobes; the
  // others are given one afterwards by their colour (AssignUnseen). When no
  // pixel saw one, all choose (and every material is flagged).
  const std::vector<double> smallest_half_angle = SmallestHalfAngles(s);
  const double seen_within = options.unobserved_half_angle_deg * M_PI / 180.0;
  std::vector<std::uint8_t> seen(s.pixels, 0);
  bool any_seen = false;
  for (int p : active) {
    seen[p] = smallest_half_angle[p] <= seen_within;
    any_seen = any_seen || (seen[p] && !is_mixed[p]);
  }
  std::vector<int> clustered, mixed, unseen;
  std::vector<Eigen::VectorXd> features;
  for (std::size_t i = 0; i < active.size(); ++i) {
    if (is_mixed[active[i]]) {
      mixed.push_back(active[i]);
      continue;
    }
    if (any_seen && !seen[active[i]]) {
      unseen.push_back(active[i]);
      continue;
    }
    const internal::PixelLobe& pl = own[i];
    Eigen::VectorXd f(chroma_dims + 2);
    if (chroma_dims) f.head<2>() = chroma[active[i]];
    // Bounded: a grazing pixel's own lobe can take any weight, and must not outweigh its colour.
    const double strength = std::min(1.0, std::sqrt(std::max(0.0, pl.weight.head(s.channels).mean())));
    f[chroma_dims] = strength;
    f[chroma_dims + 1] = pl.exponent > 0.0 ? strength * std::log10(pl.exponent) / 2.0 : 0.0;
    clustered.push_back(active[i]);
    features.push_back(f);
  }
  if (clustered.empty()) {
    summary.End(Termination::kFailure, "every pixel mixes two colours or the background (" +
                                           std::to_string(mixed.size()) + " mixed pixels); no material can be chosen");
    return summary;
  }

  std::vector<brdf::Model> candidates{brdf::Model::kLambertian};
  candidates.insert(candidates.end(), options.lobes.begin(), options.lobes.end());
  Partition best;
  const int max_k = std::min<int>(options.max_materials, static_cast<int>(clustered.size()));
  for (int k = 1; k <= max_k; ++k) {
    ProgressThrottle throttle(options.progress, "materials", max_k);
    throttle.Update(k - 1);
    std::vector<int> labels, best_labels;
    double best_inertia = std::numeric_limits<double>::infinity();
    for (int r = 0; r < options.kmeans_restarts; ++r) {
      const double inertia = KMeans(features, k, 1234u + 17u * r + 101u * k, &labels);
      if (inertia < best_inertia) {
        best_inertia = inertia;
        best_labels = labels;
      }
    }
    Partition part;
    part.groups = Groups(clustered, best_labels, k);
    FitPartition(s, candidates, options.shape_search_pixels, &part);
    // A clustering that cuts one material in two says the data hold fewer
    // than k materials; larger k only cut further, so the search ends.
    if (k > 1 && CutsOneMaterial(s, part, options.split_alpha)) break;
    for (int it = 0; it < 4 && part.groups.size() > 1; ++it) {
      if (!Reassign(s, chroma, &part)) break;
      FitPartition(s, candidates, options.shape_search_pixels, &part);
    }
    summary.bic_by_materials.push_back(part.bic);
    if (part.bic < best.bic) best = std::move(part);
    if (k == max_k) throttle.Finish();
  }

  // Materials the clustering split but one paint explains are merged (the
  // albedo is per pixel anyway). Comparing the two fits by chi^2 or by their
  // parameters' errors cannot tell: the pixels were sorted into the two by
  // those very fits, and cutting any spread of pixels in two yields two
  // "significantly" different means. So the test is whether the pixels'
  // own lobe weights form two groups at all (SplitIndex).
  for (bool merged = true; merged && best.groups.size() > 1;) {
    merged = false;
    for (std::size_t a = 0; a < best.groups.size() && !merged; ++a)
      for (std::size_t b = a + 1; b < best.groups.size() && !merged; ++b) {
        if (best.materials[a].fit.model != best.materials[b].fit.model) continue;
        std::vector<int> joint = best.groups[a];
        joint.insert(joint.end(), best.groups[b].begin(), best.groups[b].end());
        internal::MaterialResult fit = internal::FitMaterial(s, joint, candidates, {}, options.shape_search_pixels);
        if (fit.fit.model != brdf::Model::kLambertian &&
            !SplitIsChance(s, best.groups[a], best.groups[b], fit.fit, options.split_alpha))
          continue;
        best.groups[a] = std::move(joint);
        best.groups.erase(best.groups.begin() + static_cast<std::ptrdiff_t>(b));
        best.materials.erase(best.materials.begin() + static_cast<std::ptrdiff_t>(b));
        best.materials[a] = std::move(fit);
        ++summary.materials_merged;
        merged = true;
      }
  }
  if (AssignUnseen(s, chroma, unseen, options.split_alpha,
                   [&] {
                     std::vector<MaterialFit> fits;
                     for (const auto& m : best.materials) fits.push_back(m.fit);
                     return fits;
                   }(),
                   &best.groups)) {
    // A paint no pixel of which saw a highlight: its lobe is what its own
    // pixels show (mostly none), never a neighbouring paint's.
    best.materials.push_back(internal::FitMaterial(s, best.groups.back(), candidates, {}, options.shape_search_pixels));
    ++summary.materials_unobserved;
  }

  // Final albedos, their deviations and residuals per pixel.
  const int C = s.channels;
  maps->albedo = cv::Mat(s.height, s.width, CV_32FC(C), cv::Scalar::all(std::numeric_limits<float>::quiet_NaN()));
  maps->albedo_sigma = maps->albedo.clone();
  maps->material = cv::Mat(s.height, s.width, CV_8U, cv::Scalar(255));
  maps->rms_residual = cv::Mat(s.height, s.width, CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  maps->normals = normals.clone();
  maps->materials.clear();
  ProgressThrottle albedo_progress(options.progress, "albedo", static_cast<std::int64_t>(best.groups.size()));
  std::vector<int> material_of(s.pixels, -1);
  std::vector<double> pixel_rms(s.pixels, 0.0);
  // Pixel p's RMS residual in image units under a material (what the
  // poor-fit test compares: a residual the model leaves, in the units the
  // relit images are judged in) and its chi-square.
  struct PixelResidual {
    double rms = 0.0, squared_sum = 0.0, chi_square = 0.0;
    long long count = 0;
  };
  auto residual_of = [&](int p, const internal::PixelSums& sums, const MaterialFit& fit, double* rho) {
    PixelResidual out;
    for (int ch = 0; ch < C; ++ch) out.chi_square += internal::PixelCost(sums.c[ch], fit.specular[ch], &rho[ch]);
    for (int j = 0; j < s.lights; ++j) {
      const std::size_t cell = s.At(p, j);
      if (!s.usable[cell]) continue;
      for (int ch = 0; ch < C; ++ch) {
        const double d = s.value[cell * C + ch] -
                         internal::Predict(s, cell, {fit.model, fit.shape}, fit.specular[ch], rho[ch], s.intensity[j][ch]);
        out.squared_sum += d * d;
        ++out.count;
      }
    }
    out.rms = std::sqrt(out.squared_sum / std::max<long long>(1, out.count));
    return out;
  };
  // Writes pixel p's albedo, its deviation, residual and material.
  auto write_pixel = [&](int p, int m, const internal::PixelSums& sums, const MaterialFit& fit) {
    const int r = s.pixel_index[p] / s.width, c = s.pixel_index[p] % s.width;
    float* albedo = maps->albedo.ptr<float>(r) + c * C;
    float* sigma = maps->albedo_sigma.ptr<float>(r) + c * C;
    double rho[3] = {0.0, 0.0, 0.0};
    const PixelResidual out = residual_of(p, sums, fit, rho);
    for (int ch = 0; ch < C; ++ch) {
      albedo[ch] = static_cast<float>(rho[ch]);
      // Weighted least squares, scaled by the pixel's own chi^2 per dof (one dof per channel used by rho).
      double unused;
      const double channel_cost = internal::PixelCost(sums.c[ch], fit.specular[ch], &unused);
      const double dof = std::max(1, sums.samples - 1);
      sigma[ch] = static_cast<float>(std::sqrt(channel_cost / dof / std::max(sums.c[ch].uu, 1e-300)));
    }
    pixel_rms[p] = out.rms;
    maps->rms_residual.at<float>(r, c) = static_cast<float>(out.rms);
    maps->material.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(m);
    return out;
  };
  double chi_square = 0.0;
  long long residuals = 0;
  std::vector<double> typical_rms(best.groups.size(), 0.0);
  for (std::size_t m = 0; m < best.groups.size(); ++m) {
    MaterialFit fit = best.materials[m].fit;
    const std::vector<int>& group = best.groups[m];
    std::vector<internal::PixelSums> sums;
    internal::FitGroup(s, group, {fit.model, fit.shape}, {}, &sums);
    std::vector<double> rms(group.size());
    double squared_sum = 0.0;
    long long count = 0;
    for (std::size_t i = 0; i < group.size(); ++i) {
      const int p = group[i];
      material_of[p] = static_cast<int>(m);
      const PixelResidual residual = write_pixel(p, static_cast<int>(m), sums[i], fit);
      rms[i] = residual.rms;
      squared_sum += residual.squared_sum;
      count += residual.count;
      chi_square += residual.chi_square;
      residuals += residual.count;
    }
    fit.rms_residual = std::sqrt(squared_sum / std::max<long long>(1, count));
    // Poor fits: far above the material's typical residual.
    const double typical = Median(rms);
    typical_rms[m] = typical;
    for (std::size_t i = 0; i < group.size(); ++i)
      if (rms[i] > options.poor_fit_ratio * typical && rms[i] > 0.0) {
        const int p = group[i];
        flags.at<std::uint8_t>(s.pixel_index[p] / s.width, s.pixel_index[p] % s.width) =
            static_cast<std::uint8_t>(PixelFlag::kPoorFit);
        ++summary.pixels_poor_fit;
      }

    // What the lights could show of this material.
    std::vector<double> min_angle;
    std::set<int> highlight_lights;
    long long saturated = 0, lit = 0;
    const double half_width = fit.model == brdf::Model::kLambertian ? 0.0 : LobeHalfWidth(fit);
    fit.pixels = static_cast<int>(group.size());
    fit.highlight_pixels = 0;
    for (int p : group) {
      for (int j = 0; j < s.lights; ++j) {
        const std::size_t cell = s.At(p, j);
        saturated += s.saturated[cell];
        lit += s.saturated[cell] + s.usable[cell];
        if (!s.usable[cell] || half_width <= 0.0) continue;
        if (std::acos(std::clamp(s.geometry[cell].cos_h, -1.0, 1.0)) < half_width) highlight_lights.insert(j);
      }
      min_angle.push_back(smallest_half_angle[p]);
      fit.highlight_pixels += seen[p];
    }
    fit.min_half_angle_deg = Median(min_angle) * 180.0 / M_PI;
    fit.highlight_lights = static_cast<int>(highlight_lights.size());
    if (fit.model != brdf::Model::kLambertian && fit.highlight_lights < options.min_highlight_lights)
      AddWarning(&fit.warnings, Warning::kTooFewHighlightLights);
    // Most pixels saw no highlight: whatever lobe (or none) the few that did
    // show, the material's lobe is not measured where it lies.
    if (2 * fit.highlight_pixels < fit.pixels) AddWarning(&fit.warnings, Warning::kHighlightsUnobserved);
    if (lit > 0 && static_cast<double>(saturated) / lit > options.max_saturated_fraction)
      AddWarning(&fit.warnings, Warning::kSaturatedHighlights);
    for (Warning w : fit.warnings) AddWarning(&summary.warnings, w);
    maps->materials.push_back(fit);
    albedo_progress.Update(static_cast<std::int64_t>(m + 1));
  }
  albedo_progress.Finish();

  // Mixed pixels: the material that explains each best, if it explains it as
  // well as the poor-fit test asks of its own pixels; otherwise none. Either
  // way the flag stays: a blend's albedo is not either paint's.
  for (int p : mixed) {
    const int r = s.pixel_index[p] / s.width, c = s.pixel_index[p] % s.width;
    flags.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(PixelFlag::kMixed);
    ++summary.pixels_mixed;
    internal::PixelSums best_sums;
    const int best_m = LowestCostMaterial(s, p, maps->materials, &best_sums);
    if (best_m < 0) continue;
    double rho[3];
    const double rms = residual_of(p, best_sums, maps->materials[best_m], rho).rms;
    if (rms > options.poor_fit_ratio * typical_rms[best_m] && rms > 0.0) continue;
    write_pixel(p, best_m, best_sums, maps->materials[best_m]);
    ++summary.pixels_mixed_assigned;
  }

  // Per light: measured over predicted where the diffuse term dominates.
  summary.light_intensity_ratio.assign(s.lights, std::numeric_limits<double>::quiet_NaN());
  for (int j = 0; j < s.lights; ++j) {
    std::vector<double> ratios;
    for (int p : active) {
      const std::size_t cell = s.At(p, j);
      if (!s.usable[cell] || material_of[p] < 0) continue;
      const MaterialFit& fit = maps->materials[material_of[p]];
      const int r = s.pixel_index[p] / s.width, c = s.pixel_index[p] % s.width;
      const float* albedo = maps->albedo.ptr<float>(r) + c * C;
      double measured = 0.0, predicted = 0.0, diffuse = 0.0;
      for (int ch = 0; ch < C; ++ch) {
        const double e = s.intensity[j][ch];
        measured += s.value[cell * C + ch];
        predicted += internal::Predict(s, cell, {fit.model, fit.shape}, fit.specular[ch], albedo[ch], e);
        diffuse += e * s.geometry[cell].cos_i * albedo[ch] / M_PI;
      }
      if (predicted > 0.0 && diffuse > 0.9 * predicted && predicted > 4.0 * pixel_rms[p]) ratios.push_back(measured / predicted);
    }
    if (ratios.size() >= 20) summary.light_intensity_ratio[j] = Median(ratios);
    if (std::isfinite(summary.light_intensity_ratio[j]) &&
        std::abs(summary.light_intensity_ratio[j] - 1.0) > options.max_intensity_error)
      summary.inconsistent_lights.push_back(j);
  }
  if (!summary.inconsistent_lights.empty()) AddWarning(&summary.warnings, Warning::kInconsistentIntensities);

  maps->flags = flags;
  maps->highlight_seen = cv::Mat(s.height, s.width, CV_8U, cv::Scalar(255));
  for (int p : active) {
    if (maps->material.at<std::uint8_t>(s.pixel_index[p]) == 255) continue;
    maps->highlight_seen.at<std::uint8_t>(s.pixel_index[p]) = seen[p];
    summary.pixels_highlight_unseen += !seen[p];
  }
  summary.reduced_chi_square = residuals > 0 ? chi_square / static_cast<double>(residuals) : 0.0;
  summary.materials = static_cast<int>(maps->materials.size());
  summary.pixels_fitted = static_cast<int>(active.size()) - summary.pixels_poor_fit - summary.pixels_mixed;
  summary.termination = Termination::kSuccess;
  if (!summary.warnings.empty()) {
    summary.message = "warnings:";
    for (Warning w : summary.warnings) summary.message += std::string(" ") + WarningName(w);
  }
  timer.Finish(&summary);
  return summary;
}

}  // namespace photorig::solvers::reflectance
