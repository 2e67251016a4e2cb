#include "photorig/solvers/ps/near_lights.h"

#include "photorig/solvers/ps/evaluation.h"

#include "kernels/near_lambertian_sums.h"
#include "lobe_sharing.h"
#include "model_selection.h"
#include "per_pixel_fits.h"

#include <boost/math/tools/minima.hpp>
#include <omp.h>
#include <opencv2/imgproc.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <vector>

namespace photorig::solvers::ps {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
// The rounds' lattice leaves at least this many pixels across the object
// (NearLightOptions::round_step_px).
constexpr int kRoundLatticeSidePx = 32;
// The depth search's grid leaves about this many pixels across the object
// (NearLightOptions::offset_stride): a few hundred pixels in all.
constexpr int kOffsetGridSidePx = 16;

double RadiansToDegrees(double radians) { return radians * 180.0 / kPi; }

// What every pixel's fit reads: the stack's samples and the lights'
// geometry, fixed for the whole solve. Its pixels are those of a lattice of
// the image (every step-th pixel of every step-th row from (origin,
// origin)); its pixel (r, c) is the image's (origin + step r, origin + step c).
struct PixelProblem {
  const PhotometricStack& stack;
  std::vector<camera::PreparedNearLight> prepared;  // the same LEDs, for one sample at a time
  internal::NearLightTable lights;
  // One per light, the lattice's samples row after row without padding: the
  // kernel reads neighbouring lanes as one vector.
  std::vector<const float*> planes;
  std::vector<cv::Mat> copies;  // the planes, where the images themselves do not serve
  int step = 1, origin = 0;
  camera::PixelRays rays;  // the lattice's
  internal::NearSampleRules rules;
  double max_condition_number = 0.0;
  const float* dark_data = nullptr;  // the stack's dark frame; null without one
  const std::uint8_t* mask_data = nullptr;  // its mask; null without one
  std::size_t dark_stride = 0, mask_stride = 0;  // their rows' strides, in elements

  PixelProblem(const PhotometricStack& stack, const std::vector<camera::NearLight>& leds, const camera::Camera& camera)
      : stack(stack), rays(camera) {
    if (!stack.dark.empty()) dark_data = stack.dark.ptr<float>(), dark_stride = stack.dark.step1();
    if (!stack.mask.empty()) mask_data = stack.mask.ptr<std::uint8_t>(), mask_stride = stack.mask.step1();
    for (std::size_t k = 0; k < leds.size(); ++k) {
      const camera::PreparedNearLight& light = prepared.emplace_back(leds[k]);
      lights.position.insert(lights.position.end(), {light.position_mm.x(), light.position_mm.y(), light.position_mm.z()});
      lights.axis.insert(lights.axis.end(), {light.axis.x(), light.axis.y(), light.axis.z()});
      lights.cos_exponent.push_back(light.cos_exponent);
      lights.constant.push_back(stack.light_scales[k] * light.scale);
      lights.w.push_back(light.w);
    }
    bool continuous = true;
    for (const cv::Mat& image : stack.images) continuous = continuous && image.isContinuous();
    if (!continuous)
      for (const cv::Mat& image : stack.images) copies.push_back(image.clone());
    for (const cv::Mat& image : continuous ? stack.images : copies) planes.push_back(image.ptr<float>());
  }

  // The same problem on the lattice of every step-th pixel from (origin,
  // origin), its samples copied out of the images.
  PixelProblem Lattice(int lattice_step, int lattice_origin) const {
    if (lattice_step == step && lattice_origin == origin) return *this;
    PixelProblem lattice = *this;
    lattice.step = lattice_step, lattice.origin = lattice_origin;
    lattice.rays = rays.Lattice(lattice_step, lattice_origin);
    const int count = static_cast<int>(stack.images.size());
    lattice.copies.assign(count, cv::Mat());
    lattice.planes.assign(count, nullptr);
    // Each sample is a line of its own in a plane of the whole image: the
    // planes in parallel keep twice as many of those reads in flight.
#pragma omp parallel for schedule(static)
    for (int k = 0; k < count; ++k) {
      cv::Mat& samples = lattice.copies[k];
      samples.create(lattice.rows(), lattice.cols(), CV_32F);
      for (int r = 0; r < samples.rows; ++r) {
        const float* in = stack.images[k].ptr<float>(lattice.ImageRow(r)) + lattice.origin;
        float* out = samples.ptr<float>(r);
        for (int c = 0; c < samples.cols; ++c) out[c] = in[lattice.step * c];
      }
      lattice.planes[k] = samples.ptr<float>();
    }
    return lattice;
  }
  int rows() const { return rays.camera().height_px; }
  int cols() const { return rays.camera().width_px; }
  cv::Size size() const { return {cols(), rows()}; }
  int ImageRow(int r) const { return origin + step * r; }
  int ImageCol(int c) const { return origin + step * c; }
  // Where pixel (r, c)'s sample lies in every plane.
  int SampleIndex(int r, int c) const { return r * cols() + c; }
  // Read for every pixel of every pass: through plain pointers, not cv::Mat's out-of-line empty().
  double Dark(int r, int c) const { return dark_data ? dark_data[ImageRow(r) * dark_stride + ImageCol(c)] : 0.0; }
  bool InMask(int r, int c) const { return !mask_data || mask_data[ImageRow(r) * mask_stride + ImageCol(c)] != 0; }

