#include "samples.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace photorig::solvers::reflectance::internal {

void FrameOf(const Eigen::Vector3d& n, Eigen::Vector3d* t, Eigen::Vector3d* b) {
  const Eigen::Vector3d a = std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  *t = a.cross(n).normalized();
  *b = n.cross(*t);
}

namespace {

std::vector<double> LogGrid(double lo, double hi, int count) {
  std::vector<double> grid(count);
  for (int i = 0; i < count; ++i) grid[i] = lo * std::pow(hi / lo, static_cast<double>(i) / (count - 1));
  return grid;
}

}  // namespace

Eigen::Vector3d ToLocal(const Eigen::Vector3d& n, const Eigen::Vector3d& w) {
  Eigen::Vector3d t, b;
  FrameOf(n, &t, &b);
  return {t.dot(w), b.dot(w), n.dot(w)};
}

PixelLights::PixelLights(const ReflectanceStack& stack) : stack_(stack) {
  for (const camera::NearLight& light : stack.near_lights) near_.emplace_back(light);
}

double PixelLights::At(int index, int j, Eigen::Vector3d* towards) const {
  if (near_.empty()) {
    *towards = stack_.light_directions[j];
    return 1.0;
  }
  const cv::Vec3f point = stack_.points_mm.ptr<cv::Vec3f>()[index];
  return near_[j].RelativeIrradiance(Eigen::Vector3d(point[0], point[1], point[2]), towards);
}

Eigen::Vector3d PixelLights::View(int index) const {
  if (stack_.views.empty()) return stack_.view_direction.normalized();
  const cv::Vec3f v = stack_.views.ptr<cv::Vec3f>()[index];
  return Eigen::Vector3d(v[0], v[1], v[2]).normalized();
}

Samples Gather(const ReflectanceStack& stack, const cv::Mat& normals, const cv::Mat& mask, double min_cosine,
               cv::Mat* flags, long long* saturated_samples) {
  const PixelLights lights(stack);
  Samples s;
  s.width = stack.width();
  s.height = stack.height();
  s.lights = stack.light_count();
  s.channels = stack.channels();
  *flags = cv::Mat(s.height, s.width, CV_8U, cv::Scalar(static_cast<int>(PixelFlag::kFitted)));
  for (int j = 0; j < s.lights; ++j) s.intensity.push_back(stack.Intensity(j));
  *saturated_samples = 0;
  for (int r = 0; r < s.height; ++r) {
    for (int c = 0; c < s.width; ++c) {
      if (!mask.empty() && mask.at<std::uint8_t>(r, c) == 0) {
        flags->at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(PixelFlag::kOutsideMask);
        continue;
      }
      const cv::Vec3f nf = normals.at<cv::Vec3f>(r, c);
      const Eigen::Vector3d n(nf[0], nf[1], nf[2]);
      if (!n.allFinite() || n.norm() < 0.5 || n.normalized().dot(lights.View(r * s.width + c)) <= 0.0) {
        flags->at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(PixelFlag::kNoNormal);
        continue;
      }
      s.pixel_index.push_back(r * s.width + c);
      s.normal.push_back(n.normalized());
    }
  }
  s.pixels = static_cast<int>(s.pixel_index.size());
  const std::size_t cells = static_cast<std::size_t>(s.pixels) * s.lights;
  s.value.resize(cells * s.channels);
  s.weight.assign(cells * s.channels, 1.0f);
  s.usable.assign(cells, 0);
  s.saturated.assign(cells, 0);
  s.geometry.resize(cells);
  if (!stack.near_lights.empty()) s.gain.resize(cells);
  s.usable_count.assign(s.pixels, 0);
  long long clipped = 0;
#pragma omp parallel for schedule(static) reduction(+ : clipped)
  for (int p = 0; p < s.pixels; ++p) {
    const Eigen::Vector3d& n = s.normal[p];
    Eigen::Vector3d t, b;
    FrameOf(n, &t, &b);
    const int idx = s.pixel_index[p];
    const Eigen::Vector3d view = lights.View(idx);
    const Eigen::Vector3d wo(t.dot(view), b.dot(view), n.dot(view));
    for (int j = 0; j < s.lights; ++j) {
      Eigen::Vector3d w;
      const double gain = lights.At(idx, j, &w);
      const std::size_t cell = s.At(p, j);
      if (!s.gain.empty()) s.gain[cell] = static_cast<float>(gain);
      s.geometry[cell] = brdf::GeometryOf(Eigen::Vector3d(t.dot(w), b.dot(w), n.dot(w)), wo);
      const float* px = stack.images[j].ptr<float>() + static_cast<std::size_t>(idx) * s.channels;
      bool clip = false, finite = true;
      for (int ch = 0; ch < s.channels; ++ch) {
        s.value[cell * s.channels + ch] = px[ch];
        clip = clip || px[ch] >= stack.saturation_level;
        finite = finite && std::isfinite(px[ch]);
      }
      const bool lit = s.geometry[cell].cos_i >= min_cosine && gain > 0.0;
      if (lit && clip) {
        s.saturated[cell] = 1;
        ++clipped;
      }
      s.usable[cell] = lit && !clip && finite;
      s.usable_count[p] += s.usable[cell];
    }
  }
  *saturated_samples = clipped;
  return s;
}

