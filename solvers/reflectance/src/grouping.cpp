// The statistics the reflectance fit's stages share: k-means, and the
// tests of whether two groups of pixels are one (fit_stages.h).
#include "fit_stages.h"
#include "photorig/solvers/core/normal_quantile.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

namespace photorig::solvers::reflectance::internal {
namespace {

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
  const double z = -core::NormalQuantile(alpha);
  return index >= 1.0 - 2.0 / M_PI - z * 0.35 / std::sqrt(effective_count);
}

}  // namespace

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

double Median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto mid = v.begin() + v.size() / 2;
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// Whether two groups of pixels of one lobe model are one group cut in two:
// each pixel's own weight w_i for the joint lobe (its reduced normal
// equation B_i / A_i, channels pooled) with precision A_i (IsOneGroup).
bool SplitIsChance(const Samples& s, const std::vector<int>& a, const std::vector<int>& b, const MaterialFit& joint,
                   double alpha) {
  auto moments_of = [&](const std::vector<int>& pixels) {
    Moments m;
    for (int p : pixels) {
      const PixelSums sums = SumsOf(s, p, {joint.model, joint.shape}, {});
      double precision = 0.0, score = 0.0;
      for (int ch = 0; ch < s.channels; ++ch) {
        const ChannelSums& cs = sums.c[ch];
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

}  // namespace photorig::solvers::reflectance::internal