  Eigen::Vector3d Point(int r, int c, double z_mm) const { return rays.Point(r, c, z_mm); }
  // The height of a pixel whose integrated height is `relative` (0 at the
  // reference) with the surface placed at offset_mm: a shift along z for an
  // orthographic camera, a scale about the pinhole's centre for a pinhole.
  double Height(float relative, double offset_mm) const {
    if (!rays.camera().IsPinhole()) return relative + offset_mm;
    const double d = rays.camera().pinhole.distance_mm;
    return d - (d - relative) * (d - offset_mm) / d;
  }
};

struct PixelAt {
  int r = 0, c = 0;
  double z_mm = 0.0;  // the height of its surface point
};

struct PixelFit {
  PixelFlag flag = PixelFlag::kSolved;
  Eigen::Vector3d b = Eigen::Vector3d::Zero();  // rho / pi * n
  double length = 0.0, inverse_length = 0.0;    // |b| = rho / pi, and 1 / |b|
  float confidence = 0.0f;                      // as WriteConfidence gives it for these 3 parameters
  int usable = 0;
  double chi_square = 0.0;  // weighted by the noise where it is known
};

// Lane j's weighted least squares of I_k - D = s_k f_k(x) (b . l_k(x));
// a lane that failed the conditioning screen is tested exactly (its normal
// matrix's eigenvalues) and solved again.
PixelFit SolveLane(const PixelProblem& p, const internal::NearLaneFits& lanes, int j) {
  PixelFit fit;
  fit.usable = static_cast<int>(lanes.usable[j]);
  if (fit.usable < 3) {
    fit.flag = PixelFlag::kTooFewLights;
    return fit;
  }
  fit.b = Eigen::Vector3d(lanes.b[0][j], lanes.b[1][j], lanes.b[2][j]);
  fit.length = lanes.length[j], fit.inverse_length = lanes.inverse_length[j];
  fit.chi_square = lanes.chi_square[j];
  fit.confidence = static_cast<float>(lanes.confidence[j]);
  if (!lanes.conditioned[j]) {
    const auto& m = lanes.matrix;
    Eigen::Matrix3d normal_matrix;
    normal_matrix << m[0][j], m[1][j], m[2][j], m[1][j], m[3][j], m[4][j], m[2][j], m[4][j], m[5][j];
    const Eigen::Vector3d rhs(lanes.rhs[0][j], lanes.rhs[1][j], lanes.rhs[2][j]);
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen;
    eigen.computeDirect(normal_matrix, Eigen::EigenvaluesOnly);
    const double smallest = eigen.eigenvalues()(0), largest = eigen.eigenvalues()(2);
    // The normal matrix holds A^T W A: its eigenvalues are squared singular values.
    if (!(smallest > 0.0) || std::sqrt(largest / smallest) > p.max_condition_number) {
      fit.flag = PixelFlag::kIllConditioned;
      return fit;
    }
    // The same system's solution (the chi-square above is its residuals').
    fit.b = normal_matrix.ldlt().solve(rhs);
    fit.length = fit.b.norm(), fit.inverse_length = 1.0 / fit.length;
  }
  if (!(fit.length > 0.0)) fit.flag = PixelFlag::kRejectedByModel;
  return fit;
}

// The kernel's lanes for pixels[start, start + kNearLanes): spare lanes
// past the end repeat the last pixel.
internal::NearLanePixels LanePixels(const PixelProblem& p, std::span<const PixelAt> pixels, std::size_t start) {
  internal::NearLanePixels batch;
  const std::size_t last = pixels.size() - 1;
  for (int j = 0; j < internal::kNearLanes; ++j) {
    const PixelAt& at = pixels[std::min(start + j, last)];
    const Eigen::Vector3d point = p.Point(at.r, at.c, at.z_mm);
    batch.x[j] = static_cast<float>(point.x()), batch.y[j] = static_cast<float>(point.y());
    batch.z[j] = static_cast<float>(point.z());
    batch.dark[j] = static_cast<float>(p.Dark(at.r, at.c));
    batch.offset[j] = p.SampleIndex(at.r, at.c);
  }
  return batch;
}

// The kernel's lanes for row r's pixels columns[0, kNearLanes), their
// surface points at height[c]: spare lanes past the end repeat the last.
internal::NearLanePixels RowLanePixels(const PixelProblem& p, int r, std::span<const int> columns, const float* height) {
  using internal::kNearLanes;
  internal::NearLanePixels batch;
  int c[kNearLanes];
  float z[kNearLanes];
  const std::size_t last = columns.size() - 1;
  for (int j = 0; j < kNearLanes; ++j) c[j] = columns[std::min<std::size_t>(j, last)], z[j] = height[c[j]];
  p.rays.RowPoints(r, c, z, kNearLanes, batch.x, batch.y, batch.z);
  const float* dark = p.dark_data ? p.dark_data + p.ImageRow(r) * p.dark_stride : nullptr;
  for (int j = 0; j < kNearLanes; ++j) {
    batch.dark[j] = dark ? dark[p.ImageCol(c[j])] : 0.0f;
    batch.offset[j] = p.SampleIndex(r, c[j]);
  }
  return batch;
}

// fits[i]: pixels[i]'s fit over its usable samples, kNearLanes pixels at a time.
void FitPixels(const PixelProblem& p, std::span<const PixelAt> pixels, std::span<PixelFit> fits) {
  using internal::kNearLanes;
  std::vector<float> rows;
  internal::NearLaneFits lanes;
  for (std::size_t start = 0; start < pixels.size(); start += kNearLanes) {
    const int n = static_cast<int>(std::min<std::size_t>(kNearLanes, pixels.size() - start));
    internal::FitNearLanes(p.lights, p.planes.data(), p.rules, p.max_condition_number, LanePixels(p, pixels, start),
                           &rows, &lanes);
    for (int j = 0; j < n; ++j) fits[start + j] = SolveLane(p, lanes, j);
  }
}

// The residual variance against the noise's (1 at the noise level) of a fit
// with `parameters` of its own; nothing to test with no sample to spare or
// without a noise model.
void WriteConfidence(const internal::NearSampleRules& rules, int used, int parameters, double chi_square, float* out) {
  const int dof = used - parameters;
  *out = rules.noise_known && dof > 0 ? static_cast<float>(std::min(1.0, dof / std::max(chi_square, 1e-300))) : 0.0f;
}

// The maps of a fit of every pixel, their values left for FitAllPixels to write.
void AllocateResult(const cv::Size size, NormalMap* result) {
  result->normals.create(size, CV_32FC3);
  result->albedo.create(size, CV_32F);
  result->flags.create(size, CV_8U);
  result->usable_lights.create(size, CV_16U);
  result->model.create(size, CV_8U);
  result->confidence.create(size, CV_32F);
  result->specular.create(size, CV_32FC2);
}

// Row r of every map of a NormalMap, as plain pointers: a pass writes
// every pixel of its rows.
struct MapRow {
  float *normal, *albedo, *confidence, *specular;
  std::uint8_t *flag, *model;
  std::uint16_t* usable;
  MapRow(NormalMap* map, int r)
      : normal(map->normals.ptr<float>(r)), albedo(map->albedo.ptr<float>(r)),
        confidence(map->confidence.ptr<float>(r)), specular(map->specular.ptr<float>(r)),
        flag(map->flags.ptr<std::uint8_t>(r)), model(map->model.ptr<std::uint8_t>(r)),
        usable(map->usable_lights.ptr<std::uint16_t>(r)) {}
  // Pixel c without a normal (flag says why), its lobe cleared.
  void Unsolved(int c, PixelFlag why, int used) const {
    normal[3 * c] = normal[3 * c + 1] = normal[3 * c + 2] = kNaN;
    albedo[c] = kNaN, confidence[c] = 0.0f, specular[2 * c] = specular[2 * c + 1] = 0.0f;
    flag[c] = static_cast<std::uint8_t>(why), model[c] = static_cast<std::uint8_t>(PixelModel::kNone);
    usable[c] = static_cast<std::uint16_t>(std::min(used, 65535));
  }
};

// Every pixel of the mask fitted with its surface at height_mm, every map
// of *result written whole (AllocateResult); each fit's chi-square into
// *chi_square (CV_32F) unless null. A lane the kernel solved and found well
// conditioned is written from the kernel's numbers as they stand; only the
// rest go through SolveLane.
void FitAllPixels(const PixelProblem& p, const cv::Mat& height_mm, NormalMap* result, cv::Mat* chi_square = nullptr) {
  using internal::kNearLanes;
  if (chi_square) chi_square->create(height_mm.size(), CV_32F);
#pragma omp parallel
  {
    std::vector<int> columns;  // the row's pixels in the mask
    std::vector<float> rows;
    internal::NearLaneFits lanes;
#pragma omp for schedule(dynamic, 4)
    for (int r = 0; r < p.rows(); ++r) {
      const MapRow out(result, r);
      const float* height = height_mm.ptr<float>(r);
      columns.clear();
      for (int c = 0; c < p.cols(); ++c)
        if (p.InMask(r, c))
          columns.push_back(c);
        else
          out.Unsolved(c, PixelFlag::kOutsideMask, 0);
      float* chi = chi_square ? chi_square->ptr<float>(r) : nullptr;
      for (std::size_t start = 0; start < columns.size(); start += kNearLanes) {
        const int n = static_cast<int>(std::min<std::size_t>(kNearLanes, columns.size() - start));
        internal::FitNearLanes(p.lights, p.planes.data(), p.rules, p.max_condition_number,
                               RowLanePixels(p, r, std::span<const int>(columns).subspan(start), height), &rows, &lanes);
        for (int j = 0; j < n; ++j) {
          const int c = columns[start + j];
          const int usable = static_cast<int>(lanes.usable[j]);
          if (chi) chi[c] = usable < 3 ? 0.0f : static_cast<float>(lanes.chi_square[j]);  // as SolveLane leaves it
          double b[3] = {lanes.b[0][j], lanes.b[1][j], lanes.b[2][j]};
          double length = lanes.length[j], inverse_length = lanes.inverse_length[j];
          if (!(lanes.conditioned[j] && usable >= 3 && length > 0.0)) {
            const PixelFit fit = SolveLane(p, lanes, j);
            if (fit.flag != PixelFlag::kSolved) {
              out.Unsolved(c, fit.flag, fit.usable);
              continue;
            }
            b[0] = fit.b.x(), b[1] = fit.b.y(), b[2] = fit.b.z();
            length = fit.length, inverse_length = fit.inverse_length;
          }
          out.normal[3 * c] = static_cast<float>(b[0] * inverse_length);
          out.normal[3 * c + 1] = static_cast<float>(b[1] * inverse_length);
          out.normal[3 * c + 2] = static_cast<float>(b[2] * inverse_length);
          out.albedo[c] = static_cast<float>(kPi * length), out.confidence[c] = static_cast<float>(lanes.confidence[j]);
          out.specular[2 * c] = out.specular[2 * c + 1] = 0.0f;
          out.flag[c] = static_cast<std::uint8_t>(PixelFlag::kSolved);
          out.model[c] = static_cast<std::uint8_t>(PixelModel::kLambertian);
          out.usable[c] = static_cast<std::uint16_t>(std::min(usable, 65535));
        }
      }
    }
  }
}

// A pixel's samples as the fits past the Lambertian pass read them, with
// its surface point at height z_mm: per light the dark-subtracted value,
// 1 / sigma (0: unusable), the unit vector towards the LED and its
// irradiance gain s_k f_k(x).
struct NearPixelSamples {
  std::vector<double> observed, inverse_sigma, towards, gain;