void LobeBasis(const Lobe& lobe, const brdf::Geometry& g, double* a0, double* a1) {
  // The brdf module's own lobes, so the two stay one definition. A
  // Blinn-Phong lobe is zero at weight 0; GGX's Schlick term is not. The
  // per-material lobe's weight is GGX's F0, its lobe scale 1.
  const double extra = lobe.model == brdf::Model::kGgx ? 1.0 : 0.0;
  *a0 = lobe.model == brdf::Model::kGgx ? brdf::EvaluateLobe(lobe.model, 0.0, lobe.shape, extra, g) : 0.0;
  *a1 = lobe.model == brdf::Model::kLambertian ? 0.0 : brdf::EvaluateLobe(lobe.model, 1.0, lobe.shape, extra, g);
}

PixelSums SumsOf(const Samples& s, int p, const Lobe& lobe, const std::vector<std::uint8_t>& enabled) {
  PixelSums sums;
  for (int j = 0; j < s.lights; ++j) {
    const std::size_t cell = s.At(p, j);
    if (!s.usable[cell] || (!enabled.empty() && !enabled[j])) continue;
    const brdf::Geometry& g = s.geometry[cell];
    double a0, a1;
    LobeBasis(lobe, g, &a0, &a1);
    ++sums.samples;
    for (int ch = 0; ch < s.channels; ++ch) {
      const double e = s.Irradiance(cell, j, ch) * g.cos_i;
      const double u = e / M_PI, g = e * a0, h = e * (a1 - a0);
      const double y = s.value[cell * s.channels + ch] - g;
      const double w = s.weight[cell * s.channels + ch];
      ChannelSums& cs = sums.c[ch];
      cs.uu += w * u * u;
      cs.uh += w * u * h;
      cs.hh += w * h * h;
      cs.uy += w * u * y;
      cs.hy += w * h * y;
      cs.yy += w * y * y;
    }
  }
  return sums;
}

double PixelCost(const ChannelSums& cs, double weight, double* rho) {
  if (cs.uu <= 0.0) {
    *rho = 0.0;
    return cs.yy;
  }
  double r = (cs.uy - weight * cs.uh) / cs.uu;
  if (r < 0.0) r = 0.0;
  *rho = r;
  const double cost = cs.yy - 2.0 * r * cs.uy - 2.0 * weight * cs.hy + r * r * cs.uu + 2.0 * r * weight * cs.uh +
                      weight * weight * cs.hh;
  return std::max(cost, 0.0);
}

GroupFit FitGroup(const Samples& s, const std::vector<int>& pixels, const Lobe& lobe,
                  const std::vector<std::uint8_t>& enabled, std::vector<PixelSums>* sums_out) {
  std::vector<PixelSums> local;
  std::vector<PixelSums>& sums = sums_out ? *sums_out : local;
  sums.resize(pixels.size());
  const int count = static_cast<int>(pixels.size());
#pragma omp parallel for schedule(static) if (count > 256)
  for (int i = 0; i < count; ++i) sums[i] = SumsOf(s, pixels[i], lobe, enabled);
  GroupFit fit;
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (const PixelSums& ps : sums) {
    fit.residuals += static_cast<long long>(ps.samples) * s.channels;
    for (int ch = 0; ch < s.channels; ++ch) {
      const ChannelSums& cs = ps.c[ch];
      if (cs.uu <= 0.0) continue;
      fit.reduced_hh[ch] += cs.hh - cs.uh * cs.uh / cs.uu;
      b[ch] += cs.hy - cs.uh * cs.uy / cs.uu;
    }
  }
  if (lobe.model != brdf::Model::kLambertian) {
    for (int ch = 0; ch < s.channels; ++ch) {
      double w = fit.reduced_hh[ch] > 1e-300 ? b[ch] / fit.reduced_hh[ch] : 0.0;
      w = std::max(w, 0.0);
      if (lobe.model == brdf::Model::kGgx) w = std::min(w, 1.0);  // F0 is a reflectance
      fit.weight[ch] = w;
    }
  }
  for (const PixelSums& ps : sums)
    for (int ch = 0; ch < s.channels; ++ch) {
      double rho;
      fit.cost += PixelCost(ps.c[ch], fit.weight[ch], &rho);
      const ChannelSums& cs = ps.c[ch];
      if (cs.uu <= 0.0) continue;
      // The pixel's share of the weight's normal equation, off balance at the shared weight.
      const double score = (cs.hy - cs.uh * cs.uy / cs.uu) - fit.weight[ch] * (cs.hh - cs.uh * cs.uh / cs.uu);
      fit.weight_variance[ch] += score * score;
    }
  for (int ch = 0; ch < s.channels; ++ch)
    fit.weight_variance[ch] = fit.reduced_hh[ch] > 0.0 ? fit.weight_variance[ch] / (fit.reduced_hh[ch] * fit.reduced_hh[ch]) : 0.0;
  return fit;
}

