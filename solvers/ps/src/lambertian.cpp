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

void WriteSolution(int pixel, float x0, float x1, float x2, NormalMap* out) {
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

  std::vector<const float*> planes(k);
  for (int i = 0; i < k; ++i) planes[i] = stack.images[i].ptr<float>();
  const float* dark = stack.dark.empty() ? nullptr : stack.dark.ptr<float>();
  const std::uint8_t* mask = stack.mask.empty() ? nullptr : stack.mask.ptr<std::uint8_t>();
  std::array<float, 3> dark_weight{};  // sum_k weights(:, k): dark subtraction folded into one term
  for (int c = 0; c < 3; ++c) dark_weight[c] = global.weights.row(c).sum();
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
    alignas(64) std::uint16_t usable[kTilePixels];
    std::vector<float> samples(k);

#pragma omp for schedule(dynamic, 4)
    for (int tile = 0; tile < tiles; ++tile) {
      const int begin = tile * kTilePixels;
      const int n = std::min(kTilePixels, pixels - begin);
      for (int i = 0; i < n; ++i) {
        x0[i] = x1[i] = x2[i] = 0.0f;
        usable[i] = 0;
        d[i] = dark ? dark[begin + i] : 0.0f;
      }
      // The streaming pass: every sample is read exactly once from memory.
      for (int l = 0; l < k; ++l) {
        const float* image = planes[l] + begin;
        const float w0 = global.weights(0, l), w1 = global.weights(1, l), w2 = global.weights(2, l);
#pragma omp simd
        for (int i = 0; i < n; ++i) {
          const float v = image[i];
          x0[i] += w0 * v;
          x1[i] += w1 * v;
          x2[i] += w2 * v;
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
          WriteSolution(p, x0[i] - dark_weight[0] * d[i], x1[i] - dark_weight[1] * d[i],
                        x2[i] - dark_weight[2] * d[i], result);
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
        WriteSolution(p, y0, y1, y2, result);
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