  void Read(const PixelProblem& p, int r, int c, double z_mm) {
    const int lights = p.lights.count();
    observed.resize(lights), inverse_sigma.resize(lights), towards.resize(3 * lights), gain.resize(lights);
    const internal::NearSampleRules& rules = p.rules;
    const int pixel = p.SampleIndex(r, c);
    const Eigen::Vector3d point = p.Point(r, c, z_mm);
    const double dark_dn = p.Dark(r, c);
    for (int k = 0; k < lights; ++k) {
      const double value = p.planes[k][pixel], signal = value - dark_dn;
      Eigen::Vector3d to;
      gain[k] = p.stack.light_scales[k] * p.prepared[k].RelativeIrradiance(point, &to);
      const bool usable = signal > rules.shadow_threshold && value < rules.saturation_level && gain[k] > 0.0;
      const double variance = rules.read_variance + rules.shot_gain * std::max(signal, 0.0);
      observed[k] = signal;
      inverse_sigma[k] = !usable ? 0.0 : rules.noise_known ? 1.0 / std::sqrt(variance) : 1.0;
      for (int axis = 0; axis < 3; ++axis) towards[3 * k + axis] = to[axis];
    }
  }
};

// A pixel the method refits, with its surface at z_mm, from its Lambertian fit.
struct RefitPixel {
  int r = 0, c = 0;
  double z_mm = 0.0;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double albedo = 0.0;
};

// A refit, and what the depth search sums for it: its chi-square, or for
// IRLS twice its loss over every usable sample (TwiceLoss), which does not
// jump as samples cross the inlier weight.
struct RefitAnswer {
  internal::PixelFit fit;
  double objective = 0.0;
};

// The method's fit of pixels the Lambertian model leaves unexplained, each
// with its own light vectors, gains and line of sight: `robust` by the
// distant method's IRLS lanes, on rows s_k f_k(x) l_k(x), so that highlights
// and inter-reflections lose their pull as under distant lights;
// `blinn-phong` and `auto` by its Blinn-Phong lanes with a diffuse term and a
// normalised lobe, the samples divided by their gains (which scale the whole
// model) and their sigmas likewise; and `auto`'s steps 5 and 6 (shared and
// GGX lobes, lobe_sharing.h) on the same rows. One per thread.
class NearRefitter {
 public:
  NearRefitter(const PixelProblem& p, const PhotometricStereoOptions& options)
      : p_(p), lights_(p.lights.count()), loss_(options.robust.loss), irls_(lights_, options.robust) {
    if (options.method != Method::kRobust) lobes_.emplace(lights_, options.blinn_phong);
    if (options.method == Method::kAuto) ggx_.emplace(lights_, options.blinn_phong, internal::LaneLobe::kGgx);
  }

  void Fit(std::span<const RefitPixel> pixels, std::span<RefitAnswer> answers) {
    Read(pixels);
    FitRobust(pixels, answers);
    if (lobes_) FitLobes(pixels, answers);
  }

  // Step 5 for `items` (pixels of the map, whose surface is at height_mm):
  // as LobeSharingFits::share, a pixel that takes its held lobe marked in *held.
  void ShareLobe(const internal::ModelLadder& ladder, std::span<const internal::SharedLobeItem> items,
                 const cv::Mat& height_mm, std::vector<internal::SharedShapeTest>* tests, NormalMap* map,
                 std::vector<std::uint8_t>* held) {
    for (std::size_t first = 0; first < items.size(); first += kLobeBatch) {
      const std::size_t count = std::min(kLobeBatch, items.size() - first);
      ReadMapPixels(items.subspan(first, count), height_mm, [](const internal::SharedLobeItem& item) { return item.pixel; });
      candidates_.clear();
      for (std::size_t i = 0; i < count; ++i) {
        internal::SharingCandidate candidate;
        candidate.item = &items[first + i];
        candidate.kept = internal::FitInMap(*map, candidate.item->pixel);
        candidate.lambertian = LambertianOnRow(i, candidate.kept);
        if (ladder.NextWithSharedLobe(candidate.Fits()).action != internal::LadderStep::Action::kFitSharedLobe) continue;
        candidate.problem = LobeRow(i);
        candidates_.push_back(candidate);
      }
      internal::ClimbSharedLobes(ladder, *lobes_, candidates_,
                                 [&](const internal::SharingCandidate& candidate, const internal::PixelFit& chosen) {
                                   if (tests) {
                                     ladder.AddToShapeTest(candidate.Fits(), &(*tests)[candidate.item->region]);
                                   } else if (&chosen != &candidate.kept) {
                                     internal::WriteFitToMap(candidate.item->pixel, chosen, map);
                                     (*held)[candidate.item->pixel] = 1;
                                   }
                                 });
    }
  }

  // Step 6 for `pixels` of the map (LobeSharingFits::offer_ggx, `test`
  // its); held: the pixels whose lobe step 5 held.
  void OfferGgx(const internal::ModelLadder& ladder, std::span<const int> pixels, const cv::Mat& height_mm,
                const std::vector<std::uint8_t>& held, internal::SharedShapeTest* test, NormalMap* map) {
    for (std::size_t first = 0; first < pixels.size(); first += kLobeBatch) {
      const std::size_t count = std::min(kLobeBatch, pixels.size() - first);
      ReadMapPixels(pixels.subspan(first, count), height_mm, [](int pixel) { return pixel; });
      offers_.clear();
      for (std::size_t i = 0; i < count; ++i) {
        internal::GgxCandidate offer;
        offer.pixel = pixels[first + i];
        offer.held = !held.empty() && held[offer.pixel] != 0;
        offer.kept = internal::FitInMap(*map, offer.pixel);
        offer.on_samples = KeptOnUsable(i, offer.kept, offer.held);
        if (ladder.NextWithGgx(internal::GgxFits{&offer.on_samples}).action != internal::LadderStep::Action::kFitGgx)
          continue;
        offer.problem = LobeRow(i);
        offers_.push_back(offer);
      }
      if (test) {
        internal::TestGgx(ladder, *ggx_, offers_, test);
        continue;
      }
      internal::ClimbGgx(ladder, *ggx_, offers_, [&](const internal::GgxCandidate& offer, const internal::PixelFit& ggx) {
        internal::WriteFitToMap(offer.pixel, ggx, map);
      });
    }
  }

  // Step 7 for `pixels` of the map (ModelLadder::NextWithLowFrequency), each
  // at its surface's height with its own light and view vectors; held: the
  // pixels whose lobe step 5 held (empty: none), shape_rejected: the pixels
  // of regions that reject one Blinn-Phong shape (empty: none). Into the map
  // if `write`; adds how many fell back to *fell_back, the pixels each
  // rule gave the fit to *rules and the lobe-shift tests to *tally.
  void OfferLowFrequency(const internal::ModelLadder& ladder, const PhotometricStereoOptions& options,
                         std::span<const int> pixels, const cv::Mat& height_mm, const std::vector<std::uint8_t>& held,
                         const std::vector<std::uint8_t>& shape_rejected, bool test_lobe_shift, bool write,
                         NormalMap* map, std::size_t* fell_back, LowFrequencyRuleCounts* rules,
                         internal::LobeShiftTally* tally) {
    internal::LowFrequencyFitter fitter(options.selection.spike_fraction);
    for (std::size_t first = 0; first < pixels.size(); first += kLobeBatch) {
      const std::size_t count = std::min(kLobeBatch, pixels.size() - first);
      ReadMapPixels(pixels.subspan(first, count), height_mm, [](int pixel) { return pixel; });
      for (std::size_t i = 0; i < count; ++i) {
        const int pixel = pixels[first + i];
        const internal::PixelFit kept = internal::FitInMapWithChi2(*map, pixel, !held.empty() && held[pixel] != 0);
        const double* w = &geometry_[6 * i * lights_];
        const internal::LowFrequencyProblem problem{.lights = lights_,
                                                    .wx = w,
                                                    .wy = w + 1,
                                                    .wz = w + 2,
                                                    .stride = 6,
                                                    .view = views_[i],
                                                    .observed = &scaled_[i * lights_],
                                                    .inverse_sigma = &scaled_inverse_sigma_[i * lights_]};
        const internal::LowFrequencyOffer offer{
            .region_rejects_shape = !shape_rejected.empty() && shape_rejected[pixel] != 0,
            .test_lobe_shift = test_lobe_shift,
            .min_exponent = options.blinn_phong.min_exponent};
        bool fell = false;
        internal::LowFrequencyRule rule = internal::LowFrequencyRule::kNone;
        const internal::PixelFit chosen =
            internal::ClimbLowFrequency(ladder, fitter, kept, problem, offer, &fell, write ? nullptr : tally, &rule);
        if (!write) continue;
        if (chosen.model == PixelModel::kLowFrequency) {
          internal::WriteFitToMap(pixel, chosen, map);
          internal::CountRule(rule, rules);
        }
        *fell_back += fell;
      }
    }
  }

 private:
  // Steps 5 and 6 read and fit this many pixels at a time.
  static constexpr std::size_t kLobeBatch = 64;

