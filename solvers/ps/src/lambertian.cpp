#include "photorig/ps/lambertian.h"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <omp.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>

namespace photorig::ps {
namespace {

using Clock = std::chrono::steady_clock;
double MillisecondsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

constexpr int kMaxLights = 65535;  // NormalMap::usable_lights is 16-bit
constexpr int kTilePixels = 1024;  // 4 KB per accumulator row: stays in L1 across all K planes

// Pseudo-inverse of the full light matrix, with 1/s_k folded in:
// x = sum_k weights(:, k) * (I_k - D).
struct GlobalSolver {
  Eigen::Matrix<float, 3, Eigen::Dynamic> weights;
  double condition_number = std::numeric_limits<double>::infinity();
};

GlobalSolver BuildGlobalSolver(const PhotometricStack& stack) {
  const int k = stack.light_count();
  GlobalSolver solver;
  solver.weights.setZero(3, k);
  Eigen::MatrixXd a(k, 3);
  for (int r = 0; r < k; ++r) a.row(r) = stack.light_directions[r].transpose();
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::Vector3d s = svd.singularValues();
  solver.condition_number = s(2) > 0.0 ? s(0) / s(2) : std::numeric_limits<double>::infinity();
  if (!std::isfinite(solver.condition_number)) return solver;
  const Eigen::MatrixXd pinv =
      svd.matrixV() * s.cwiseInverse().asDiagonal() * svd.matrixU().transpose();  // 3 x k
  for (int r = 0; r < k; ++r) solver.weights.col(r) = (pinv.col(r) / stack.light_scales[r]).cast<float>();
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

// Writes a solved pixel; false when x = 0 (all usable samples were zero after
// dark subtraction, so no direction exists) and nothing was written.
bool WriteSolution(int pixel, float x0, float x1, float x2, float confidence, NormalMap* out) {
  const float length = std::sqrt(x0 * x0 + x1 * x1 + x2 * x2);
  if (!(length > 0.0f)) return false;
  out->normals.ptr<cv::Vec3f>()[pixel] = cv::Vec3f(x0 / length, x1 / length, x2 / length);
  out->albedo.ptr<float>()[pixel] = static_cast<float>(M_PI) * length;
  out->flags.ptr<std::uint8_t>()[pixel] = static_cast<std::uint8_t>(PixelFlag::kSolved);
  out->model.ptr<std::uint8_t>()[pixel] = static_cast<std::uint8_t>(PixelModel::kLambertian);
  out->confidence.ptr<float>()[pixel] = confidence;
  return true;
}

// What the per-tile kernels need from the solve's setup.
struct TileConstants {
  const float* const* planes = nullptr;  // K planes
  int lights = 0;
  const float* weights = nullptr;         // 3 x K, row-major: the pseudo-inverse with 1/s_k folded in
  const float* inverse_scale2 = nullptr;  // K
  const double* inverse_scale = nullptr;  // K: 1 / s_k
  const double* directions = nullptr;     // K x 3, row-major: w_k
  std::array<double, 3> dark_weight{};    // row sums of weights
  std::array<double, 6> gram{};           // G = A^T A: xx, yy, zz, xy, xz, yz
  double sum_inverse_scale2 = 0.0;
  double read_variance = 0.0, shot_gain = 0.0;
  float shadow = 0.0f, saturation = 0.0f;
};

// Per-pixel sums over all K samples of one tile; 8 rows of 4 KB stay in L1.
struct TileSums {
  alignas(64) float x0[kTilePixels], x1[kTilePixels], x2[kTilePixels];
  alignas(64) float q1[kTilePixels], q2[kTilePixels];  // sum I/s^2, sum I^2/s^2
  alignas(64) float usable[kTilePixels];                // count of usable samples (exact in float)
  alignas(64) float dark[kTilePixels];
  alignas(64) float threshold[kTilePixels];             // a sample is usable when threshold < I < saturation
};

// Sums over the usable samples only (subset S), in double, for tiles with
// shadowed or clipped pixels: the normal equations G_S x = A_S^T b_S of each
// pixel, sum_S b^2 for its residual and sum_S 1/s^2, sum_S (I - D)/s^2 for
// its expected residual.
struct SubsetSums {
  alignas(64) double g[6][kTilePixels];  // G_S: xx, yy, zz, xy, xz, yz
  alignas(64) double r[3][kTilePixels];  // A_S^T b_S
  alignas(64) double b2[kTilePixels], u[kTilePixels], signal[kTilePixels];
};

// The hot loops are built for several instruction sets and the best one the
// CPU supports is picked at load time (GCC function multi-versioning): the
// library itself stays at the baseline ISA (see CMakeLists.txt). They use no
// Eigen, whose types must not cross code built for different ISAs.
#define PHOTORIG_PS_MULTIVERSION \
  __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))

// x = W I, sum I/s^2, sum I^2/s^2 and the usable-sample count of every pixel
// of the tile, in one pass over its K planes. Planes are taken four at a time
// so the accumulators are loaded and stored once per four samples.
PHOTORIG_PS_MULTIVERSION
void AccumulateTile(const TileConstants& c, int begin, int n, TileSums* t) {
  const int k = c.lights;
  const float* w0 = c.weights;
  const float* w1 = c.weights + k;
  const float* w2 = c.weights + 2 * k;
  const float* u = c.inverse_scale2;
  const float saturation = c.saturation;
  float* __restrict x0 = t->x0;
  float* __restrict x1 = t->x1;
  float* __restrict x2 = t->x2;
  float* __restrict q1 = t->q1;
  float* __restrict q2 = t->q2;
  float* __restrict usable = t->usable;
  float* __restrict threshold = t->threshold;
#pragma omp simd
  for (int i = 0; i < n; ++i) {
    threshold[i] = t->dark[i] + c.shadow;
    x0[i] = x1[i] = x2[i] = q1[i] = q2[i] = usable[i] = 0.0f;
  }
  int l = 0;
  for (; l + 4 <= k; l += 4) {
    const float* __restrict a = c.planes[l] + begin;
    const float* __restrict b = c.planes[l + 1] + begin;
    const float* __restrict e = c.planes[l + 2] + begin;
    const float* __restrict f = c.planes[l + 3] + begin;
#pragma omp simd
    for (int i = 0; i < n; ++i) {
      const float va = a[i], vb = b[i], ve = e[i], vf = f[i];
      x0[i] += w0[l] * va + w0[l + 1] * vb + w0[l + 2] * ve + w0[l + 3] * vf;
      x1[i] += w1[l] * va + w1[l + 1] * vb + w1[l + 2] * ve + w1[l + 3] * vf;
      x2[i] += w2[l] * va + w2[l + 1] * vb + w2[l + 2] * ve + w2[l + 3] * vf;
      q1[i] += u[l] * va + u[l + 1] * vb + u[l + 2] * ve + u[l + 3] * vf;
      q2[i] += u[l] * va * va + u[l + 1] * vb * vb + u[l + 2] * ve * ve + u[l + 3] * vf * vf;
      const float ti = threshold[i];
      usable[i] += static_cast<float>((va > ti) & (va < saturation)) + static_cast<float>((vb > ti) & (vb < saturation)) +
                   static_cast<float>((ve > ti) & (ve < saturation)) + static_cast<float>((vf > ti) & (vf < saturation));
    }
  }
  for (; l < k; ++l) {
    const float* __restrict a = c.planes[l] + begin;
#pragma omp simd
    for (int i = 0; i < n; ++i) {
      const float v = a[i];
      x0[i] += w0[l] * v;
      x1[i] += w1[l] * v;
      x2[i] += w2[l] * v;
      q1[i] += u[l] * v;
      q2[i] += u[l] * v * v;
      usable[i] += static_cast<float>((v > threshold[i]) & (v < saturation));
    }
  }
}

// SubsetSums of every pixel of the tile (the tile's planes are still in cache).
PHOTORIG_PS_MULTIVERSION
void AccumulateSubsetTile(const TileConstants& c, int begin, int n, const TileSums& t, SubsetSums* s) {
  for (auto* row : {s->g[0], s->g[1], s->g[2], s->g[3], s->g[4], s->g[5], s->r[0], s->r[1], s->r[2], s->b2, s->u, s->signal})
    std::fill(row, row + n, 0.0);
  // Four lights per sweep over the tile, so the twelve accumulators are
  // loaded and stored once per four samples (the rows do not fit in L1).
  constexpr int kGroup = 4;
  const float saturation = c.saturation;
  for (int first = 0; first < c.lights; first += kGroup) {
    const int count = std::min(kGroup, c.lights - first);
    const float* planes[kGroup];
    double wx[kGroup], wy[kGroup], wz[kGroup], inverse_scale[kGroup], u[kGroup];
    for (int j = 0; j < kGroup; ++j) {
      // Missing lights of the last group repeat light 0 with weight 0.
      const int l = j < count ? first + j : 0;
      planes[j] = c.planes[l] + begin;
      wx[j] = c.directions[3 * l];
      wy[j] = c.directions[3 * l + 1];
      wz[j] = c.directions[3 * l + 2];
      inverse_scale[j] = j < count ? c.inverse_scale[l] : 0.0;
      u[j] = inverse_scale[j] * inverse_scale[j];
    }
    const double present[kGroup] = {1.0, count > 1 ? 1.0 : 0.0, count > 2 ? 1.0 : 0.0, count > 3 ? 1.0 : 0.0};
#pragma omp simd
    for (int i = 0; i < n; ++i) {
      double gxx = s->g[0][i], gyy = s->g[1][i], gzz = s->g[2][i], gxy = s->g[3][i], gxz = s->g[4][i], gyz = s->g[5][i];
      double rx = s->r[0][i], ry = s->r[1][i], rz = s->r[2][i], b2 = s->b2[i], su = s->u[i], signal_sum = s->signal[i];
      for (int j = 0; j < kGroup; ++j) {
        const float v = planes[j][i];
        const double m = (v > t.threshold[i]) & (v < saturation) ? present[j] : 0.0;
        const double signal = m * (double(v) - t.dark[i]);
        const double b = signal * inverse_scale[j];
        gxx += m * (wx[j] * wx[j]);
        gyy += m * (wy[j] * wy[j]);
        gzz += m * (wz[j] * wz[j]);
        gxy += m * (wx[j] * wy[j]);
        gxz += m * (wx[j] * wz[j]);
        gyz += m * (wy[j] * wz[j]);
        rx += wx[j] * b;
        ry += wy[j] * b;
        rz += wz[j] * b;
        b2 += b * b;
        su += m * u[j];
        signal_sum += signal * u[j];
      }
      s->g[0][i] = gxx, s->g[1][i] = gyy, s->g[2][i] = gzz, s->g[3][i] = gxy, s->g[4][i] = gxz, s->g[5][i] = gyz;
      s->r[0][i] = rx, s->r[1][i] = ry, s->r[2][i] = rz, s->b2[i] = b2, s->u[i] = su, s->signal[i] = signal_sum;
    }
  }
}

// Writes every pixel of the tile as the fully lit solution: normal, albedo,
// confidence from RSS = sum b^2 - x^T G x, usable count, zero specular. The
// caller overwrites the pixels that are masked, shadowed or clipped.
PHOTORIG_PS_MULTIVERSION
void WriteLitTile(const TileConstants& c, int begin, int n, const TileSums& t, NormalMap* out) {
  float* __restrict normals = out->normals.ptr<float>() + 3 * static_cast<std::size_t>(begin);
  float* __restrict albedo = out->albedo.ptr<float>() + begin;
  float* __restrict confidence = out->confidence.ptr<float>() + begin;
  float* __restrict specular = out->specular.ptr<float>() + 2 * static_cast<std::size_t>(begin);
  std::uint8_t* __restrict flags = out->flags.ptr<std::uint8_t>() + begin;
  std::uint8_t* __restrict model = out->model.ptr<std::uint8_t>() + begin;
  std::uint16_t* __restrict usable = out->usable_lights.ptr<std::uint16_t>() + begin;
  const double k = c.lights;
  const double dof_fraction = (k - 3.0) / k;
  const double nan = std::numeric_limits<double>::quiet_NaN();
#pragma omp simd
  for (int i = 0; i < n; ++i) {
    const double d = t.dark[i];
    const double x = t.x0[i] - c.dark_weight[0] * d;
    const double y = t.x1[i] - c.dark_weight[1] * d;
    const double z = t.x2[i] - c.dark_weight[2] * d;
    const double sum_b2 = t.q2[i] - 2.0 * d * t.q1[i] + d * d * c.sum_inverse_scale2;
    const double xgx = c.gram[0] * x * x + c.gram[1] * y * y + c.gram[2] * z * z +
                       2.0 * (c.gram[3] * x * y + c.gram[4] * x * z + c.gram[5] * y * z);
    const double rss = std::max(0.0, sum_b2 - xgx);
    const double signal = std::max(0.0, t.q1[i] - d * c.sum_inverse_scale2);
    const double expected = (c.read_variance * c.sum_inverse_scale2 + c.shot_gain * signal) * dof_fraction;
    // Confidence(): expected / observed residual variance, or R^2 without a
    // noise model. Everything is computed on every lane and then selected, so
    // the loop vectorises.
    const double known = std::min(1.0, expected / rss);
    const double r2 = std::clamp(1.0 - rss / std::max(sum_b2, 1e-300), 0.0, 1.0);
    const double fit = rss > 0.0 ? (expected > 0.0 ? known : r2) : 1.0;
    const double length = std::sqrt(x * x + y * y + z * z);
    const bool solved = length > 0.0;
    const double inverse = solved ? 1.0 / length : nan;
    normals[3 * i] = static_cast<float>(x * inverse);
    normals[3 * i + 1] = static_cast<float>(y * inverse);
    normals[3 * i + 2] = static_cast<float>(z * inverse);
    albedo[i] = static_cast<float>(solved ? M_PI * length : nan);
    confidence[i] = solved ? static_cast<float>(fit) : 0.0f;
  }
  // The narrow outputs in a loop of their own: mixed with the double lanes
  // above they would force 2-wide vectors.
#pragma omp simd
  for (int i = 0; i < n; ++i) {
    const bool solved = albedo[i] > 0.0f;  // false for NaN
    flags[i] = solved ? std::uint8_t{0} : static_cast<std::uint8_t>(PixelFlag::kTooFewLights);
    model[i] = solved ? static_cast<std::uint8_t>(PixelModel::kLambertian) : std::uint8_t{0};
    usable[i] = static_cast<std::uint16_t>(t.usable[i]);
  }
  std::fill(specular, specular + 2 * n, 0.0f);
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

  const GlobalSolver global = BuildGlobalSolver(stack);
  summary.condition_number = global.condition_number;
  if (!(global.condition_number <= options.max_condition_number)) {
    summary.message = "light directions are coplanar or nearly so (condition number " +
                      std::to_string(global.condition_number) + " > " +
                      std::to_string(options.max_condition_number) + ")";
    return summary;
  }

  const int width = stack.width(), height = stack.height();
  const int pixels = width * height;
  // Every output pixel is written once by the pass below: no pre-fill passes.
  result->normals.create(height, width, CV_32FC3);
  result->albedo.create(height, width, CV_32F);
  result->flags.create(height, width, CV_8U);
  result->usable_lights.create(height, width, CV_16U);
  result->model.create(height, width, CV_8U);
  result->confidence.create(height, width, CV_32F);
  result->specular.create(height, width, CV_32FC2);

  std::vector<const float*> planes(k);
  for (int i = 0; i < k; ++i) planes[i] = stack.images[i].ptr<float>();
  const float* dark = stack.dark.empty() ? nullptr : stack.dark.ptr<float>();
  const std::uint8_t* mask = stack.mask.empty() ? nullptr : stack.mask.ptr<std::uint8_t>();
  // For the residual of fully lit pixels without a second pass:
  //   RSS = sum_k b_k^2 - x^T G x,  G = A^T A,  b_k = (I_k - D) / s_k,
  // and sum_k b_k^2 = sum I^2/s^2 - 2 D sum I/s^2 + D^2 sum 1/s^2.
  std::vector<float> weights(3 * static_cast<std::size_t>(k)), inverse_scale2(k);
  std::vector<double> inverse_scale(k), directions(3 * static_cast<std::size_t>(k));
  Eigen::Matrix3d gram = Eigen::Matrix3d::Zero();
  TileConstants constants;
  for (int i = 0; i < k; ++i) {
    for (int c = 0; c < 3; ++c) {
      weights[c * k + i] = global.weights(c, i);
      constants.dark_weight[c] += global.weights(c, i);  // dark subtraction folded into one term
    }
    inverse_scale2[i] = static_cast<float>(1.0 / (stack.light_scales[i] * stack.light_scales[i]));
    inverse_scale[i] = 1.0 / stack.light_scales[i];
    for (int c = 0; c < 3; ++c) directions[3 * i + c] = stack.light_directions[i](c);
    constants.sum_inverse_scale2 += inverse_scale2[i];
    gram += stack.light_directions[i] * stack.light_directions[i].transpose();
  }
  constants.planes = planes.data();
  constants.lights = k;
  constants.weights = weights.data();
  constants.inverse_scale2 = inverse_scale2.data();
  constants.inverse_scale = inverse_scale.data();
  constants.directions = directions.data();
  constants.gram = {gram(0, 0), gram(1, 1), gram(2, 2), gram(0, 1), gram(0, 2), gram(1, 2)};
  const NoiseModel noise = stack.noise;
  constants.read_variance = noise.read_sigma * noise.read_sigma;
  constants.shot_gain = noise.shot_gain;
  constants.shadow = static_cast<float>(options.shadow_threshold);
  constants.saturation = std::isfinite(options.saturation_level) ? static_cast<float>(options.saturation_level)
                                                                   : std::numeric_limits<float>::infinity();
  const double max_condition2 = options.max_condition_number * options.max_condition_number;
  summary.setup_ms = MillisecondsSince(start);

  const auto solve_start = Clock::now();
  const int tiles = (pixels + kTilePixels - 1) / kTilePixels;
  std::size_t rejected_samples = 0, on_subset = 0;
  std::size_t solved = 0, outside_mask = 0, too_few = 0, ill_conditioned = 0;
  const int threads = options.num_threads > 0 ? options.num_threads : omp_get_max_threads();

#pragma omp parallel num_threads(threads) \
    reduction(+ : rejected_samples, on_subset, solved, outside_mask, too_few, ill_conditioned)
  {
    TileSums sums;
    const auto subset_sums = std::make_unique<SubsetSums>();  // 96 KB: heap, not the thread's stack
    auto unsolved = [&](int p, PixelFlag flag) {
      result->normals.ptr<cv::Vec3f>()[p] = cv::Vec3f::all(std::numeric_limits<float>::quiet_NaN());
      result->albedo.ptr<float>()[p] = std::numeric_limits<float>::quiet_NaN();
      result->flags.ptr<std::uint8_t>()[p] = static_cast<std::uint8_t>(flag);
      result->model.ptr<std::uint8_t>()[p] = static_cast<std::uint8_t>(PixelModel::kNone);
      result->confidence.ptr<float>()[p] = 0.0f;
    };

#pragma omp for schedule(dynamic, 4)
    for (int tile = 0; tile < tiles; ++tile) {
      const int begin = tile * kTilePixels;
      const int n = std::min(kTilePixels, pixels - begin);
      for (int i = 0; i < n; ++i) sums.dark[i] = dark ? dark[begin + i] : 0.0f;
      // The streaming pass: every sample is read exactly once from memory.
      AccumulateTile(constants, begin, n, &sums);
      // Every pixel as if fully lit; the loop below corrects the others.
      WriteLitTile(constants, begin, n, sums, result);
      bool subset_ready = false;
      for (int i = 0; i < n; ++i) {
        const int p = begin + i;
        const int usable = static_cast<int>(sums.usable[i]);
        if (mask && mask[p] == 0) {
          unsolved(p, PixelFlag::kOutsideMask);
          result->usable_lights.ptr<std::uint16_t>()[p] = 0;
          ++outside_mask;
          continue;
        }
        rejected_samples += static_cast<std::size_t>(k - usable);
        if (usable < 3) {
          unsolved(p, PixelFlag::kTooFewLights);
          ++too_few;
          continue;
        }
        if (usable == k || !options.exclude_unusable_samples) {
          if (result->flags.ptr<std::uint8_t>()[p] == static_cast<std::uint8_t>(PixelFlag::kSolved)) {
            ++solved;
          } else {
            // All usable samples were zero after dark subtraction: no direction exists.
            unsolved(p, PixelFlag::kTooFewLights);
            ++too_few;
          }
          continue;
        }
        // Some samples are shadowed or clipped: solve this pixel's normal
        // equations on its usable subset (least squares on the subset, as the
        // subset's pseudo-inverse would give).
        if (!subset_ready) {
          AccumulateSubsetTile(constants, begin, n, sums, subset_sums.get());
          subset_ready = true;
        }
        const SubsetSums& ss = *subset_sums;
        Eigen::Matrix3d g;
        g << ss.g[0][i], ss.g[3][i], ss.g[4][i], ss.g[3][i], ss.g[1][i], ss.g[5][i], ss.g[4][i], ss.g[5][i], ss.g[2][i];
        // cond(A_S) = sqrt(cond(G_S)), G_S = A_S^T A_S. The Frobenius-norm
        // condition number |G| |G^-1| bounds the spectral one from above, so
        // the exact (eigenvalue) test is only needed when that bound fails.
        const double det = g.determinant();
        const Eigen::Matrix3d inverse = g.inverse();
        const double bound = g.norm() * inverse.norm();
        if (!(det > 0.0) || !(bound <= max_condition2)) {
          Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen;
          eigen.computeDirect(g, Eigen::EigenvaluesOnly);
          const Eigen::Vector3d lambda = eigen.eigenvalues();  // ascending
          if (!(lambda(0) > 0.0) || !(lambda(2) <= max_condition2 * lambda(0))) {
            unsolved(p, PixelFlag::kIllConditioned);
            ++ill_conditioned;
            continue;
          }
        }
        ++on_subset;
        const Eigen::Vector3d rhs(ss.r[0][i], ss.r[1][i], ss.r[2][i]);
        const Eigen::Vector3d x = inverse * rhs;
        const double rss = std::max(0.0, ss.b2[i] - x.dot(rhs));
        const double expected = (constants.read_variance * ss.u[i] + constants.shot_gain * ss.signal[i]) *
                                static_cast<double>(usable - 3) / usable;
        if (WriteSolution(p, float(x(0)), float(x(1)), float(x(2)), Confidence(rss, expected, ss.b2[i]), result)) {
          ++solved;
        } else {
          unsolved(p, PixelFlag::kTooFewLights);
          ++too_few;
        }
      }
    }
  }

  summary.samples_rejected = rejected_samples;
  summary.pixels_on_light_subsets = on_subset;
  summary.pixels_total = static_cast<std::size_t>(pixels);
  summary.pixels_solved = solved;
  summary.pixels_outside_mask = outside_mask;
  summary.pixels_too_few_lights = too_few;
  summary.pixels_ill_conditioned = ill_conditioned;
  summary.solve_ms = MillisecondsSince(solve_start);
  summary.total_ms = MillisecondsSince(start);
  summary.termination = Termination::kSuccess;
  return summary;
}

}  // namespace photorig::ps