const std::vector<double>& ShapeGrid(brdf::Model model) {
  static const std::vector<double> exponents = LogGrid(2.0, 3000.0, 22);
  static const std::vector<double> roughness = LogGrid(0.02, 1.0, 18);
  return model == brdf::Model::kGgx ? roughness : exponents;
}

ShapeSearch SearchShape(const Samples& s, const std::vector<int>& pixels, brdf::Model model,
                        const std::vector<std::uint8_t>& enabled, bool refine) {
  const std::vector<double>& grid = ShapeGrid(model);
  auto cost_at = [&](double log_shape) { return FitGroup(s, pixels, {model, std::exp(log_shape)}, enabled).cost; };
  std::vector<double> costs(grid.size());
  for (std::size_t i = 0; i < grid.size(); ++i) costs[i] = cost_at(std::log(grid[i]));
  const std::size_t best = std::min_element(costs.begin(), costs.end()) - costs.begin();
  ShapeSearch out{grid[best], costs[best], 0.0};
  if (!refine) return out;
  // Golden section on log(shape) between the neighbours of the best grid point.
  double lo = std::log(grid[best > 0 ? best - 1 : 0]);
  double hi = std::log(grid[std::min(best + 1, grid.size() - 1)]);
  const double ratio = 0.5 * (std::sqrt(5.0) - 1.0);
  double x1 = hi - ratio * (hi - lo), x2 = lo + ratio * (hi - lo);
  double f1 = cost_at(x1), f2 = cost_at(x2);
  for (int it = 0; it < 14; ++it) {
    if (f1 < f2) {
      hi = x2; x2 = x1; f2 = f1;
      x1 = hi - ratio * (hi - lo);
      f1 = cost_at(x1);
    } else {
      lo = x1; x1 = x2; f1 = f2;
      x2 = lo + ratio * (hi - lo);
      f2 = cost_at(x2);
    }
  }
  const double x = f1 < f2 ? x1 : x2, fx = std::min(f1, f2);
  if (fx < out.cost) out = {std::exp(x), fx, 0.0};
  // Curvature of the cost in log(shape): the cost is a chi-square, so var = 2 / cost''.
  const double step = 0.05, xs = std::log(out.shape);
  const double curvature = (cost_at(xs + step) - 2.0 * out.cost + cost_at(xs - step)) / (step * step);
  out.log_shape_sigma = curvature > 0.0 ? std::sqrt(2.0 / curvature) : std::numeric_limits<double>::infinity();
  return out;
}

namespace {

// Every n-th pixel, so that at most `count` remain.
std::vector<int> Subsample(const std::vector<int>& pixels, int count) {
  if (static_cast<int>(pixels.size()) <= count) return pixels;
  std::vector<int> out;
  const double step = static_cast<double>(pixels.size()) / count;
  for (int i = 0; i < count; ++i) out.push_back(pixels[static_cast<std::size_t>(i * step)]);
  return out;
}

// The cost is a chi-square (samples weighted by their noise): -2 log L up to a constant.
double Bic(double chi_square, long long residuals, int parameters) {
  return chi_square + parameters * std::log(static_cast<double>(std::max<long long>(residuals, 1)));
}

}  // namespace