  // Every pixel's samples, IRLS rows and (for the lobes) scaled samples and geometry.
  void Read(std::span<const RefitPixel> pixels) {
    const std::size_t n = pixels.size();
    observed_.resize(n * lights_), inverse_sigma_.resize(n * lights_), rows_.resize(3 * n * lights_);
    if (lobes_)
      scaled_.resize(n * lights_), scaled_inverse_sigma_.resize(n * lights_), geometry_.resize(6 * n * lights_),
          views_.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      const RefitPixel& at = pixels[i];
      samples_.Read(p_, at.r, at.c, at.z_mm);
      std::copy(samples_.observed.begin(), samples_.observed.end(), &observed_[i * lights_]);
      std::copy(samples_.inverse_sigma.begin(), samples_.inverse_sigma.end(), &inverse_sigma_[i * lights_]);
      for (int k = 0; k < lights_; ++k)
        for (int axis = 0; axis < 3; ++axis)
          rows_[3 * (i * lights_ + k) + axis] = samples_.gain[k] * samples_.towards[3 * k + axis];
      if (!lobes_) continue;
      for (int k = 0; k < lights_; ++k) {
        const double gain = samples_.gain[k];
        const bool lit = gain > 0.0 && samples_.inverse_sigma[k] > 0.0;
        scaled_[i * lights_ + k] = lit ? samples_.observed[k] / gain : 0.0;
        scaled_inverse_sigma_[i * lights_ + k] = lit ? samples_.inverse_sigma[k] * gain : 0.0;
      }
      views_[i] = p_.rays.ViewDirection(at.r, at.c);
      internal::BlinnPhongGeometry(lights_, samples_.towards.data(), views_[i], &geometry_[6 * i * lights_]);
    }
  }

  // Read() for pixels of the map (`index_of` an entry's index into it), each
  // at its surface's height.
  template <typename Entry, typename IndexOf>
  void ReadMapPixels(std::span<const Entry> entries, const cv::Mat& height_mm, IndexOf index_of) {
    map_pixels_.clear();
    for (const Entry& entry : entries) {
      const int pixel = index_of(entry), r = pixel / p_.cols(), c = pixel % p_.cols();
      map_pixels_.push_back({r, c, height_mm.at<float>(r, c)});
    }
    Read(map_pixels_);
  }

  // Pixel i's row as a lobe fit reads it: samples over their gains, geometry and view.
  internal::LobeProblem LobeRow(std::size_t i) const {
    internal::LobeProblem problem;
    problem.observed = &scaled_[i * lights_], problem.inverse_sigma = &scaled_inverse_sigma_[i * lights_];
    problem.geometry = &geometry_[6 * i * lights_], problem.view = views_[i];
    return problem;
  }

  // Step 5's Lambertian fit of pixel i's lit samples (LambertianOnRow) in the lobe's units.
  internal::PixelFit LambertianOnRow(std::size_t i, const internal::PixelFit& kept) const {
    const double* w = &geometry_[6 * i * lights_];
    return internal::LambertianOnRow(lights_, w, w + 1, w + 2, 6, &scaled_[i * lights_], &scaled_inverse_sigma_[i * lights_],
                                     kept.normal * kept.albedo / kPi);
  }

  // Step 6's judgement of the fit pixel i kept on its lit samples: a lobe's
  // chi-square at its parameters (3 of its own where step 5 held it), a
  // Lambertian fit's as step 5 takes it.
  internal::PixelFit KeptOnUsable(std::size_t i, const internal::PixelFit& kept, bool held) const {
    if (kept.model != PixelModel::kBlinnPhong) {
      internal::PixelFit on_samples = LambertianOnRow(i, kept);
      on_samples.normal = kept.normal;  // the kept fit is where the GGX fit starts
      return on_samples;
    }
    const double* geometry = &geometry_[6 * i * lights_];
    std::vector<int> lit;
    for (int k = 0; k < lights_; ++k)
      if (scaled_inverse_sigma_[i * lights_ + k] > 0.0) lit.push_back(k);
    Eigen::Matrix<double, Eigen::Dynamic, 3> directions(lit.size(), 3);
    Eigen::VectorXd observed(lit.size()), inverse_sigma(lit.size());
    for (std::size_t j = 0; j < lit.size(); ++j) {
      const int k = lit[j];
      directions.row(j) = Eigen::RowVector3d(geometry[6 * k], geometry[6 * k + 1], geometry[6 * k + 2]);
      observed[j] = scaled_[i * lights_ + k], inverse_sigma[j] = scaled_inverse_sigma_[i * lights_ + k];
    }
    internal::PixelFit on_samples = kept;
    on_samples.chi2 = internal::BlinnPhongChi2(directions, observed, inverse_sigma, views_[i], kept);
    on_samples.ok = std::isfinite(on_samples.chi2);
    on_samples.used = static_cast<int>(lit.size());
    on_samples.parameters = held ? internal::kSharedLobeParameters : internal::kBlinnPhongParameters;
    return on_samples;
  }

  void FitRobust(std::span<const RefitPixel> pixels, std::span<RefitAnswer> answers) {
    const std::size_t n = pixels.size();
    robust_problems_.resize(n), robust_solutions_.assign(n, {});
    for (std::size_t i = 0; i < n; ++i)
      robust_problems_[i] = {&observed_[i * lights_], &inverse_sigma_[i * lights_],
                             pixels[i].normal * (pixels[i].albedo / kPi), &rows_[3 * i * lights_]};
    irls_.Fit(robust_problems_, robust_solutions_);
    for (std::size_t i = 0; i < n; ++i) {
      const internal::RobustSolution& fit = robust_solutions_[i];
      double objective = 0.0;
      for (int k = 0; k < lights_; ++k) {
        const double* row = &rows_[3 * (i * lights_ + k)];
        const double residual = observed_[i * lights_ + k] - (row[0] * fit.x.x() + row[1] * fit.x.y() + row[2] * fit.x.z());
        if (inverse_sigma_[i * lights_ + k] > 0.0) objective += internal::TwiceLoss(loss_, residual * inverse_sigma_[i * lights_ + k]);
      }
      answers[i] = {internal::IrlsFit(fit), objective};
      // Nothing left out: the Lambertian fit itself.
      if (fit.rejected == 0) answers[i].fit.model = PixelModel::kLambertian;
    }
  }

  // The lobe from the IRLS fit of answers (the Lambertian start where IRLS
  // failed): with the highlight's samples down-weighted its normal is near
  // the surface's, where a Lambertian fit that strong highlights tilt by
  // degrees can leave a narrow lobe's fit in a local minimum (as the distant
  // method starts its lobes from the trimmed fit).
  void FitLobes(std::span<const RefitPixel> pixels, std::span<RefitAnswer> answers) {
    const std::size_t n = pixels.size();
    lobe_problems_.resize(n), lobe_solutions_.assign(n, {});
    for (std::size_t i = 0; i < n; ++i) {
      const internal::PixelFit& start = answers[i].fit;
      lobe_problems_[i] = {.observed = &scaled_[i * lights_],
                           .inverse_sigma = &scaled_inverse_sigma_[i * lights_],
                           .start_normal = start.ok ? start.normal : pixels[i].normal,
                           .start_albedo = start.ok ? start.albedo : pixels[i].albedo,
                           .geometry = &geometry_[6 * i * lights_]};
    }
    lobes_->Fit(lobe_problems_, lobe_solutions_);
    for (std::size_t i = 0; i < n; ++i) {
      int used = 0;
      for (int k = 0; k < lights_; ++k) used += scaled_inverse_sigma_[i * lights_ + k] > 0.0;
      answers[i] = {internal::LobeFitFrom(lobe_solutions_[i], used, PixelModel::kBlinnPhong), lobe_solutions_[i].chi2};
    }
  }

  const PixelProblem& p_;
  int lights_;
  RobustOptions::Loss loss_;
  internal::RobustLambertianLanes irls_;
  std::optional<internal::LobeLaneFitter> lobes_, ggx_;
  NearPixelSamples samples_;
  std::vector<double> observed_, inverse_sigma_, rows_;  // the samples and IRLS rows s_k f_k(x) l_k(x)
  // The lobe's: the samples over their gains, its light and half vectors, and the view.
  std::vector<double> scaled_, scaled_inverse_sigma_, geometry_;
  std::vector<Eigen::Vector3d> views_;
  std::vector<RefitPixel> map_pixels_;
  std::vector<internal::SharingCandidate> candidates_;
  std::vector<internal::GgxCandidate> offers_;
  std::vector<internal::RobustProblem> robust_problems_;
  std::vector<internal::RobustSolution> robust_solutions_;
  std::vector<internal::LobeProblem> lobe_problems_;
  std::vector<internal::LobeSolution> lobe_solutions_;
};

