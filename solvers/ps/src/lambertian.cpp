#include "photorig/ps/lambertian.h"

#include <Eigen/SVD>
#include <omp.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <unordered_map>

namespace photorig::ps {
namespace {

using Clock = std::chrono::steady_clock;
double MillisecondsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

constexpr int kMaxLights = 256;  // width of the per-pixel usable-sample bitset
constexpr int kTilePixels = 1024;  // 4 KB per accumulator row: stays in L1 across all K planes

using LightSubset = std::array<std::uint64_t, kMaxLights / 64>;

struct LightSubsetHash {
  std::size_t operator()(const LightSubset& subset) const {
    std::uint64_t h = 0x9e3779b97f4a7c15ull;
    for (std::uint64_t word : subset) h = (h ^ word) * 0xff51afd7ed558ccdull;
    return static_cast<std::size_t>(h ^ (h >> 33));
  }
};

// Pseudo-inverse of the light matrix restricted to a subset, with 1/s_k folded
// in: x = sum_k weights(:, k) * (I_k - D). Columns of unused lights are zero.
struct SubsetSolver {
  Eigen::Matrix<float, 3, Eigen::Dynamic> weights;
  double condition_number = std::numeric_limits<double>::infinity();
};

SubsetSolver BuildSubsetSolver(const PhotometricStack& stack, const LightSubset& subset) {
  const int k = stack.light_count();
  std::vector<int> used;
  for (int i = 0; i < k; ++i)
    if (subset[i / 64] >> (i % 64) & 1u) used.push_back(i);
  SubsetSolver solver;
  solver.weights.setZero(3, k);
  if (used.size() < 3) return solver;
  Eigen::MatrixXd a(used.size(), 3);
  for (std::size_t r = 0; r < used.size(); ++r) a.row(r) = stack.light_directions[used[r]].transpose();
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::Vector3d s = svd.singularValues();
  solver.condition_number = s(2) > 0.0 ? s(0) / s(2) : std::numeric_limits<double>::infinity();
  if (!std::isfinite(solver.condition_number)) return solver;
  const Eigen::MatrixXd pinv =
      svd.matrixV() * s.cwiseInverse().asDiagonal() * svd.matrixU().transpose();  // 3 x m
  for (std::size_t r = 0; r < used.size(); ++r)
    solver.weights.col(used[r]) = (pinv.col(r) / stack.light_scales[used[r]]).cast<float>();
  return solver;
}

// Confidence from the residual: expected / observed residual variance when the
// noise is known (1 = explained down to the noise), else the coefficient of
// determination 1 - RSS / sum(b^2).
float Confidence(double rss, double expected_rss, double sum_b2) {
  if (!(rss > 0.0)) return 1.0f;
  if (expected_rss > 0.0) return static_cast<float>(std::min(1.0, expected_rss / rss));
  return static_cast<float>(std::clamp(1.0 - rss / std::max(sum_b2, 1e-300), 0.0, 1.0));
}

void WriteSolution(int pixel, float x0, float x1, float x2, float confidence, NormalMap* out) {
  const float length = std::sqrt(x0 * x0 + x1 * x1 + x2 * x2);
  auto* n = out->normals.ptr<cv::Vec3f>() + pixel;
  if (!(length > 0.0f)) {
    // All usable samples were zero after dark subtraction: no direction exists.
    out->flags.ptr<std::uint8_t>()[pixel] = static_cast<std::uint8_t>(PixelFlag::kTooFewLights);
    return;
  }
  *n = cv::Vec3f(x0 / length, x1 / length, x2 / length);
  out->albedo.ptr<float>()[pixel] = static_cast<float>(M_PI) * length;
  out->flags.ptr<std::uint8_t>()[pixel] = static_cast<std::uint8_t>(PixelFlag::kSolved);
  out->model.ptr<std::uint8_t>()[pixel] = static_cast<std::uint8_t>(PixelModel::kLambertian);
  out->confidence.ptr<float>()[pixel] = confidence;
}

}  // namespace

bool LambertianOptions::IsValid(std::string* why) const {
  auto fail = [why](const char* text) {
    if (why) *why = text;
    return false;
  };
  if (!(shadow_threshold >= 0.0) || !std::isfinite(shadow_threshold))
    return fail("shadow_threshold must be finite and >= 0");
  if (!(saturation_level > shadow_threshold)) return fail("saturation_level must exceed shadow_threshold");
  if (!(max_condition_number > 1.0)) return fail("max_condition_number must be > 1");
  if (num_threads < 0) return fail("num_threads must be >= 0 (0 = all)");
  return true;
}

SolverSummary SolveLambertian(const LambertianOptions& options, const PhotometricStack& stack,
                              NormalMap* result) {
  const auto start = Clock::now();
  SolverSummary summary;
  summary.method = options.exclude_unusable_samples ? "lambertian" : "lambertian-l2";
  summary.light_count = stack.light_count();
  std::string why;
  if (!options.IsValid(&why)) {
    summary.message = "invalid options: " + why;
    return summary;
  }
  if (!stack.IsValid(&why)) {
    summary.message = "invalid stack: " + why;
    return summary;
  }
  const int k = stack.light_count();
  if (k < 3) {
    summary.message = "photometric stereo needs at least 3 lights, got " + std::to_string(k);
    return summary;
  }
  if (k > kMaxLights) {
    summary.message = "at most " + std::to_string(kMaxLights) + " lights are supported, got " +
                      std::to_string(k);
    return summary;
  }

  LightSubset all_lights{};
  for (int i = 0; i < k; ++i) all_lights[i / 64] |= std::uint64_t{1} << (i % 64);
  const SubsetSolver global = BuildSubsetSolver(stack, all_lights);
  summary.condition_number = global.condition_number;
  if (!(global.condition_number <= options.max_condition_number)) {
    summary.message = "light directions are coplanar or nearly so (condition number " +
                      std::to_string(global.condition_number) + " > " +
                      std::to_string(options.max_condition_number) + ")";
    return summary;
  }

  const int width = stack.width(), height = stack.height();
  const int pixels = width * height;
  result->normals.create(height, width, CV_32FC3);
  result->normals.setTo(cv::Scalar::all(std::numeric_limits<float>::quiet_NaN()));
  result->albedo.create(height, width, CV_32F);
  result->albedo.setTo(std::numeric_limits<float>::quiet_NaN());
  result->flags.create(height, width, CV_8U);
  result->flags.setTo(static_cast<int>(PixelFlag::kOutsideMask));
  result->usable_lights.create(height, width, CV_16U);
  result->usable_lights.setTo(0);
  result->model = cv::Mat::zeros(height, width, CV_8U);
  result->confidence = cv::Mat::zeros(height, width, CV_32F);
  result->specular = cv::Mat::zeros(height, width, CV_32FC2);

  std::vector<const float*> planes(k);
  for (int i = 0; i < k; ++i) planes[i] = stack.images[i].ptr<float>();
  const float* dark = stack.dark.empty() ? nullptr : stack.dark.ptr<float>();
  const std::uint8_t* mask = stack.mask.empty() ? nullptr : stack.mask.ptr<std::uint8_t>();
  std::array<float, 3> dark_weight{};  // sum_k weights(:, k): dark subtraction folded into one term
  for (int c = 0; c < 3; ++c) dark_weight[c] = global.weights.row(c).sum();
  // For the residual of fully lit pixels without a second pass:
  //   RSS = sum_k b_k^2 - x^T G x,  G = A^T A,  b_k = (I_k - D) / s_k,
  // and sum_k b_k^2 = sum I^2/s^2 - 2 D sum I/s^2 + D^2 sum 1/s^2.
  std::vector<float> inverse_scale2(k);
  double sum_inverse_scale2 = 0.0;
  Eigen::Matrix3d gram = Eigen::Matrix3d::Zero();
  for (int i = 0; i < k; ++i) {
    inverse_scale2[i] = static_cast<float>(1.0 / (stack.light_scales[i] * stack.light_scales[i]));
    sum_inverse_scale2 += inverse_scale2[i];
    gram += stack.light_directions[i] * stack.light_directions[i].transpose();
  }
  const NoiseModel noise = stack.noise;
  const float shadow = static_cast<float>(options.shadow_threshold);
  const float saturation = std::isfinite(options.saturation_level)
                               ? static_cast<float>(options.saturation_level)
                               : std::numeric_limits<float>::infinity();
  summary.setup_ms = MillisecondsSince(start);

  const auto solve_start = Clock::now();
  const int tiles = (pixels + kTilePixels - 1) / kTilePixels;
  std::size_t rejected_samples = 0, distinct_subsets = 0;
  const int threads = options.num_threads > 0 ? options.num_threads : omp_get_max_threads();

#pragma omp parallel num_threads(threads) reduction(+ : rejected_samples, distinct_subsets)
  {
    std::unordered_map<LightSubset, SubsetSolver, LightSubsetHash> cache;
    alignas(64) float x0[kTilePixels], x1[kTilePixels], x2[kTilePixels], d[kTilePixels];
    alignas(64) float q1[kTilePixels], q2[kTilePixels];  // sum I/s^2, sum I^2/s^2
    alignas(64) std::uint16_t usable[kTilePixels];
    std::vector<float> samples(k);

#pragma omp for schedule(dynamic, 4)
    for (int tile = 0; tile < tiles; ++tile) {
      const int begin = tile * kTilePixels;
      const int n = std::min(kTilePixels, pixels - begin);
      for (int i = 0; i < n; ++i) {
        x0[i] = x1[i] = x2[i] = q1[i] = q2[i] = 0.0f;
        usable[i] = 0;
        d[i] = dark ? dark[begin + i] : 0.0f;
      }
      // The streaming pass: every sample is read exactly once from memory.
      for (int l = 0; l < k; ++l) {
        const float* image = planes[l] + begin;
        const float w0 = global.weights(0, l), w1 = global.weights(1, l), w2 = global.weights(2, l);
        const float u = inverse_scale2[l];
#pragma omp simd
        for (int i = 0; i < n; ++i) {
          const float v = image[i];
          x0[i] += w0 * v;
          x1[i] += w1 * v;
          x2[i] += w2 * v;
          const float vu = v * u;
          q1[i] += vu;
          q2[i] += vu * v;
          usable[i] += static_cast<std::uint16_t>((v - d[i] > shadow) & (v < saturation));
        }
      }
      for (int i = 0; i < n; ++i) {
        const int p = begin + i;
        if (mask && mask[p] == 0) continue;
        result->usable_lights.ptr<std::uint16_t>()[p] = usable[i];
        rejected_samples += static_cast<std::size_t>(k - usable[i]);
        if (usable[i] < 3) {
          result->flags.ptr<std::uint8_t>()[p] = static_cast<std::uint8_t>(PixelFlag::kTooFewLights);
          continue;
        }
        if (usable[i] == k || !options.exclude_unusable_samples) {
          const Eigen::Vector3d x(x0[i] - dark_weight[0] * d[i], x1[i] - dark_weight[1] * d[i],
                                  x2[i] - dark_weight[2] * d[i]);
          const double sum_b2 = q2[i] - 2.0 * d[i] * q1[i] + double(d[i]) * d[i] * sum_inverse_scale2;
          const double rss = std::max(0.0, sum_b2 - x.dot(gram * x));
          const double noise_sum = noise.read_sigma * noise.read_sigma * sum_inverse_scale2 +
                                   noise.shot_gain * std::max(0.0, q1[i] - d[i] * sum_inverse_scale2);
          const double expected_rss = noise_sum * (k - 3) / k;
          WriteSolution(p, float(x(0)), float(x(1)), float(x(2)), Confidence(rss, expected_rss, sum_b2), result);
          continue;
        }
        // Some samples are shadowed or clipped: solve on this pixel's own subset.
        // The tile was just streamed, so these reads hit cache.
        LightSubset subset{};
        for (int l = 0; l < k; ++l) {
          const float v = planes[l][p];
          samples[l] = v - d[i];
          if ((samples[l] > shadow) & (v < saturation)) subset[l / 64] |= std::uint64_t{1} << (l % 64);
        }
        auto found = cache.find(subset);
        if (found == cache.end()) {
          found = cache.emplace(subset, BuildSubsetSolver(stack, subset)).first;
          ++distinct_subsets;
        }
        const SubsetSolver& solver = found->second;
        if (!(solver.condition_number <= options.max_condition_number)) {
          result->flags.ptr<std::uint8_t>()[p] = static_cast<std::uint8_t>(PixelFlag::kIllConditioned);
          continue;
        }
        float y0 = 0.0f, y1 = 0.0f, y2 = 0.0f;
        for (int l = 0; l < k; ++l) {
          y0 += solver.weights(0, l) * samples[l];
          y1 += solver.weights(1, l) * samples[l];
          y2 += solver.weights(2, l) * samples[l];
        }
        double rss = 0.0, expected = 0.0, sum_b2 = 0.0;
        for (int l = 0; l < k; ++l) {
          if (!(subset[l / 64] >> (l % 64) & 1u)) continue;
          const double b = samples[l] / stack.light_scales[l];
          const Eigen::Vector3d& w = stack.light_directions[l];
          const double r = b - (w.x() * y0 + w.y() * y1 + w.z() * y2);
          rss += r * r;
          sum_b2 += b * b;
          expected += noise.Variance(samples[l]) * inverse_scale2[l];
        }
        expected *= static_cast<double>(usable[i] - 3) / usable[i];
        WriteSolution(p, y0, y1, y2, Confidence(rss, expected, sum_b2), result);
      }
    }
  }

  summary.samples_rejected = rejected_samples;
  summary.distinct_light_subsets = distinct_subsets;
  summary.pixels_total = static_cast<std::size_t>(pixels);
  const std::uint8_t* flags = result->flags.ptr<std::uint8_t>();
  for (int p = 0; p < pixels; ++p) {
    switch (static_cast<PixelFlag>(flags[p])) {
      case PixelFlag::kSolved: ++summary.pixels_solved; break;
      case PixelFlag::kOutsideMask: ++summary.pixels_outside_mask; break;
      case PixelFlag::kTooFewLights: ++summary.pixels_too_few_lights; break;
      case PixelFlag::kIllConditioned: ++summary.pixels_ill_conditioned; break;
      case PixelFlag::kRejectedByModel: ++summary.pixels_rejected_by_model; break;
    }
  }
  summary.solve_ms = MillisecondsSince(solve_start);
  summary.total_ms = MillisecondsSince(start);
  summary.termination = Termination::kSuccess;
  return summary;
}

}  // namespace photorig::ps