MaterialResult FitMaterial(const Samples& s, const std::vector<int>& pixels, const std::vector<brdf::Model>& candidates,
                           const std::vector<std::uint8_t>& enabled, int search_pixels) {
  MaterialResult best;
  double best_bic = std::numeric_limits<double>::infinity();
  const std::vector<int> subset = Subsample(pixels, search_pixels);
  // Each lobe's shape search on a thread of its own: one parallel region
  // per material rather than one per trial shape (FitGroup's), since on a
  // busy machine every region waits at its barrier for a descheduled thread.
  const int count = static_cast<int>(candidates.size());
  const int lobes = static_cast<int>(std::count_if(candidates.begin(), candidates.end(),
                                                   [](brdf::Model m) { return m != brdf::Model::kLambertian; }));
  std::vector<ShapeSearch> searches(candidates.size());
#pragma omp parallel for schedule(dynamic, 1) if (lobes > 1)
  for (int c = 0; c < count; ++c)
    if (candidates[c] != brdf::Model::kLambertian) searches[c] = SearchShape(s, subset, candidates[c], enabled, true);
  for (int c = 0; c < count; ++c) {
    const brdf::Model model = candidates[c];
    const Lobe lobe{model, searches[c].shape};
    const double log_sigma = searches[c].log_shape_sigma;
    const GroupFit fit = FitGroup(s, pixels, lobe, enabled);
    const int parameters = model == brdf::Model::kLambertian ? 0 : s.channels + 1;
    const double bic = Bic(fit.cost, fit.residuals, parameters);
    if (model == brdf::Model::kLambertian) best.fit.bic_lambertian = bic;
    if (bic < best_bic) {
      best_bic = bic;
      best.fit.model = model;
      best.fit.specular = fit.weight;
      best.fit.shape = lobe.shape;
      // One standard deviation with pixels as the independent units; the
      // shape's, from the cost's curvature, inflated by the same factor
      // over the per-sample noise model's variance (at least 1).
      double inflation = 1.0;
      for (int ch = 0; ch < s.channels; ++ch) {
        best.fit.specular_sigma[ch] = model != brdf::Model::kLambertian ? std::sqrt(fit.weight_variance[ch]) : 0.0;
        if (model != brdf::Model::kLambertian && fit.reduced_hh[ch] > 0.0)
          inflation = std::max(inflation, fit.weight_variance[ch] * fit.reduced_hh[ch]);
      }
      best.fit.shape_sigma = log_sigma * std::sqrt(inflation);
      best.fit.bic = bic;
      best.fit.pixels = static_cast<int>(pixels.size());
      best.cost = fit.cost;
      best.residuals = fit.residuals;
    }
  }
  return best;
}

namespace {

// The pixel's own lobe as a Lobe.
Lobe OwnLobe(const PixelLobe& own) {
  return {own.exponent > 0.0 ? brdf::Model::kBlinnPhong : brdf::Model::kLambertian, own.exponent};
}

// Least squares of v_b = a + b m_b + c m_b^2 over bins, each bin's error
// relative to its value (a median's spread scales with it), with every
// coefficient >= 0: the unconstrained fits of each subset of free terms,
// the feasible one of least error kept. `fixed_a` >= 0 holds a.
Eigen::Vector3d FitVariance(const std::vector<double>& m, const std::vector<double>& v, double fixed_a) {
  Eigen::Vector3d best = Eigen::Vector3d::Zero();
  double best_error = std::numeric_limits<double>::infinity();
  for (int subset = 1; subset < 8; ++subset) {
    const bool use[3] = {fixed_a < 0.0 && (subset & 1), (subset & 2) != 0, (subset & 4) != 0};
    std::vector<int> terms;
    for (int t = 0; t < 3; ++t)
      if (use[t]) terms.push_back(t);
    if (terms.empty() || static_cast<int>(terms.size()) > static_cast<int>(m.size())) continue;
    Eigen::MatrixXd A(m.size(), terms.size());
    Eigen::VectorXd y(m.size());
    for (std::size_t b = 0; b < m.size(); ++b) {
      const double scale = 1.0 / std::max(v[b], 1e-300);
      for (std::size_t t = 0; t < terms.size(); ++t) A(b, t) = std::pow(m[b], terms[t]) * scale;
      y[b] = (v[b] - std::max(fixed_a, 0.0)) * scale;
    }
    const Eigen::VectorXd x = A.colPivHouseholderQr().solve(y);
    if (x.minCoeff() < 0.0) continue;
    const double error = (A * x - y).squaredNorm();
    if (error < best_error) {
      best_error = error;
      best.setZero();
      for (std::size_t t = 0; t < terms.size(); ++t) best[terms[t]] = x[t];
    }
  }
  if (fixed_a >= 0.0) best[0] = fixed_a;
  return best;
}

}  // namespace