// Whether a pixel's Lambertian fit explains its samples: chi-square at most
// the adequacy quantile for its degrees of freedom; never where the noise is
// unknown. The pixels it does not explain are the ones the method refits.
class LambertianAdequacy {
 public:
  LambertianAdequacy(const PixelProblem& p, const PhotometricStereoOptions& options)
      : noise_known_(p.rules.noise_known),
        quantiles_(internal::ChiSquareQuantiles(p.lights.count(), options.selection.adequacy_quantile)) {}
  bool Explains(double chi_square, int usable) const {
    const int dof = usable - 3;
    return noise_known_ && dof > 0 && chi_square <= quantiles_[dof];
  }

 private:
  bool noise_known_;
  std::vector<double> quantiles_;
};

// Whether the method refits pixels in each round: `low-frequency` fits once,
// after the last round (step 7), and its rounds place the surface with the
// Lambertian fit, as `lambertian`'s do.
bool RefitsInRounds(Method method) {
  return method != Method::kL2 && method != Method::kLambertian && method != Method::kLowFrequency;
}

// Whether the method keeps a refit over the pixel's Lambertian fit: IRLS
// and `blinn-phong` wherever the refit succeeds; `auto` only where the
// information criterion says the samples pay for the lobe's two parameters
// (its step 4), on a pixel with a sample to spare; *evidence: how far the
// lobe's criterion is below the Lambertian fit's.
bool KeepsRefit(Method method, const internal::PixelFit& refit, double lambertian_chi_square, double* evidence) {
  *evidence = 0.0;
  if (!refit.ok) return false;
  if (method != Method::kAuto) return true;
  const internal::PixelFit lambertian{.ok = true, .chi2 = lambertian_chi_square, .used = refit.used};
  *evidence = lambertian.Bic() - refit.Bic();
  return refit.used > internal::kBlinnPhongParameters && *evidence > 0.0;
}

// From the second round on: the pixels whose Lambertian fit the noise does
// not explain (chi-square above its adequacy quantile; every solved pixel
// where the noise is unknown) refitted as the method says (NearRefitter).
// Returns the pixels that kept a lobe with kConfidentLobeEvidence (`auto`'s
// glossy pixels, for its step 5).
std::vector<internal::GlossyPixel> Refit(const PixelProblem& p, const PhotometricStereoOptions& options,
                                         const cv::Mat& height_mm, const cv::Mat& lambertian_chi_square,
                                         NormalMap* result) {
  std::vector<internal::GlossyPixel> glossy;
  const LambertianAdequacy adequacy(p, options);
  auto explained = [&](int r, int c) {
    return adequacy.Explains(lambertian_chi_square.at<float>(r, c), result->usable_lights.at<std::uint16_t>(r, c));
  };
#pragma omp parallel
  {
    NearRefitter refitter(p, options);
    std::vector<RefitPixel> pixels;
    std::vector<RefitAnswer> answers;
    std::vector<internal::GlossyPixel> thread_glossy;
#pragma omp for schedule(dynamic, 4) nowait
    for (int r = 0; r < p.rows(); ++r) {
      pixels.clear();
      for (int c = 0; c < p.cols(); ++c) {
        if (result->flags.at<std::uint8_t>(r, c) != static_cast<std::uint8_t>(PixelFlag::kSolved) || explained(r, c))
          continue;
        const cv::Vec3f n = result->normals.at<cv::Vec3f>(r, c);
        pixels.push_back({r, c, height_mm.at<float>(r, c), Eigen::Vector3d(n[0], n[1], n[2]), result->albedo.at<float>(r, c)});
      }
      answers.resize(pixels.size());
      refitter.Fit(pixels, answers);
      for (std::size_t i = 0; i < pixels.size(); ++i) {
        const internal::PixelFit& fit = answers[i].fit;
        const int c = pixels[i].c;
        double evidence;
        if (!KeepsRefit(options.method, fit, lambertian_chi_square.at<float>(r, c), &evidence)) continue;
        if (evidence >= internal::kConfidentLobeEvidence)
          thread_glossy.push_back({r * p.cols() + c, static_cast<float>(fit.specular_albedo), static_cast<float>(fit.exponent)});
        result->normals.at<cv::Vec3f>(r, c) = cv::Vec3f(float(fit.normal.x()), float(fit.normal.y()), float(fit.normal.z()));
        result->albedo.at<float>(r, c) = static_cast<float>(fit.albedo);
        result->specular.at<cv::Vec2f>(r, c) = cv::Vec2f(float(fit.specular_albedo), float(fit.exponent));
        result->model.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(fit.model);
        result->usable_lights.at<std::uint16_t>(r, c) = static_cast<std::uint16_t>(fit.used);
        WriteConfidence(p.rules, fit.used, fit.parameters, fit.chi2, &result->confidence.at<float>(r, c));
      }
    }
#pragma omp critical
    glossy.insert(glossy.end(), thread_glossy.begin(), thread_glossy.end());
  }
  // In pixel order, whatever the threads did: the lobes pooled from them do not depend on it.
  std::sort(glossy.begin(), glossy.end(), [](const auto& a, const auto& b) { return a.pixel < b.pixel; });
  return glossy;
}

// Each pixel of *values (CV_32F) that `known` leaves out (0) takes the value
// of the nearest pixel it keeps; nothing changes if it keeps none.
void FillFromNearest(const cv::Mat& known, cv::Mat* values) {
  if (cv::countNonZero(known) == 0) return;
  cv::Mat distance, labels;
  const cv::Mat unknown = ~known;
  cv::distanceTransform(unknown, distance, labels, cv::DIST_L2, cv::DIST_MASK_5, cv::DIST_LABEL_PIXEL);
  std::vector<float> value_of_label(values->total() + 1);  // labels number the known pixels from 1
  for (int r = 0; r < values->rows; ++r)
    for (int c = 0; c < values->cols; ++c)
      if (known.at<std::uint8_t>(r, c)) value_of_label[labels.at<int>(r, c)] = values->at<float>(r, c);
  for (int r = 0; r < values->rows; ++r)
    for (int c = 0; c < values->cols; ++c)
      if (!known.at<std::uint8_t>(r, c)) values->at<float>(r, c) = value_of_label[labels.at<int>(r, c)];
}

// The integrated height of every pixel of p's lattice, 0 at its reference
// (the mean for an orthographic camera; for a pinhole one, the
// geometric-mean distance from the camera at the sample plane). The
// integrator leaves out pixels too close to grazing, which take their
// nearest neighbour's height (a rim pixel sits at the height of the surface
// beside it), as do the pixels off the mask: the lattice is interpolated
// between its pixels.
cv::Mat RelativeDepth(const NearLightOptions& options, const PixelProblem& p, const NormalMap& map,
                      IntegrationWorkspace* workspace = nullptr) {
  const cv::Mat solved = map.flags == static_cast<int>(PixelFlag::kSolved);
  IntegrationOptions integration;
  integration.integrator = options.integrator;
  const bool pinhole = p.rays.camera().IsPinhole();
  if (!pinhole) integration.pixel_pitch = p.rays.camera().pixel_pitch_mm;
  cv::Mat depth;
  const IntegrationSummary integrated =
      pinhole ? IntegrateNormalsPerspective(integration, p.rays, map.normals, solved, &depth, workspace)
              : IntegrateNormals(integration, map.normals, solved, &depth, workspace);
  if (!integrated.IsSolutionUsable() || integrated.pixels == 0) return cv::Mat::zeros(map.normals.size(), CV_32F);
  const cv::Mat known = depth == depth;  // not NaN
  const double reference = pinhole ? 0.0 : cv::mean(depth, known)[0];
  FillFromNearest(known, &depth);
  return depth - reference;
}

