#include "photorig/solvers/lighting/inverse_lighting.h"

#include "photorig/solvers/lighting/nnls.h"
#include "photorig/solvers/lighting/spherical_harmonics.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

namespace photorig::solvers::lighting {
namespace {

// Results are R, G, B columns; OpenCV stores B, G, R.
int ColourColumn(int stored_channel, int channels) { return channels == 3 ? 2 - stored_channel : 0; }

// Normal equations of one linear model, per image channel and per held-out fold.
struct NormalEquations {
  std::vector<Eigen::MatrixXd> gram;      // [fold * channels + channel]
  std::vector<Eigen::VectorXd> rhs;
  std::vector<double> sum_squares;
  std::vector<std::size_t> samples;       // per fold
  double sum_intensity = 0.0;
  int channels = 0;
};

std::string CheckInputs(const cv::Mat& normals, const cv::Mat& albedo, const cv::Mat& image, const cv::Mat& mask) {
  if (normals.empty() || normals.type() != CV_32FC3) return "normals must be CV_32FC3";
  if (image.size() != normals.size() || image.depth() != CV_32F || (image.channels() != 1 && image.channels() != 3)) {
    return "image must be CV_32F with 1 or 3 channels and the normals' size";
  }
  if (albedo.size() != normals.size() || albedo.depth() != CV_32F ||
      (albedo.channels() != 1 && albedo.channels() != image.channels())) {
    return "albedo must be CV_32F, the normals' size, 1 channel or the image's channels";
  }
  if (!mask.empty() && (mask.size() != normals.size() || mask.type() != CV_8U)) return "mask must be CV_8U";
  return {};
}

// basis(n, out) fills `columns` regressors for a surface of unit albedo; the
// albedo multiplies them per channel. Folds: a fixed pseudo-random pixel split.
template <typename Basis>
NormalEquations Accumulate(const cv::Mat& normals, const cv::Mat& albedo, const cv::Mat& image, const cv::Mat& mask,
                           int stride, double min_albedo, int columns, Basis basis) {
  NormalEquations eq;
  eq.channels = image.channels();
  for (int i = 0; i < 2 * eq.channels; ++i) {
    eq.gram.push_back(Eigen::MatrixXd::Zero(columns, columns));
    eq.rhs.push_back(Eigen::VectorXd::Zero(columns));
    eq.sum_squares.push_back(0.0);
  }
  eq.samples = {0, 0};
  Eigen::VectorXd phi(columns);
  for (int r = 0; r < normals.rows; r += stride) {
    const cv::Vec3f* n_row = normals.ptr<cv::Vec3f>(r);
    const float* a_row = albedo.ptr<float>(r);
    const float* i_row = image.ptr<float>(r);
    for (int c = 0; c < normals.cols; c += stride) {
      if (!mask.empty() && !mask.at<std::uint8_t>(r, c)) continue;
      const Eigen::Vector3d n(n_row[c][0], n_row[c][1], n_row[c][2]);
      if (!(std::abs(n.squaredNorm() - 1.0) < 1e-2)) continue;
      if (!(a_row[c * albedo.channels()] > min_albedo)) continue;
      basis(n, phi.data());
      const int fold = static_cast<int>(((static_cast<unsigned>(r) * 73856093u) ^ (static_cast<unsigned>(c) * 19349663u)) >> 7 & 1u);
      ++eq.samples[static_cast<std::size_t>(fold)];
      for (int ch = 0; ch < eq.channels; ++ch) {
        const double a = a_row[albedo.channels() == 1 ? c : c * eq.channels + ch];
        const double value = i_row[c * eq.channels + ch];
        const std::size_t k = static_cast<std::size_t>(fold * eq.channels + ch);
        eq.gram[k].selfadjointView<Eigen::Lower>().rankUpdate(phi, a * a);
        eq.rhs[k] += (a * value) * phi;
        eq.sum_squares[k] += value * value;
        eq.sum_intensity += value;
      }
    }
  }
  for (auto& g : eq.gram) g = g.selfadjointView<Eigen::Lower>();
  return eq;
}

Eigen::MatrixXd Select(const Eigen::MatrixXd& m, const std::vector<int>& index) {
  Eigen::MatrixXd out(index.size(), index.size());
  for (std::size_t a = 0; a < index.size(); ++a)
    for (std::size_t b = 0; b < index.size(); ++b)
      out(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) = m(index[a], index[b]);
  return out;
}
Eigen::VectorXd SelectEntries(const Eigen::VectorXd& v, const std::vector<int>& index) {
  Eigen::VectorXd out(index.size());
  for (std::size_t a = 0; a < index.size(); ++a) out(static_cast<Eigen::Index>(a)) = v(index[a]);
  return out;
}
double Sse(const Eigen::MatrixXd& g, const Eigen::VectorXd& h, double s, const Eigen::VectorXd& x) {
  return std::max(0.0, x.dot(g * x) - 2.0 * x.dot(h) + s);
}

// The fitted irradiance's worst one-sigma over the visible hemisphere, over
// its mean there: `covariance` of the coefficients `x` of the columns
// `index`, each normal's regressors from `basis`. Directions on a
// Fibonacci lattice of the hemisphere, dense enough for band 8's lobes.
template <typename Basis>
double HemisphereRelativeSigma(const Eigen::MatrixXd& covariance, const Eigen::VectorXd& x, const std::vector<int>& index,
                               int columns, Basis basis) {
  constexpr int kDirections = 600;
  Eigen::VectorXd phi(columns), row(static_cast<Eigen::Index>(index.size()));
  double worst = 0.0, mean = 0.0;
  for (int i = 0; i < kDirections; ++i) {
    const double z = (i + 0.5) / kDirections, radius = std::sqrt(1.0 - z * z);
    const double azimuth = i * M_PI * (3.0 - std::sqrt(5.0));
    basis(Eigen::Vector3d(radius * std::cos(azimuth), radius * std::sin(azimuth), z), phi.data());
    for (std::size_t a = 0; a < index.size(); ++a) row(static_cast<Eigen::Index>(a)) = phi(index[a]);
    worst = std::max(worst, std::sqrt(std::max(0.0, row.dot(covariance * row))));
    mean += row.dot(x) / kDirections;
  }
  return worst / std::max(std::abs(mean), 1e-300);
}

}  // namespace

bool ShFitOptions::IsValid(std::string* why) const {
  if (max_band < 0 || max_band > 8 || fixed_band < 0 || fixed_band > 8 || pixel_stride < 1 || !(heldout_tolerance >= 0.0)) {
    if (why) *why = "bands in [0, 8], pixel_stride >= 1, heldout_tolerance >= 0";
    return false;
  }
  if (!(max_hemisphere_relative_sigma > 0.0)) {
    if (why) *why = "max_hemisphere_relative_sigma must be > 0";
    return false;
  }
  return true;
}

ShLightingSummary FitShLighting(const cv::Mat& normals, const cv::Mat& albedo, const cv::Mat& image,
                                const cv::Mat& mask, const ShFitOptions& options) {
  const solvers::core::SolveTimer timer;
  ShLightingSummary summary;
  if (solvers::core::EndIfInvalid(options, &summary)) return summary;
  if (solvers::core::EndIfBadInput(CheckInputs(normals, albedo, image, mask), &summary)) return summary;
  const int top_band = options.selection == ShFitOptions::Selection::kFixed ? options.fixed_band : options.max_band;
  const int columns = ShCoefficientCount(top_band);
  std::vector<double> kernel(static_cast<std::size_t>(columns));
  for (int l = 0; l <= top_band; ++l)
    for (int m = -l; m <= l; ++m) kernel[static_cast<std::size_t>(l * l + l + m)] = LambertianKernel(l) / M_PI;
  const auto basis = [&](const Eigen::Vector3d& n, double* out) {
    EvaluateSh(top_band, n, out);
    for (int j = 0; j < columns; ++j) out[j] *= kernel[static_cast<std::size_t>(j)];
  };
  const NormalEquations eq =
      Accumulate(normals, albedo, image, mask, options.pixel_stride, options.min_albedo, columns, basis);
  const int channels = eq.channels;
  summary.pixels_used = eq.samples[0] + eq.samples[1];

  // Candidate bands; a band whose kernel vanishes (odd > 1) adds nothing a Lambertian surface shows.
  std::vector<int> bands;
  for (int band = 0; band <= top_band; ++band) {
    if (LambertianKernel(band) != 0.0 && (options.selection != ShFitOptions::Selection::kFixed || band == top_band)) {
      bands.push_back(band);
    }
  }
  if (options.selection == ShFitOptions::Selection::kFixed && bands.empty()) bands.push_back(top_band);
  auto columns_of = [&](int band) {
    std::vector<int> index;
    for (int j = 0; j < ShCoefficientCount(band); ++j) {
      if (kernel[static_cast<std::size_t>(j)] != 0.0) index.push_back(j);
    }
    return index;
  };
  if (summary.pixels_used < static_cast<std::size_t>(2 * columns_of(bands.back()).size())) {
    summary.End(solvers::core::Termination::kFailure, "too few valid pixels (" + std::to_string(summary.pixels_used) + ")");
    return summary;
  }

  const double n_total = static_cast<double>(summary.pixels_used) * channels;
  double best_heldout = std::numeric_limits<double>::infinity();
  for (int band : bands) {
    const std::vector<int> index = columns_of(band);
    ShCandidate candidate;
    candidate.band = band;
    double sse_train = 0.0, sse_heldout = 0.0;
    for (int ch = 0; ch < channels; ++ch) {
      const auto k0 = static_cast<std::size_t>(ch), k1 = static_cast<std::size_t>(channels + ch);
      const Eigen::MatrixXd g0 = Select(eq.gram[k0], index), g1 = Select(eq.gram[k1], index);
      const Eigen::VectorXd h0 = SelectEntries(eq.rhs[k0], index), h1 = SelectEntries(eq.rhs[k1], index);
      const Eigen::VectorXd x_all = (g0 + g1).ldlt().solve(h0 + h1);
      sse_train += Sse(g0 + g1, h0 + h1, eq.sum_squares[k0] + eq.sum_squares[k1], x_all);
      sse_heldout += Sse(g1, h1, eq.sum_squares[k1], g0.ldlt().solve(h0)) +
                     Sse(g0, h0, eq.sum_squares[k0], g1.ldlt().solve(h1));
    }
    candidate.train_rms = std::sqrt(sse_train / n_total);
    candidate.heldout_rms = std::sqrt(sse_heldout / n_total);
    const double k = static_cast<double>(index.size()) * channels;
    candidate.bic = n_total * std::log(std::max(sse_train / n_total, 1e-300)) + k * std::log(n_total);
    best_heldout = std::min(best_heldout, candidate.heldout_rms);
    summary.candidates.push_back(candidate);
  }

  int chosen = bands.back();
  if (options.selection == ShFitOptions::Selection::kHeldOut) {
    // Lowest band within tolerance of the best held-out residual; an absolute floor
    // keeps noiseless data (residuals at rounding level) from picking by rounding.
    const double floor = 1e-6 * eq.sum_intensity / n_total;
    for (const auto& c : summary.candidates) {
      if (c.heldout_rms <= best_heldout * (1.0 + options.heldout_tolerance) + floor) {
        chosen = c.band;
        break;
      }
    }
  } else if (options.selection == ShFitOptions::Selection::kBic) {
    double best_bic = std::numeric_limits<double>::infinity();
    for (const auto& c : summary.candidates) {
      if (c.bic < best_bic) {
        best_bic = c.bic;
        chosen = c.band;
      }
    }
  }

  const std::vector<int> index = columns_of(chosen);
  summary.band = chosen;
  summary.coefficients = Eigen::MatrixXd::Zero(ShCoefficientCount(chosen), channels);
  double sse = 0.0;
  for (int ch = 0; ch < channels; ++ch) {
    const auto k0 = static_cast<std::size_t>(ch), k1 = static_cast<std::size_t>(channels + ch);
    const Eigen::MatrixXd g = Select(eq.gram[k0] + eq.gram[k1], index);
    const Eigen::VectorXd h = SelectEntries(eq.rhs[k0] + eq.rhs[k1], index);
    const Eigen::VectorXd x = g.ldlt().solve(h);
    sse += Sse(g, h, eq.sum_squares[k0] + eq.sum_squares[k1], x);
    for (std::size_t a = 0; a < index.size(); ++a) summary.coefficients(index[a], ColourColumn(ch, channels)) = x(static_cast<Eigen::Index>(a));
    if (ch == 0) {
      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(g);
      summary.condition_number =
          std::sqrt(eigen.eigenvalues().maxCoeff() / std::max(eigen.eigenvalues().minCoeff(), 1e-300));
      const double dof = std::max(1.0, static_cast<double>(summary.pixels_used) - static_cast<double>(index.size()));
      const Eigen::MatrixXd covariance =
          Sse(g, h, eq.sum_squares[k0] + eq.sum_squares[k1], x) / dof *
          g.ldlt().solve(Eigen::MatrixXd::Identity(g.rows(), g.cols()));
      summary.hemisphere_relative_sigma = HemisphereRelativeSigma(covariance, x, index, columns, basis);
    }
  }
  summary.rms_residual = std::sqrt(sse / n_total);
  summary.relative_rms_residual = summary.rms_residual / std::max(std::abs(eq.sum_intensity / n_total), 1e-300);
  if (std::isfinite(summary.rms_residual)) {
    std::string message = "band " + std::to_string(chosen) + " selected";
    if (!(summary.hemisphere_relative_sigma <= options.max_hemisphere_relative_sigma)) {
      char figures[160];
      std::snprintf(figures, sizeof figures, "%.3g %% (one sigma) at the worst normal, above the %.3g %% allowed",
                    100.0 * summary.hemisphere_relative_sigma, 100.0 * options.max_hemisphere_relative_sigma);
      message += "; the lighting is pinned down on the normals seen, but the rest of the visible hemisphere is "
                 "extrapolated: " + std::string(figures) +
                 ". Relight only these normals, or fit normals that span more of the sphere (a lower band "
                 "extrapolates less)";
    }
    summary.End(solvers::core::Termination::kSuccess, message);
  } else {
    summary.End(solvers::core::Termination::kFailure, "the fit's residual is not finite (NaN or infinite input values?)");
  }
  timer.Finish(&summary);
  return summary;
}

namespace {

// The simplest set of LEDs the data support, from the NNLS solution x of
// (g, h) (one channel; sum_squares = b.b, n samples): the LED whose removal
// raises the sum of squares least is dropped, and the rest refitted, while
// that rise is below BIC's price of one parameter, ln(n) sigma^2, sigma^2
// the full fit's residual variance. Returns the number dropped.
int DropUnsupportedLeds(const Eigen::MatrixXd& g, const Eigen::VectorXd& h, double sum_squares, double n,
                        Eigen::VectorXd* x) {
  std::vector<int> active;
  for (int k = 0; k < x->size(); ++k)
    if ((*x)(k) > 0.0) active.push_back(k);
  double sse = Sse(g, h, sum_squares, *x);
  const double variance = sse / std::max(1.0, n - static_cast<double>(active.size()));
  const double price = std::log(n) * variance;
  int dropped = 0;
  while (active.size() > 1) {
    double best_sse = std::numeric_limits<double>::infinity();
    std::size_t best = 0;
    Eigen::VectorXd best_x;
    for (std::size_t i = 0; i < active.size(); ++i) {
      std::vector<int> kept = active;
      kept.erase(kept.begin() + static_cast<std::ptrdiff_t>(i));
      Eigen::VectorXd sub_x;
      const NnlsSummary nnls = SolveNnlsNormal(g(kept, kept), h(kept), &sub_x);
      if (nnls.termination != solvers::core::Termination::kSuccess) continue;
      Eigen::VectorXd full = Eigen::VectorXd::Zero(x->size());
      full(kept) = sub_x;
      const double candidate = Sse(g, h, sum_squares, full);
      if (candidate < best_sse) best_sse = candidate, best = i, best_x = full;
    }
    if (!(best_sse - sse < price)) break;
    active.erase(active.begin() + static_cast<std::ptrdiff_t>(best));
    // An LED the refit set to zero is gone as well.
    active.erase(std::remove_if(active.begin(), active.end(), [&](int k) { return !(best_x(k) > 0.0); }), active.end());
    *x = best_x;
    sse = best_sse;
    ++dropped;
  }
  return dropped;
}

}  // namespace

bool LedWeightsOptions::IsValid(std::string* why) const {
  if (pixel_stride < 1) {
    if (why) *why = "pixel_stride >= 1";
    return false;
  }
  return true;
}

LedWeightsSummary FitLedWeights(const cv::Mat& normals, const cv::Mat& albedo, const cv::Mat& image,
                                const cv::Mat& mask, const std::vector<Eigen::Vector3d>& led_directions,
                                const std::vector<double>& led_intensities, const LedWeightsOptions& options) {
  const solvers::core::SolveTimer timer;
  LedWeightsSummary summary;
  if (solvers::core::EndIfInvalid(options, &summary)) return summary;
  if (solvers::core::EndIfBadInput(CheckInputs(normals, albedo, image, mask), &summary)) return summary;
  if (led_directions.empty() || led_directions.size() != led_intensities.size()) {
    summary.End(solvers::core::Termination::kInvalidInput, "need one intensity per LED direction");
    return summary;
  }
  const int leds = static_cast<int>(led_directions.size());
  const NormalEquations eq = Accumulate(normals, albedo, image, mask, options.pixel_stride, options.min_albedo, leds,
                                        [&](const Eigen::Vector3d& n, double* out) {
                                          for (int k = 0; k < leds; ++k) {
                                            out[k] = led_intensities[static_cast<std::size_t>(k)] / M_PI *
                                                     std::max(0.0, n.dot(led_directions[static_cast<std::size_t>(k)].normalized()));
                                          }
                                        });
  summary.pixels_used = eq.samples[0] + eq.samples[1];
  if (summary.pixels_used < static_cast<std::size_t>(leds)) {
    summary.End(solvers::core::Termination::kFailure, "too few valid pixels (" + std::to_string(summary.pixels_used) +
                                                     " for " + std::to_string(leds) + " LEDs)");
    return summary;
  }
  summary.weights = Eigen::MatrixXd::Zero(leds, eq.channels);
  double sse = 0.0;
  bool converged = true;
  for (int ch = 0; ch < eq.channels; ++ch) {
    const auto k0 = static_cast<std::size_t>(ch), k1 = static_cast<std::size_t>(eq.channels + ch);
    const Eigen::MatrixXd g = eq.gram[k0] + eq.gram[k1];
    const Eigen::VectorXd h = eq.rhs[k0] + eq.rhs[k1];
    Eigen::VectorXd x;
    const NnlsSummary nnls = SolveNnlsNormal(g, h, &x);
    converged = converged && nnls.termination == solvers::core::Termination::kSuccess;
    if (options.simplest_led_set && converged)
      summary.leds_dropped += DropUnsupportedLeds(g, h, eq.sum_squares[k0] + eq.sum_squares[k1],
                                                  static_cast<double>(summary.pixels_used), &x);
    summary.weights.col(ColourColumn(ch, eq.channels)) = x;
    sse += Sse(g, h, eq.sum_squares[k0] + eq.sum_squares[k1], x);
  }
  // Round-off leaves dust on LEDs the fit does not need; count those that matter.
  const double significant = 1e-4 * summary.weights.maxCoeff();
  for (int k = 0; k < leds; ++k) summary.active_leds += summary.weights.row(k).maxCoeff() > significant ? 1 : 0;
  const double n_total = static_cast<double>(summary.pixels_used) * eq.channels;
  summary.rms_residual = std::sqrt(sse / n_total);
  summary.relative_rms_residual = summary.rms_residual / std::max(std::abs(eq.sum_intensity / n_total), 1e-300);
  if (converged) {
    summary.End(solvers::core::Termination::kSuccess, "");
  } else {
    summary.End(solvers::core::Termination::kNoConvergence, "NNLS iteration limit reached");
  }
  timer.Finish(&summary);
  return summary;
}

}  // namespace photorig::solvers::lighting