SensorNoise EstimateNoise(const Samples& s, const std::vector<int>& pixels, const std::vector<PixelLobe>& own,
                          const SensorNoise& given, std::string* source) {
  const bool read_given = given.read_sigma.head(s.channels).minCoeff() > 0.0;
  const bool shot_given = given.shot_gain.head(s.channels).minCoeff() > 0.0;
  if (read_given && shot_given) {
    *source = "given";
    return given;
  }
  *source = read_given ? "read noise given, shot noise estimated" : "estimated";
  // Squared residuals of each pixel's own fit, scaled up for the parameters
  // it spent (n / (n - k)), against the fit's prediction per channel.
  std::vector<std::vector<std::pair<double, double>>> points(s.channels);
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    const int p = pixels[i];
    const Lobe lobe = OwnLobe(own[i]);
    const int n = s.usable_count[p];
    const double k = 1.0 + (lobe.model == brdf::Model::kLambertian ? 0.0 : 1.0 + 1.0 / s.channels);
    if (n <= k + 1.0) continue;
    const double correction = n / (n - k);
    for (int j = 0; j < s.lights; ++j) {
      const std::size_t cell = s.At(p, j);
      if (!s.usable[cell]) continue;
      for (int ch = 0; ch < s.channels; ++ch) {
        const double predicted = Predict(s, cell, lobe, own[i].weight[ch], own[i].rho[ch], s.Irradiance(cell, j, ch));
        const double r = s.value[cell * s.channels + ch] - predicted;
        points[ch].emplace_back(predicted, r * r * correction);
      }
    }
  }
  SensorNoise noise = given;
  for (int ch = 0; ch < s.channels; ++ch) {
    auto& pts = points[ch];
    if (pts.size() < 100) continue;
    // Equal-count bins of the prediction; each bin's variance from its median
    // squared residual (a chi-square(1) has median 0.455): what a few
    // pixels the model does not fit (edges, blends) cannot move.
    std::sort(pts.begin(), pts.end());
    const int bins = 24;
    std::vector<double> m, v;
    for (int b = 0; b < bins; ++b) {
      const std::size_t lo = pts.size() * b / bins, hi = pts.size() * (b + 1) / bins;
      if (hi <= lo) continue;
      std::vector<double> r2;
      double mean = 0.0;
      for (std::size_t i = lo; i < hi; ++i) {
        mean += pts[i].first;
        r2.push_back(pts[i].second);
      }
      auto mid = r2.begin() + static_cast<std::ptrdiff_t>(r2.size() / 2);
      std::nth_element(r2.begin(), mid, r2.end());
      m.push_back(std::max(0.0, mean / (hi - lo)));
      v.push_back(*mid / 0.4549);
    }
    const double fixed_read = read_given ? given.read_sigma[ch] * given.read_sigma[ch] : -1.0;
    const Eigen::Vector3d c = FitVariance(m, v, fixed_read);
    noise.read_sigma[ch] = std::sqrt(c[0]);
    noise.shot_gain[ch] = c[1];
    noise.relative[ch] = std::sqrt(c[2]);
  }
  return noise;
}

void WeightSamples(const SensorNoise& noise, const std::vector<int>& pixels, const std::vector<PixelLobe>& own,
                   Samples* s) {
  // A floor for a model that says a dark sample has no noise at all.
  double floor = std::numeric_limits<double>::infinity();
  for (int ch = 0; ch < s->channels; ++ch) floor = std::min(floor, noise.Variance(ch, 1.0));
  floor = std::max(1e-6 * floor, 1e-300);
  const int count = static_cast<int>(pixels.size());
#pragma omp parallel for schedule(static)
  for (int i = 0; i < count; ++i) {
    const int p = pixels[i];
    const Lobe lobe = OwnLobe(own[i]);
    for (int j = 0; j < s->lights; ++j) {
      const std::size_t cell = s->At(p, j);
      if (!s->usable[cell]) continue;
      for (int ch = 0; ch < s->channels; ++ch) {
        const double predicted = Predict(*s, cell, lobe, own[i].weight[ch], own[i].rho[ch], s->Irradiance(cell, j, ch));
        s->weight[cell * s->channels + ch] = static_cast<float>(1.0 / std::max(noise.Variance(ch, predicted), floor));
      }
    }
  }
}

double Predict(const Samples& s, std::size_t cell, const Lobe& lobe, double weight, double rho, double irradiance) {
  const brdf::Geometry& g = s.geometry[cell];
  if (g.cos_i <= 0.0) return 0.0;
  double a0, a1;
  LobeBasis(lobe, g, &a0, &a1);
  return irradiance * g.cos_i * (rho / M_PI + a0 + weight * (a1 - a0));
}

}  // namespace photorig::solvers::reflectance::internal