// Each pixel's height at `image`'s pixels (a step-1 problem) with the
// surface placed at offset_mm, its relative height bilinear between the
// pixels of lattice_problem's `lattice` around it; past the lattice's last
// row or column, the nearest one's.
cv::Mat HeightsFromLattice(const PixelProblem& lattice_problem, const cv::Mat& lattice, const PixelProblem& image,
                           double offset_mm) {
  cv::Mat height(image.size(), CV_32F);
  const double step = lattice_problem.step, origin = lattice_problem.origin;
  // Image pixel i lies between lattice pixels low and low + 1 (clamped to
  // the last), `fraction` of the way: worked out once per column and row.
  struct Between {
    int low, high;
    float fraction;
  };
  auto between = [&](int pixel, int last) {
    const double u = std::clamp((pixel - origin) / step, 0.0, static_cast<double>(last));
    const int low = std::min(static_cast<int>(u), std::max(last - 1, 0));
    return Between{low, std::min(low + 1, last), static_cast<float>(u - low)};
  };
  std::vector<Between> columns(height.cols);
  for (int c = 0; c < height.cols; ++c) columns[c] = between(c, lattice.cols - 1);
#pragma omp parallel for schedule(static)
  for (int r = 0; r < height.rows; ++r) {
    const Between row = between(r, lattice.rows - 1);
    const float* top = lattice.ptr<float>(row.low);
    const float* bottom = lattice.ptr<float>(row.high);
    float* out = height.ptr<float>(r);
    for (int c = 0; c < height.cols; ++c) {
      const Between& column = columns[c];
      const float upper = top[column.low] + column.fraction * (top[column.high] - top[column.low]);
      const float lower = bottom[column.low] + column.fraction * (bottom[column.high] - bottom[column.low]);
      out[c] = static_cast<float>(image.Height(upper + row.fraction * (lower - upper), offset_mm));
    }
  }
  return height;
}

// The solved pixels of every stride-th row and column, with their
// integrated heights (relative to the reference) and their fits, from which
// a refit at another depth starts.
struct SparseGrid {
  std::vector<PixelAt> pixels;
  std::vector<float> relative;
  std::vector<RefitPixel> starts;
};

SparseGrid SparsePixels(int stride, const NormalMap& map, const cv::Mat& relative) {
  SparseGrid grid;
  for (int r = stride / 2; r < relative.rows; r += stride)
    for (int c = stride / 2; c < relative.cols; c += stride) {
      if (map.flags.at<std::uint8_t>(r, c) != static_cast<std::uint8_t>(PixelFlag::kSolved)) continue;
      grid.pixels.push_back({r, c, 0.0});
      grid.relative.push_back(relative.at<float>(r, c));
      const cv::Vec3f n = map.normals.at<cv::Vec3f>(r, c);
      grid.starts.push_back({r, c, 0.0, Eigen::Vector3d(n[0], n[1], n[2]), map.albedo.at<float>(r, c)});
    }
  return grid;
}

// The sum over the grid of each pixel's misfit with the surface at relative
// + offset_mm, as the method would fit it there: the Lambertian chi-square
// where that fit explains the samples, else (robust, blinn-phong, auto) the
// refit's misfit (RefitAnswer::objective), so that the highlights a refit
// models or leaves out do not pull the surface. Which pixels are refitted is
// decided at each depth: fixed from the last round, a pixel that was
// explained there but holds a highlight here would weigh that highlight at
// full chi-square. Summed in a fixed order, so the search takes the same
// steps with any number of threads.
double SparseMisfit(const PixelProblem& p, const PhotometricStereoOptions& options, const LambertianAdequacy& adequacy,
                    SparseGrid& grid, double offset_mm) {
  constexpr std::size_t kChunk = 8 * internal::kNearLanes;
  const std::size_t count = grid.pixels.size(), chunks = (count + kChunk - 1) / kChunk;
  for (std::size_t i = 0; i < count; ++i)
    grid.pixels[i].z_mm = grid.starts[i].z_mm = p.Height(grid.relative[i], offset_mm);
  std::vector<double> chunk_sum(chunks, 0.0);
  const bool refits = RefitsInRounds(options.method);
  // Without refits the grid's few hundred Lambertian fits take less time
  // than waking a second thread; the search calls this a dozen times or more.
#pragma omp parallel if (refits)
  {
    std::vector<PixelFit> fits(kChunk);
    std::optional<NearRefitter> refitter;
    if (refits) refitter.emplace(p, options);
    std::vector<RefitPixel> unexplained;
    std::vector<std::size_t> index;
    std::vector<RefitAnswer> answers;
#pragma omp for schedule(dynamic, 1)
    for (std::size_t chunk = 0; chunk < chunks; ++chunk) {
      const std::size_t begin = chunk * kChunk, size = std::min(kChunk, count - begin);
      FitPixels(p, std::span<const PixelAt>(grid.pixels).subspan(begin, size), std::span<PixelFit>(fits).first(size));
      unexplained.clear(), index.clear();
      for (std::size_t i = 0; refits && i < size; ++i) {
        if (fits[i].flag != PixelFlag::kSolved || adequacy.Explains(fits[i].chi_square, fits[i].usable)) continue;
        unexplained.push_back(grid.starts[begin + i]);
        index.push_back(i);
      }
      answers.resize(unexplained.size());
      if (!unexplained.empty()) refitter->Fit(unexplained, answers);
      for (std::size_t j = 0; j < unexplained.size(); ++j)
        if (answers[j].fit.ok) fits[index[j]].chi_square = std::min(fits[index[j]].chi_square, answers[j].objective);
      for (std::size_t i = 0; i < size; ++i)
        if (fits[i].flag == PixelFlag::kSolved) chunk_sum[chunk] += fits[i].chi_square;
    }
  }
  double total = 0.0;
  for (const double sum : chunk_sum) total += sum;
  return total;
}

// Where the depth search looks: below the lowest LED and no deeper than that
// under the plane; a pinhole's scale stays positive.
struct OffsetRange {
  double low_mm = 0.0, high_mm = 0.0;
};

OffsetRange DepthOffsetRange(const std::vector<camera::NearLight>& lights, const camera::Camera& camera) {
  double lowest_led_mm = std::numeric_limits<double>::infinity();
  for (const camera::NearLight& light : lights)
    if (!light.at_infinity) lowest_led_mm = std::min(lowest_led_mm, light.position_mm.z());
  OffsetRange range{-0.5 * lowest_led_mm, 0.5 * lowest_led_mm};
  if (camera.IsPinhole()) range.high_mm = std::min(range.high_mm, 0.9 * camera.pinhole.distance_mm);
  return range;
}

// The depth offset within the range where the grid's summed misfit is least.
double BestOffset(const PixelProblem& p, const PhotometricStereoOptions& options, const NearLightOptions& near_options,
                  const NormalMap& map, const cv::Mat& relative, const OffsetRange& range) {
  constexpr double kToleranceMm = 0.01;
  // offset_stride counts the image's pixels, a lattice pixel p.step of them.
  SparseGrid grid = SparsePixels((near_options.offset_stride + p.step - 1) / p.step, map, relative);
  const LambertianAdequacy adequacy(p, options);  // its quantiles are worked out once for the whole search
  // Brent's method: parabolic steps where the summed misfit is smooth in the
  // offset (it is, away from samples crossing a threshold), golden-section
  // ones where not. Its tolerance is relative to |t|, so t runs over [1, 2]
  // for a near-uniform one in mm; the bracket it stops at is a few
  // tolerances wide.
  const double width_mm = range.high_mm - range.low_mm;
  const int bits = static_cast<int>(std::ceil(1.0 - std::log2(kToleranceMm / (4.0 * width_mm))));
  auto offset = [&](double t) { return range.low_mm + (t - 1.0) * width_mm; };
  std::uintmax_t max_iterations = 200;
  const auto [t, misfit] = boost::math::tools::brent_find_minima(
      [&](double t) { return SparseMisfit(p, options, adequacy, grid, offset(t)); }, 1.0, 2.0, bits, max_iterations);
  return offset(t);
}

// Each pixel's height with the surface `relative` placed at offset_mm.
cv::Mat Heights(const PixelProblem& p, const cv::Mat& relative, double offset_mm) {
  cv::Mat height(relative.size(), CV_32F);
  for (int r = 0; r < height.rows; ++r) {
    const float* in = relative.ptr<float>(r);
    float* out = height.ptr<float>(r);
    for (int c = 0; c < height.cols; ++c) out[c] = static_cast<float>(p.Height(in[c], offset_mm));
  }
  return height;
}

// One fit of every pixel of p with its surface at height_mm: the Lambertian
// fit, and once the surface is placed the method's refits; returns the
// refits' confidently glossy pixels.
std::vector<internal::GlossyPixel> FitRound(const PixelProblem& p, const PhotometricStereoOptions& options,
                                            const cv::Mat& height_mm, bool placed, NormalMap* map) {
  // On an unplaced surface the residuals are the geometry's, not outliers',
  // so the chi-square test cannot tell which samples to distrust.
  const bool refit = placed && RefitsInRounds(options.method);
  cv::Mat chi_square;
  FitAllPixels(p, height_mm, map, refit ? &chi_square : nullptr);
  if (!refit) return {};
  return Refit(p, options, height_mm, chi_square, map);
}

// The surface a map's pixels were fitted at, and the glossy pixels of that fit.
struct FittedSurface {
  cv::Mat height_mm;
  std::vector<internal::GlossyPixel> glossy;
};

// `auto`'s steps 5 and 6 (lobe_sharing.h) on p's map fitted at `surface`,
// with every pixel's own light and view vectors; returns how many pixels
// took a held lobe, *held marks them (empty: none), *shape_rejected the
// pixels of regions that reject one Blinn-Phong shape (empty: none).
std::size_t ShareLobes(const PixelProblem& p, const PhotometricStereoOptions& options, FittedSurface surface,
                       NormalMap* map, std::vector<std::uint8_t>* held_out,
                       std::vector<std::uint8_t>* shape_rejected) {
  if (options.method != Method::kAuto || !options.selection.share_lobe) return 0;
  const internal::ModelLadder ladder(options.method, options.selection, p.lights.count());
  const int threads = omp_get_max_threads();
  std::vector<std::unique_ptr<NearRefitter>> refitters;
  std::vector<std::uint8_t>& held = *held_out;
  *shape_rejected = internal::ShareLobes(
      ladder, options.selection.glossy_region_fraction, *map, std::move(surface.glossy), threads,
      {.begin =
           [&] {
             held.assign(map->flags.total(), 0);
             for (int t = 0; t < threads; ++t) refitters.push_back(std::make_unique<NearRefitter>(p, options));
           },
       .share = [&](int thread, std::span<const internal::SharedLobeItem> items,
                    std::vector<internal::SharedShapeTest>* tests) {
         refitters[thread]->ShareLobe(ladder, items, surface.height_mm, tests, map, &held);
       },
       .offer_ggx = [&](int thread, std::span<const int> pixels, internal::SharedShapeTest* test) {
         refitters[thread]->OfferGgx(ladder, pixels, surface.height_mm, held, test, map);
       },
       .own_lobes = nullptr});  // near lights hold no lattice lobes
  // Step 6 may have given a held pixel a GGX lobe of its own.
  std::size_t still_held = 0;
  for (std::size_t i = 0; i < held.size(); ++i)
    still_held += held[i] && map->model.ptr<std::uint8_t>()[i] == static_cast<std::uint8_t>(PixelModel::kBlinnPhong);
  return still_held;
}

// Step 7 (`auto`, `low-frequency`; ModelLadder::NextWithLowFrequency) on p's
// map fitted at height_mm, with every pixel's own light and view vectors;
// held: step 5's held lobes, shape_rejected: its rejecting regions' pixels.
// Returns how many pixels fell back; the lobe-shift test's counts into *summary.
std::size_t OfferLowFrequency(const PixelProblem& p, const PhotometricStereoOptions& options, const cv::Mat& height_mm,
                              const std::vector<std::uint8_t>& held, const std::vector<std::uint8_t>& shape_rejected,
                              NormalMap* map, SolverSummary* summary) {
  const Method method = options.method;
  if (!(method == Method::kLowFrequency || (method == Method::kAuto && options.selection.low_frequency))) return 0;
  const internal::ModelLadder ladder(method, options.selection, p.lights.count());
  std::size_t fell_back = 0;
  LowFrequencyRuleCounts rules;
  auto climb = [&](std::span<const int> pixels, bool test_lobe_shift, bool write) {
    constexpr std::size_t kChunk = 256;
    const std::size_t chunks = (pixels.size() + kChunk - 1) / kChunk;
    std::size_t fell = 0;
    int tested = 0, shifted = 0;
#pragma omp parallel if (chunks > 1) reduction(+ : fell, tested, shifted)
    {
      NearRefitter refitter(p, options);
      internal::LobeShiftTally tally;
      LowFrequencyRuleCounts mine;
#pragma omp for schedule(dynamic, 1)
      for (std::size_t chunk = 0; chunk < chunks; ++chunk) {
        const std::size_t first = chunk * kChunk, count = std::min(kChunk, pixels.size() - first);
        refitter.OfferLowFrequency(ladder, options, pixels.subspan(first, count), height_mm, held, shape_rejected,
                                   test_lobe_shift, write, map, &fell, &mine, &tally);
      }
      tested += tally.tested, shifted += tally.shifted;
#pragma omp critical(near_low_frequency_rules)
      rules += mine;
    }
    fell_back += fell;
    return internal::LobeShiftTally{tested, shifted};
  };
  const internal::LowFrequencyPlan plan = internal::PlanLowFrequency(
      ladder, *map, held, !held.empty(), [&](std::span<const int> sample) { return climb(sample, true, false); });
  climb(plan.pixels, plan.test_lobe_shift, true);
  plan.AddTo(summary);
  summary->low_frequency_rules += rules;
  return fell_back;
}

// The rounds on p's lattice: round 1 with the surface on the sample plane,
// each next one at the depth integrated from the previous round's normals
// and placed by BestOffset, until the normals stop moving (true) or
// max_rounds end. *relative: the surface the last round fitted on (empty
// if none was placed), its offset in summary->depth_offset_mm.
bool RunRounds(const PhotometricStereoOptions& options, const NearLightOptions& near_options, const PixelProblem& p,
               const OffsetRange& range, NormalMap* map, cv::Mat* relative, NearLightSummary* summary,
               FittedSurface* last) {
  AllocateResult(p.size(), map);
  cv::Mat height = cv::Mat::zeros(p.size(), CV_32F);
  IntegrationWorkspace integration;  // the rounds solve on one set of pixels, as a rule
  for (int round = 1; round <= near_options.max_rounds; ++round) {
    const cv::Mat previous = round > 1 ? map->normals.clone() : cv::Mat();
    last->glossy = FitRound(p, options, height, round > 1, map);
    last->height_mm = height;  // shared: each round's heights are a new image (Heights), never written again
    summary->rounds = round;
    if (options.progress) options.progress({"near lights", round, near_options.max_rounds, {}});
    if (round > 1) {
      // The mean angle between the two rounds' normals, over the pixels both solved.
      summary->normal_change_deg.push_back(CompareNormals(map->normals, previous).mean_deg);
      if (summary->normal_change_deg.back() < near_options.normal_change_tolerance_deg) return true;
    }
    if (round == near_options.max_rounds) break;  // no round left to fit at a new depth
    const core::SolveTimer depth_timer;
    *relative = RelativeDepth(near_options, p, *map, &integration);
    summary->depth_offset_mm = BestOffset(p, options, near_options, *map, *relative, range);
    summary->depth_ms += depth_timer.ElapsedMs();
    height = Heights(p, *relative, summary->depth_offset_mm);
  }
  return false;
}

void CountPixels(const NormalMap& map, NearLightSummary* summary) {
  // One pass over the labels, each map's values counted at once.
  std::array<std::size_t, 256> flags{}, models{};
  for (int r = 0; r < map.flags.rows; ++r) {
    const std::uint8_t* flag = map.flags.ptr<std::uint8_t>(r);
    const std::uint8_t* model = map.model.ptr<std::uint8_t>(r);
    for (int c = 0; c < map.flags.cols; ++c) ++flags[flag[c]], ++models[model[c]];
  }
  auto flagged = [&](PixelFlag flag) { return flags[static_cast<std::uint8_t>(flag)]; };
  auto modelled = [&](PixelModel model) { return models[static_cast<std::uint8_t>(model)]; };
  summary->pixels_total = map.flags.total();
  summary->pixels_solved = flagged(PixelFlag::kSolved);
  summary->pixels_outside_mask = flagged(PixelFlag::kOutsideMask);
  summary->pixels_too_few_lights = flagged(PixelFlag::kTooFewLights);
  summary->pixels_ill_conditioned = flagged(PixelFlag::kIllConditioned);
  summary->pixels_rejected_by_model = flagged(PixelFlag::kRejectedByModel);
  summary->pixels_lambertian = modelled(PixelModel::kLambertian);
  summary->pixels_irls = modelled(PixelModel::kIrls);
  summary->pixels_blinn_phong = modelled(PixelModel::kBlinnPhong);
  summary->pixels_ggx = modelled(PixelModel::kGgx);
  summary->pixels_low_frequency = modelled(PixelModel::kLowFrequency);
}

std::string CheckInputs(const PhotometricStack& stack, const std::vector<camera::NearLight>& lights, const camera::Camera& camera) {
  if (std::string why; !stack.IsValid(&why)) return why;
  if (camera.width_px != stack.width() || camera.height_px != stack.height())
    return "near lights: the camera is " + std::to_string(camera.width_px) + "x" + std::to_string(camera.height_px) +
           " pixels, the images " + std::to_string(stack.width()) + "x" + std::to_string(stack.height());
  if (static_cast<int>(lights.size()) != stack.light_count())
    return "near lights: " + std::to_string(lights.size()) + " LEDs for " + std::to_string(stack.light_count()) + " images";
  // Every LED must stand above the object: the depth search stays below the lowest.
  for (std::size_t k = 0; k < lights.size(); ++k)
    if (!(lights[k].position_mm.z() > 0.0) || !lights[k].position_mm.allFinite())
      return "near light " + std::to_string(k) + " is not above the sample plane (z <= 0)";
  return {};
}

}  // namespace

double DistantModelBiasDeg(const std::vector<camera::NearLight>& lights, const std::vector<Eigen::Vector3d>& directions,
                           double radius_mm) {
  // A grid of 41 x 41 points over the disk, each seen on the hemisphere.
  constexpr int kSteps = 41;
  double sum = 0.0;
  int count = 0;
  for (int i = 0; i < kSteps; ++i)
    for (int j = 0; j < kSteps; ++j) {
      const double x = (2.0 * (i + 0.5) / kSteps - 1.0) * radius_mm, y = (2.0 * (j + 0.5) / kSteps - 1.0) * radius_mm;
      const double rho2 = x * x + y * y;
      if (rho2 > 0.9 * radius_mm * radius_mm) continue;  // the rim is flagged, not solved
      const Eigen::Vector3d point(x, y, std::sqrt(radius_mm * radius_mm - rho2));
      const Eigen::Vector3d normal = point / radius_mm;
      Eigen::Matrix3d normal_matrix = Eigen::Matrix3d::Zero();
      Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
      int lit = 0;
      for (std::size_t k = 0; k < lights.size(); ++k) {
        Eigen::Vector3d towards;
        const double value = lights[k].RelativeIrradiance(point, &towards) * std::max(0.0, normal.dot(towards));
        if (value <= 0.0) continue;  // a shadow: the distant solve leaves it out too
        normal_matrix.noalias() += directions[k] * directions[k].transpose();
        rhs.noalias() += value * directions[k];
        ++lit;
      }
      if (lit < 3) continue;
      const Eigen::Vector3d b = normal_matrix.ldlt().solve(rhs);
      if (!(b.norm() > 0.0)) continue;
      sum += std::acos(std::clamp(b.normalized().dot(normal), -1.0, 1.0));
      ++count;
    }
  return count > 0 ? RadiansToDegrees(sum / count) : 0.0;
}

bool NearLightOptions::IsValid(std::string* why) const {
  if (std::string camera_why; !camera.IsValid(&camera_why)) return core::Refuse(why, "camera: " + camera_why);
  if (max_rounds < 1 || max_rounds > 100) return core::Refuse(why, "max_rounds must be within [1, 100]");
  if (!(normal_change_tolerance_deg > 0.0)) return core::Refuse(why, "normal_change_tolerance_deg must be > 0");
  if (offset_stride < 0) return core::Refuse(why, "offset_stride must be >= 0");
  if (round_step_px < 0 || round_step_px > 64) return core::Refuse(why, "round_step_px must be within [0, 64]");
  return true;
}

NearLightSummary SolveNearLightPhotometricStereo(const PhotometricStereoOptions& options,
                                                 const NearLightOptions& near_options,
                                                 const PhotometricStack& stack, const std::vector<camera::NearLight>& lights,
                                                 NormalMap* result, cv::Mat* height_mm) {
  core::SolveTimer timer;
  NearLightSummary summary;
  summary.method = MethodName(options.method);
  summary.light_count = stack.light_count();
  if (core::EndIfInvalid(options, &summary) || core::EndIfInvalid(near_options, &summary)) return summary;
  if (core::EndIfBadInput(CheckInputs(stack, lights, near_options.camera), &summary)) return summary;
  PixelProblem problem(stack, lights, near_options.camera);
  internal::NearSampleRules& rules = problem.rules;
  rules.exclude_unusable = options.method != Method::kL2;
  rules.shadow_threshold = std::max(options.lambertian.shadow_threshold,
                                    options.shadow_threshold_read_sigmas * stack.noise.read_sigma);
  rules.saturation_level = options.lambertian.saturation_level;
  rules.noise_known = stack.noise.IsKnown();
  rules.read_variance = stack.noise.read_sigma * stack.noise.read_sigma;
  rules.shot_gain = stack.noise.shot_gain;
  problem.max_condition_number = options.lambertian.max_condition_number;
  summary.shadow_threshold = rules.shadow_threshold;
  summary.noise_read_sigma = stack.noise.read_sigma;
  summary.noise_shot_gain = stack.noise.shot_gain;

  // With every light at infinity nothing depends on the depth: a line of
  // sight keeps its direction along its length, and such a light reaches
  // every point alike.
  const bool depth_matters =
      std::any_of(lights.begin(), lights.end(), [](const camera::NearLight& light) { return !light.at_infinity; });
  const OffsetRange range = DepthOffsetRange(lights, near_options.camera);
  // The rounds place each pixel's point for its light vectors: a surface
  // sampled every few pixels does that as well as one with every detail.
  const cv::Rect object = stack.mask.empty() ? cv::Rect(0, 0, stack.width(), stack.height()) : cv::boundingRect(stack.mask);
  const int step = !depth_matters                 ? 1
                   : near_options.round_step_px > 0 ? near_options.round_step_px
                                                    : std::max(1, std::max(object.width, object.height) / kRoundLatticeSidePx);
  const PixelProblem lattice = problem.Lattice(step, (step - 1) / 2);
  NearLightOptions resolved = near_options;  // the depth search's grid, in the image's pixels
  if (resolved.offset_stride == 0)
    resolved.offset_stride = std::max(1, std::max(object.width, object.height) / kOffsetGridSidePx);
  timer.SetupDone(&summary);
  bool converged = true;
  cv::Mat relative;  // the lattice's surface the last round fitted on; empty: none placed
  FittedSurface fitted;  // where the answer's pixels were fitted
  if (depth_matters) {
    NormalMap lattice_map;
    converged = RunRounds(options, resolved, lattice, range, step == 1 ? result : &lattice_map, &relative, &summary,
                          &fitted);
  }
  if (!depth_matters || step > 1) {
    // Every pixel fitted once, at the surface the last round fitted on (or,
    // with nothing depending on it, anywhere).
    const cv::Mat height = relative.empty() ? cv::Mat::zeros(stack.height(), stack.width(), CV_32F)
                                            : HeightsFromLattice(lattice, relative, problem, summary.depth_offset_mm);
    AllocateResult(height.size(), result);
    fitted.glossy = FitRound(problem, options, height, !depth_matters || !relative.empty(), result);
    fitted.height_mm = height;
    if (!depth_matters) summary.rounds = 1;
  }
  std::vector<std::uint8_t> held, shape_rejected;
  const cv::Mat fitted_height_mm = fitted.height_mm;
  const double fits_end_ms = timer.ElapsedMs();
  summary.tiles_ms = fits_end_ms - summary.setup_ms - summary.depth_ms;
  const std::size_t held_lobes = ShareLobes(problem, options, std::move(fitted), result, &held, &shape_rejected);
  const double shared_lobe_end_ms = timer.ElapsedMs();
  summary.shared_lobe_ms = shared_lobe_end_ms - fits_end_ms;
  const std::size_t fell_back = OfferLowFrequency(problem, options, fitted_height_mm, held, shape_rejected, result, &summary);
  summary.low_frequency_ms = timer.ElapsedMs() - shared_lobe_end_ms;
  CountPixels(*result, &summary);
  summary.pixels_shared_lobe = held_lobes;
  summary.pixels_fell_back += fell_back;
  if (height_mm) {
    // The surface itself, from the final normals at every pixel, placed
    // where the model fits it best: the rounds' surface, integrated on their
    // lattice, is shaped by its coarser steps, which shifts its best
    // placement by tens of micrometres on a sphere.
    const core::SolveTimer depth_timer;
    const cv::Mat whole = RelativeDepth(near_options, problem, *result);
    if (step > 1 && !relative.empty()) summary.depth_offset_mm = BestOffset(problem, options, resolved, *result, whole, range);
    *height_mm = Heights(problem, whole, summary.depth_offset_mm);
    height_mm->setTo(kNaN, result->flags != static_cast<int>(PixelFlag::kSolved));
    summary.depth_ms += depth_timer.ElapsedMs();
  }
  timer.Finish(&summary);
  if (summary.pixels_solved == 0) {
    summary.End(Termination::kFailure, "no pixel could be solved under the near lights");
    return summary;
  }
  summary.termination = converged ? Termination::kSuccess : Termination::kNoConvergence;
  if (!converged)
    summary.message = "the normals still moved " +
                      std::to_string(summary.normal_change_deg.empty() ? 0.0 : summary.normal_change_deg.back()) +
                      " deg in the last of " + std::to_string(near_options.max_rounds) + " rounds";
  return summary;
}

}  // namespace photorig::solvers::ps
