#include "tile_refiner.h"

#include "kernels/adequacy_screen.h"

#include <omp.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <mutex>
#include <span>

namespace photorig::solvers::ps::internal {
namespace {

// Queues longer than this run their stage; see Flush.
constexpr std::size_t kBatch = 64;
// Doubtful pixels wait for the exact test until a thread has this many:
// the Lambertian pass streams its samples from memory tile after tile, and
// stopping it for each tile's handful of doubtful pixels (a matte scene has
// about 1 %) cost 4-7 % of `auto`'s time on the benchmark spheres. Their
// samples are copied while the tile is in cache (RefineTile), so the wait
// costs no second read from memory. A glossy tile fills it alone.
constexpr std::size_t kDeferredDoubtful = 512;
// Lattice lobes (ModelSelectionOptions::lattice_lobes): in a glossy tile,
// the pixels whose index is a multiple of kLatticeStride fit their own lobes;
// a pixel waiting for them holds the median of the kNearestLatticeLobes
// adequate confident ones nearest it in its row, and fits its own where its
// row has fewer than kMinLatticeLobes. Eight: one own fit in eight, beside
// seven held fits (three parameters, not five, and fewer steps) at a
// fraction of its cost each; five: a median that two lobes of another
// material beside the pixel do not move.
constexpr int kLatticeStride = 8;
constexpr std::size_t kNearestLatticeLobes = 5;
constexpr std::size_t kMinLatticeLobes = 3;
// held_lobe_'s values: a lobe held by step 5, or by step 4's lattice.
constexpr std::uint8_t kHeldByRegion = 1, kHeldByLattice = 2;

// Rows reused from tile to tile grow only, doubling: a resize to each
// tile's size would zero-fill them again every time.
template <typename T>
void GrowToHold(std::vector<T>& rows, std::size_t size) {
  if (rows.size() < size) rows.resize(2 * size);
}

PixelFit TrimmedFit(const TrimSolution& trimmed) {
  PixelFit fit;
  const double length = trimmed.x.norm();
  fit.ok = trimmed.ok;
  fit.normal = length > 0.0 ? Eigen::Vector3d(trimmed.x / length) : trimmed.x;  // as x.normalized()
  fit.albedo = M_PI * length;
  fit.chi2 = trimmed.chi2;
  fit.used = trimmed.used;
  fit.rejected = trimmed.rejected;
  fit.model = PixelModel::kTrimmed;
  return fit;
}

}  // namespace

// A pixel waiting for a lane stage that works on a row of its samples (IRLS,
// the Blinn-Phong fit). It keeps only what the ladder looks at again: the
// Lambertian pass's solution x with its chi-square and sample count as the
// exact test found them. The fits it climbed past were inadequate, and a fit
// with no answer (kNoFit) tells the ladder as much.
struct TileRefiner::Queued {
  int pixel;
  Eigen::Vector3d x;
  double chi2;
  int used;
  PixelFit row_lambertian;  // x tested on the row
  PixelFit trimmed;         // the lobe's queue: the trimmed fit, the rung below the lobe (kNoFit if none)
  Eigen::Vector3d start_normal;
  double start_albedo;
  std::size_t row;  // of the thread's rows
};

// A thread's queues, rows and lists: everything whose size grows with the
// pixels it refines. They outlive the solve (TakeThreadBuffers), emptied but
// with their capacity: allocated afresh, a solve paid for every page of them
// again, and on two threads shiny `auto` took 1.2x as long.
struct TileRefiner::ThreadBuffers {
  std::vector<std::uint8_t> needs_refit;  // per pixel of the tile
  std::vector<int> doubtful;  // the tile's pixels that need refitting, with lanes
  std::vector<Eigen::Vector3d> doubtful_x;
  // Copied doubtful pixels' samples, a row of lights_ each (RecheckLanes::CopySamples).
  std::vector<float> doubtful_samples;
  std::vector<Recheck> rechecks;
  // Every light's sample of the queued pixels, one row per pixel
  // (SampleReader::Row); see Flush.
  std::vector<double> observed, inverse_sigma;
  // Pixels queued for trimming (with the Lambertian pass's solution x and,
  // for `auto`, its chi-square and sample count as the recheck found them)
  // and their samples (TrimmedLambertianLanes::CopySamples), one row each.
  struct Trimming {
    int pixel;
    Eigen::Vector3d x;
    double chi2;
    int used;
  };
  std::vector<Trimming> trimming;
  std::vector<float> trim_rows;
  std::vector<Queued> reweighting, lobes;
  // Lattice lobes: the glossy tile's pixels that wait for its lattice's
  // lobes (no row yet), and those that kept a held lattice lobe (marked in
  // held_lobe_ once every tile is done).
  std::vector<Queued> awaiting_lattice;
  std::vector<GlossyPixel> lattice;  // the tile's confident lattice lobes, in pixel order
  std::vector<float> nearest_specular, nearest_exponent;
  std::vector<LatticeHeld> lattice_held;
  std::vector<RobustProblem> robust_problems;
  std::vector<RobustSolution> robust_solutions;
  std::vector<TrimSolution> trim_solutions;
  std::vector<LobeProblem> problems;
  std::vector<LobeSolution> solutions;
  std::vector<GlossyPixel> glossy;  // pixels that kept a lobe with kConfidentLobeEvidence
  // Step 5: the pixels of a batch offered the shared lobe.
  std::vector<SharingCandidate> sharing;
  // Steps 5 and 6: a batch's kept fits, its problems for HeldLobeLanes (held
  // lobes to fit, kept fits to judge) and their answers.
  std::vector<PixelFit> held_kept;
  std::vector<HeldLobeProblem> held_problems;
  std::vector<HeldLobeSolution> held_solutions;
  // Step 6 in lanes: a batch's pixels the ladder asks a GGX fit of.
  std::vector<GgxCandidate> ggx_offers;

  // Empties every list, keeping its capacity.
  void Clear() {
    auto clear = [](auto&... lists) { (lists.clear(), ...); };
    clear(needs_refit, doubtful, doubtful_x, doubtful_samples, rechecks, observed, inverse_sigma, trimming, trim_rows,
          reweighting, lobes, awaiting_lattice, lattice, nearest_specular, nearest_exponent, lattice_held,
          robust_problems, robust_solutions, trim_solutions, problems, solutions, glossy, sharing, held_kept,
          held_problems, held_solutions, ggx_offers);
  }
};

// One solve's state of a thread: its buffers, taken from those earlier
// solves left, and its counts.
struct TileRefiner::ThreadState : ThreadBuffers {
  PixelScratch scratch;  // the per-pixel fitter's
  std::size_t rows = 0;  // of observed and inverse_sigma in use
  // The glossy tile being refined with lattice lobes: pixels [lattice_begin, lattice_end).
  int lattice_begin = 0, lattice_end = 0;
  std::unique_ptr<RobustLambertianLanes> irls;  // `robust` only
  std::size_t lambertian = 0, trimmed = 0, irls_fits = 0, blinn_phong = 0, rejected = 0, failed = 0, fell_back = 0;
  // Step 5: the pixels it took from each simpler model, the samples those had left out.
  std::size_t shared_lobes = 0, shared_from_lambertian = 0, shared_from_trimmed = 0;
  // Pixels that kept a held lattice lobe, and those of them whose region
  // rejected one lobe shape (step 6: their lobes count as their own).
  std::size_t lattice_lobes = 0, lattice_lobes_own = 0;
  // Step 6: the pixels that took a GGX lobe, by the model they had kept.
  std::size_t ggx = 0, ggx_from_lambertian = 0, ggx_from_trimmed = 0, ggx_from_blinn_phong = 0, ggx_from_held_lobe = 0;
  // Step 7: the pixels that took the low-frequency fit, by the model they had kept.
  std::size_t low_frequency = 0, low_from_lambertian = 0, low_from_trimmed = 0, low_from_blinn_phong = 0,
              low_from_held_lobe = 0, low_from_ggx = 0;
  LowFrequencyRuleCounts low_rules;  // and by the rule that took them
  // Samples a kept fit had left out (trimmed or unlit) that steps 5-7's fits use again.
  std::size_t samples_restored = 0;
};

// The buffers finished solves gave back, for the next solves to take: at
// most as many sets as threads of solves that ran at once.
struct TileRefiner::ThreadBufferPool {
  std::mutex lock;
  std::vector<ThreadBuffers> free;
};

TileRefiner::ThreadBufferPool& TileRefiner::BufferPool() {
  static ThreadBufferPool pool;
  return pool;
}

TileRefiner::ThreadBuffers TileRefiner::TakeThreadBuffers() {
  ThreadBufferPool& pool = BufferPool();
  const std::lock_guard<std::mutex> hold(pool.lock);
  if (pool.free.empty()) return {};
  ThreadBuffers buffers = std::move(pool.free.back());
  pool.free.pop_back();
  return buffers;
}

void TileRefiner::GiveThreadBuffers(ThreadBuffers&& buffers) {
  buffers.Clear();
  ThreadBufferPool& pool = BufferPool();
  const std::lock_guard<std::mutex> hold(pool.lock);
  pool.free.push_back(std::move(buffers));
}

TileRefiner::TileRefiner(const PhotometricStereoOptions& options, const LambertianOptions& lambertian,
                         const PhotometricStack& stack, const ModelLadder& ladder, int threads, NormalMap* result)
    : options_(options),
      stack_(stack),
      ladder_(ladder),
      result_(result),
      lanes_(options.blinn_phong.fitter == BlinnPhongOptions::Fitter::kLanes),
      lights_(stack.light_count()),
      screen_threshold_(ladder.ScreenThresholds()),
      reader_(stack, lambertian),
      recheck_(stack, lambertian),
      held_lobes_(stack, lambertian, options.blinn_phong),
      per_pixel_(ladder, reader_, stack.view_direction, options.blinn_phong),
      threads_(threads),
      states_(threads),
      lattice_lobes_(options.method == Method::kAuto && lanes_ && options.selection.lattice_lobes) {
  for (ThreadState& state : states_) static_cast<ThreadBuffers&>(state) = TakeThreadBuffers();
  if (options.method == Method::kRobust)
    for (ThreadState& state : states_)
      state.irls = std::make_unique<RobustLambertianLanes>(stack.light_directions, options.robust);
  if (lanes_) {
    for (int t = 0; t < threads; ++t) {
      lobe_fitters_.emplace_back(stack.light_directions, stack.view_direction, options.blinn_phong);
      if (options.method == Method::kAuto)
        ggx_fitters_.emplace_back(stack.light_directions, stack.view_direction, options.blinn_phong, LaneLobe::kGgx);
      trimmers_.emplace_back(stack, lambertian, ladder.gross_u2(), options.selection.max_rejected_fraction);
    }
  }
}

TileRefiner::~TileRefiner() {
  for (ThreadState& state : states_) GiveThreadBuffers(std::move(static_cast<ThreadBuffers&>(state)));
}

Eigen::Vector3d TileRefiner::PassSolution(int p) const {
  const cv::Vec3f n = result_->normals.ptr<cv::Vec3f>()[p];
  return Eigen::Vector3d(n[0], n[1], n[2]) * result_->albedo.ptr<float>()[p] / M_PI;
}

// Record and Climb run once per pixel and stage; inlined into each stage,
// where calls to them cost 1 % of shiny `auto`'s instructions.
__attribute__((always_inline)) inline void TileRefiner::Record(ThreadState& state, int p, const PixelFit& chosen,
                                                                bool fell_back, double evidence) {
  if (!chosen.ok) {
    result_->flags.ptr<std::uint8_t>()[p] = static_cast<std::uint8_t>(PixelFlag::kRejectedByModel);
    result_->normals.ptr<cv::Vec3f>()[p] = cv::Vec3f::all(std::numeric_limits<float>::quiet_NaN());
    result_->albedo.ptr<float>()[p] = std::numeric_limits<float>::quiet_NaN();
    result_->model.ptr<std::uint8_t>()[p] = static_cast<std::uint8_t>(PixelModel::kNone);
    result_->confidence.ptr<float>()[p] = 0.0f;
    ++state.failed;
    return;
  }
  WriteFitToMap(p, chosen, result_);
  state.rejected += static_cast<std::size_t>(chosen.rejected);
  state.fell_back += fell_back;
  switch (chosen.model) {
    case PixelModel::kLambertian: ++state.lambertian; break;
    case PixelModel::kTrimmed: ++state.trimmed; break;
    case PixelModel::kIrls: ++state.irls_fits; break;
    case PixelModel::kBlinnPhong:
      ++state.blinn_phong;
      if (evidence >= kConfidentLobeEvidence)
        state.glossy.push_back({p, static_cast<float>(chosen.specular_albedo), static_cast<float>(chosen.exponent)});
      break;
    case PixelModel::kGgx:  // only steps 6 and 7 keep these, after every Record
    case PixelModel::kLowFrequency:
    case PixelModel::kNone: break;
  }
}

std::size_t TileRefiner::NewRow(ThreadState& state) const {
  const std::size_t row = state.rows++;
  GrowToHold(state.observed, state.rows * lights_);
  GrowToHold(state.inverse_sigma, state.rows * lights_);
  return row;
}

std::size_t TileRefiner::GatherRow(ThreadState& state, int p, const Eigen::Vector3d& x, PixelFit* lambertian,
                                   const float* samples) {
  const std::size_t row = NewRow(state);
  int used = 0;
  double* observed = &state.observed[row * lights_];
  double* inverse_sigma = &state.inverse_sigma[row * lights_];
  const double chi2 = samples ? reader_.RowFromSamples(samples, x, observed, inverse_sigma, &used)
                              : reader_.Row(p, x, observed, inverse_sigma, &used);
  *lambertian = LambertianFit(x, chi2, used, 0);
  return row;
}

__attribute__((always_inline)) inline void TileRefiner::Climb(int thread, int p, const Eigen::Vector3d& x,
                                                              const LadderFits& fits, const float* samples,
                                                              const float* values) {
  ThreadState& state = states_[thread];
  const LadderStep step = ladder_.Next(fits);
  switch (step.action) {
    case LadderStep::Action::kKeep: Record(state, p, *step.keep, step.fell_back, step.evidence); return;
    case LadderStep::Action::kRefitLit: return;  // not asked: the recheck refits every pixel it looks at
    case LadderStep::Action::kFitSharedLobe:
    case LadderStep::Action::kFitOwnLobe:
    case LadderStep::Action::kFitGgx:
    case LadderStep::Action::kFitLowFrequency: return;  // Next never asks for them (steps 5-7 do)
    case LadderStep::Action::kTrim: {
      state.trimming.push_back({p, x, fits.lambertian->chi2, fits.lambertian->used});
      const std::size_t at = state.trim_rows.size();
      state.trim_rows.resize(at + trimmers_[thread].row_length());
      trimmers_[thread].CopySamples(p, &state.trim_rows[at], values);
      return;
    }
    case LadderStep::Action::kReweight: {
      PixelFit lambertian;
      const std::size_t row = GatherRow(state, p, x, &lambertian);
      state.reweighting.push_back({p, x, fits.lambertian->chi2, fits.lambertian->used, lambertian, kNoFit,
                                   lambertian.normal, lambertian.albedo, row});
      return;
    }
    case LadderStep::Action::kFitLobe: {
      if (p >= state.lattice_begin && p < state.lattice_end && p % kLatticeStride != 0) {
        // Waits for the lobes of its tile's lattice (HoldLatticeLobes).
        state.awaiting_lattice.push_back({p, x, fits.lambertian->chi2, fits.lambertian->used, kNoFit,
                                          fits.robust ? *fits.robust : kNoFit, step.start->normal,
                                          step.start->albedo, 0});
        return;
      }
      PixelFit lambertian;
      const std::size_t row = GatherRow(state, p, x, &lambertian, samples);
      state.lobes.push_back({p, x, fits.lambertian->chi2, fits.lambertian->used, lambertian,
                             fits.robust ? *fits.robust : kNoFit, step.start->normal, step.start->albedo, row});
      return;
    }
  }
}

void TileRefiner::Trim(int thread) {
  ThreadState& state = states_[thread];
  const std::size_t count = state.trimming.size();
  state.trim_solutions.assign(count, {});
  if (count > 0) trimmers_[thread].Fit(state.trim_rows, ladder_.quantiles(), state.trim_solutions);
  for (std::size_t i = 0; i < count; ++i) {
    const ThreadBuffers::Trimming& t = state.trimming[i];
    const PixelFit lambertian = LambertianFit(t.x, t.chi2, t.used, 0), trimmed = TrimmedFit(state.trim_solutions[i]);
    const LadderFits fits{&lambertian, &kNoFit, &trimmed};
    // The pixel's samples as copied: only a pixel that goes on to the
    // Blinn-Phong fit has them read into a row of doubles.
    Climb(thread, t.pixel, t.x, fits, &state.trim_rows[i * trimmers_[thread].row_length()]);
  }
  state.trimming.clear();
  state.trim_rows.clear();
}

void TileRefiner::Reweight(int thread) {
  ThreadState& state = states_[thread];
  const std::size_t count = state.reweighting.size();
  state.robust_problems.resize(count);
  state.robust_solutions.assign(count, {});
  for (std::size_t i = 0; i < count; ++i) {
    const Queued& q = state.reweighting[i];
    state.robust_problems[i] = {&state.observed[q.row * lights_], &state.inverse_sigma[q.row * lights_],
                                q.start_normal * q.start_albedo / M_PI};
  }
  if (count > 0) state.irls->Fit(state.robust_problems, state.robust_solutions);
  for (std::size_t i = 0; i < count; ++i) {
    const Queued& q = state.reweighting[i];
    const PixelFit reweighted = IrlsFit(state.robust_solutions[i]);
    const LadderFits fits{&q.row_lambertian, nullptr, &reweighted};
    Climb(thread, q.pixel, q.x, fits);
  }
  state.reweighting.clear();
}

void TileRefiner::FitLobes(int thread) {
  ThreadState& state = states_[thread];
  const std::size_t count = state.lobes.size();
  state.problems.resize(count);
  state.solutions.assign(count, {});
  for (std::size_t i = 0; i < count; ++i) {
    const Queued& q = state.lobes[i];
    state.problems[i] = {&state.observed[q.row * lights_], &state.inverse_sigma[q.row * lights_], q.start_normal,
                         q.start_albedo};
  }
  if (count > 0) lobe_fitters_[thread].Fit(state.problems, state.solutions);
  for (std::size_t i = 0; i < count; ++i) {
    const Queued& q = state.lobes[i];
    const PixelFit lambertian = LambertianFit(q.x, q.chi2, q.used, 0);
    const PixelFit blinn_phong = LobeFitFrom(state.solutions[i], q.row_lambertian.used, PixelModel::kBlinnPhong);
    const LadderFits fits{&lambertian, &kNoFit, &q.trimmed, &blinn_phong, &q.row_lambertian};
    Climb(thread, q.pixel, q.x, fits);
  }
  state.lobes.clear();
}

void TileRefiner::Flush(int thread, bool all) {
  ThreadState& state = states_[thread];
  if (all || state.trimming.size() >= kBatch) Trim(thread);
  const std::size_t queued_before = state.reweighting.size() + state.lobes.size();
  if (all || state.reweighting.size() >= kBatch) Reweight(thread);
  if (all || state.lobes.size() >= kBatch) FitLobes(thread);
  if (state.reweighting.size() + state.lobes.size() == queued_before) return;
  // The rows still queued move to the front of the thread's rows, which stay
  // as small as the queues.
  std::vector<Queued*> queued;
  for (auto* queue : {&state.reweighting, &state.lobes})
    for (Queued& q : *queue) queued.push_back(&q);
  std::sort(queued.begin(), queued.end(), [](const Queued* a, const Queued* b) { return a->row < b->row; });
  for (std::size_t i = 0; i < queued.size(); ++i) {
    // Ascending rows move down or stay, so no row is overwritten before it moves.
    const std::size_t from = queued[i]->row * lights_, to = i * lights_;
    std::copy_n(&state.observed[from], lights_, &state.observed[to]);
    std::copy_n(&state.inverse_sigma[from], lights_, &state.inverse_sigma[to]);
    queued[i]->row = i;
  }
  state.rows = queued.size();
}

void TileRefiner::RefineTile(int thread, int begin, int count) {
  ThreadState& state = states_[thread];
  state.needs_refit.resize(count);
  state.lambertian += ScreenTile(result_->flags.ptr<std::uint8_t>() + begin,
                                 result_->usable_lights.ptr<std::uint16_t>() + begin,
                                 result_->confidence.ptr<float>() + begin, count, screen_threshold_.data(),
                                 state.needs_refit.data());
  const std::size_t tile_first = state.doubtful.size();
  auto doubt = [&](int i) {
    const int p = begin + i;
    if (!lanes_) {
      bool fell_back = false;
      double evidence = 0.0;
      const PixelFit chosen =
          per_pixel_.Refine(p, PassSolution(p), &state.scratch, state.irls.get(), &fell_back, &evidence);
      Record(state, p, chosen, fell_back, evidence);
      return;
    }
    state.doubtful.push_back(p);
    state.doubtful_x.push_back(PassSolution(p));
  };
  // Most pixels pass the screen: the flags (0 or 1) are read eight at a
  // time, and each set one is found as the lowest set bit of its word.
  static_assert(std::endian::native == std::endian::little, "byte i of a word is bits 8i..8i+7");
  int i = 0;
  for (; i + 8 <= count; i += 8) {
    std::uint64_t eight;
    std::memcpy(&eight, &state.needs_refit[i], sizeof eight);
    for (; eight != 0; eight &= eight - 1) doubt(i + std::countr_zero(eight) / 8);
  }
  for (; i < count; ++i)
    if (state.needs_refit[i]) doubt(i);
  if (!lanes_) return;
  const bool recheck = options_.method == Method::kAuto;
  // A glossy tile's doubtful pixels are climbed now; `auto` tests a matte
  // tile's later, when the tile's samples have left the cache. Either way
  // their samples are copied now, while they are in it, into one row a
  // pixel: the stages read them there instead of gathering each pixel's
  // samples from the planes again.
  const bool glossy = state.doubtful.size() - tile_first >= kDeferredDoubtful;
  if (glossy || recheck) {
    GrowToHold(state.doubtful_samples, state.doubtful.size() * lights_);
    recheck_.CopySamples(std::span<const int>(state.doubtful).subspan(tile_first),
                         &state.doubtful_samples[tile_first * lights_]);
  }
  if (glossy) {
    if (lattice_lobes_) {
      const std::size_t glossy_first = state.glossy.size();
      state.lattice_begin = begin, state.lattice_end = begin + count;
      ClimbDoubtful(thread, tile_first, true);
      Flush(thread, true);  // the lattice's own lobes, every stage's queue emptied
      state.lattice_begin = state.lattice_end = 0;
      HoldLatticeLobes(thread, begin, begin + count, glossy_first);
    } else {
      ClimbDoubtful(thread, tile_first, true);
    }
  }
  if (state.doubtful.size() >= kDeferredDoubtful) ClimbDoubtful(thread, 0, recheck);
}

void TileRefiner::ClimbDoubtful(int thread, std::size_t first, bool copied) {
  ThreadState& state = states_[thread];
  const std::span<const int> pixels(state.doubtful.data() + first, state.doubtful.size() - first);
  const std::span<const Eigen::Vector3d> xs(state.doubtful_x.data() + first, pixels.size());
  const float* copies = copied ? state.doubtful_samples.data() + first * lights_ : nullptr;
  // `auto` looks again at the doubtful pixels in lanes before copying any
  // samples out for the lane stages: most are settled by the exact test or
  // the lit refit.
  const bool recheck = options_.method == Method::kAuto;
  if (recheck) {
    state.rechecks.resize(pixels.size());
    recheck_.Check(pixels, xs, state.rechecks, copies);
  }
  for (std::size_t j = 0; j < pixels.size(); ++j) {
    const Eigen::Vector3d& x = xs[j];
    const float* values = copies ? copies + j * lights_ : nullptr;
    if (!recheck) {  // `robust` and `blinn-phong` refit every pixel: x is not tested
      const PixelFit lambertian = LambertianFit(x, 0.0, 0, 0);
      Climb(thread, pixels[j], x, {&lambertian});
      continue;
    }
    const Recheck& again = state.rechecks[j];
    const PixelFit lambertian = LambertianFit(x, again.chi2, again.used, 0);
    if (!again.refitted) {
      Climb(thread, pixels[j], x, {&lambertian, &kNoFit}, nullptr, values);
      continue;
    }
    const PixelFit lit = LambertianFit(again.lit_x, again.lit_chi2, again.lit_used, again.unlit);
    Climb(thread, pixels[j], x, {&lambertian, &lit}, nullptr, values);
  }
  state.doubtful.resize(first);
  state.doubtful_x.resize(first);
  Flush(thread, false);
}

void TileRefiner::HoldLatticeLobes(int thread, int begin, int end, std::size_t glossy_first) {
  ThreadState& state = states_[thread];
  if (state.awaiting_lattice.empty()) return;
  state.lattice.clear();
  // A lobe that does not explain its own pixel's samples (another shape,
  // light from elsewhere) is no stand-in for its neighbours'.
  for (std::size_t i = glossy_first; i < state.glossy.size(); ++i) {
    const int p = state.glossy[i].pixel;
    if (p >= begin && p < end && ladder_.Adequate(FitInMapWithChi2(*result_, p, false)))
      state.lattice.push_back(state.glossy[i]);
  }
  std::sort(state.lattice.begin(), state.lattice.end(),
            [](const GlossyPixel& a, const GlossyPixel& b) { return a.pixel < b.pixel; });
  const int width = result_->normals.cols;
  using LatticeIterator = std::vector<GlossyPixel>::const_iterator;
  auto at = [&](int pixel) {
    return std::lower_bound(state.lattice.cbegin(), state.lattice.cend(), pixel,
                            [](const GlossyPixel& g, int q) { return g.pixel < q; });
  };
  // The first lattice lobe at or after a pixel. The waiting pixels come
  // nearly in ascending order, so the search moves on from the last one;
  // a row's bounds are searched once per row.
  LatticeIterator cursor = state.lattice.cbegin(), row_first, row_last;
  int cursor_pixel = -1, row_cached = -1;
  auto at_or_after = [&](int pixel) {
    if (pixel < cursor_pixel) cursor = at(pixel);
    while (cursor != state.lattice.cend() && cursor->pixel < pixel) ++cursor;
    cursor_pixel = pixel;
    return cursor;
  };
  // The median lobe of the lattice lobes nearest pixel p in its row (ties to
  // the left); false where the row has too few.
  auto nearest_lobe = [&](int p, double* specular_albedo, double* exponent) {
    const int row_start = p - p % width;
    if (row_start != row_cached) {
      row_first = at(std::max(begin, row_start));
      row_last = at(std::min(end, row_start + width));
      row_cached = row_start;
    }
    auto left = at_or_after(p), right = left;
    const LatticeIterator first = row_first, last = row_last;
    state.nearest_specular.clear();
    state.nearest_exponent.clear();
    while (state.nearest_exponent.size() < kNearestLatticeLobes && (left != first || right != last)) {
      const bool take_left = left != first && (right == last || p - (left - 1)->pixel <= right->pixel - p);
      const GlossyPixel& g = take_left ? *--left : *right++;
      state.nearest_specular.push_back(g.specular_albedo);
      state.nearest_exponent.push_back(g.exponent);
    }
    if (state.nearest_exponent.size() < kMinLatticeLobes) return false;
    *specular_albedo = MedianOf(state.nearest_specular);
    *exponent = MedianOf(state.nearest_exponent);
    return true;
  };
  // Queues pixel q for its own lobe, as Climb would have.
  auto own_lobe = [&](Queued q) {
    q.row = GatherRow(state, q.pixel, q.x, &q.row_lambertian);
    state.lobes.push_back(q);
  };
  // Queueing a pixel for its own lobe adds nothing to awaiting_lattice: the
  // tile's climb is over (lattice_begin = lattice_end).
  const std::vector<Queued>& awaiting = state.awaiting_lattice;
  std::vector<const Queued*> held;
  for (std::size_t first = 0; first < awaiting.size(); first += kBatch) {
    const std::size_t last = std::min(awaiting.size(), first + kBatch);
    state.held_problems.clear();
    held.clear();
    for (std::size_t i = first; i < last; ++i) {
      const Queued& q = awaiting[i];
      HeldLobeProblem problem{.pixel = q.pixel, .start_normal = q.start_normal, .start_albedo = q.start_albedo,
                              .kept_x = q.x};
      if (!nearest_lobe(q.pixel, &problem.specular_albedo, &problem.exponent)) {
        own_lobe(q);
        continue;
      }
      state.held_problems.push_back(problem);
      held.push_back(&q);
    }
    state.held_solutions.resize(state.held_problems.size());
    held_lobes_.Fit(state.held_problems, state.held_solutions);
    for (std::size_t i = 0; i < held.size(); ++i) {
      const HeldLobeProblem& problem = state.held_problems[i];
      const HeldLobeSolution& solution = state.held_solutions[i];
      PixelFit lambertian = LambertianFit(solution.lambertian_x, solution.lambertian_chi2, solution.used, 0);
      lambertian.ok = lambertian.ok && solution.lambertian_ok;
      PixelFit lobe = LobeFitFrom({.ok = solution.ok,
                                   .normal = solution.normal,
                                   .diffuse_albedo = solution.diffuse_albedo,
                                   .specular_albedo = problem.specular_albedo,
                                   .exponent = problem.exponent,
                                   .chi2 = solution.chi2,
                                   .iterations = solution.iterations},
                                  solution.used, PixelModel::kBlinnPhong);
      lobe.parameters = kSharedLobeParameters;
      if (!ladder_.KeepsLatticeLobe(lobe, lambertian)) {
        own_lobe(*held[i]);
        continue;
      }
      WriteFitToMap(problem.pixel, lobe, result_);
      const Queued& q = *held[i];
      state.lattice_held.push_back({.pixel = problem.pixel,
                                    .start_normal = {static_cast<float>(q.start_normal.x()),
                                                     static_cast<float>(q.start_normal.y()),
                                                     static_cast<float>(q.start_normal.z())},
                                    .start_albedo = static_cast<float>(q.start_albedo),
                                    .lambertian_chi2 = static_cast<float>(lambertian.chi2)});
      ++state.lattice_lobes;
      // It counts for step 5 as the lattice lobes it holds stand for it.
      if (lambertian.Bic() - lobe.Bic() >= kConfidentLobeEvidence)
        state.glossy.push_back({problem.pixel, static_cast<float>(problem.specular_albedo),
                                static_cast<float>(problem.exponent), true});
    }
  }
  state.awaiting_lattice.clear();
  Flush(thread, false);
}

void TileRefiner::Finish(int thread) {
  if (!lanes_) return;
  ClimbDoubtful(thread, 0, options_.method == Method::kAuto);
  Flush(thread, true);
}

void TileRefiner::RecordSharedLobe(ThreadState& state, int p, const PixelFit& kept, const PixelFit& lobe,
                                   int usable) {
  WriteFitToMap(p, lobe, result_);
  held_lobe_[p] = kHeldByRegion;
  ++state.shared_lobes;
  (kept.model == PixelModel::kTrimmed ? state.shared_from_trimmed : state.shared_from_lambertian) += 1;
  // The kept fit left out what it did not use (trimmed or unlit samples); the lobe uses them all.
  state.samples_restored += static_cast<std::size_t>(std::max(0, usable - kept.used));
}

void TileRefiner::ShareLobe(int thread, std::span<const SharedLobeItem> items, std::vector<SharedShapeTest>* tests) {
  ThreadState& state = states_[thread];
  // A climb that ends: the pixel's part in its region's test, or its answer.
  auto finish = [&](const SharedLobeItem& item, const SharedLobeFits& fits, const PixelFit& chosen, int usable) {
    if (tests) {
      ladder_.AddToShapeTest(fits, &(*tests)[item.region]);
    } else if (&chosen != fits.kept) {
      RecordSharedLobe(state, item.pixel, *fits.kept, chosen, usable);
    }
  };
  if (!lanes_) {
    for (const SharedLobeItem& item : items) {
      const PixelFit kept = FitInMap(*result_, item.pixel);
      SharedShapeTest test;
      const PixelFit chosen =
          per_pixel_.ShareLobe(item.pixel, kept, item.lobe, item.test_shape, &state.scratch, tests ? &test : nullptr);
      if (tests) {
        (*tests)[item.region].chi2_gain += test.chi2_gain;
        (*tests)[item.region].pixels += test.pixels;
      } else if (chosen.model == PixelModel::kBlinnPhong) {
        RecordSharedLobe(state, item.pixel, kept, chosen, state.scratch.samples.size());
      }
    }
    return;
  }
  for (std::size_t first = 0; first < items.size(); first += kBatch) {
    const std::size_t last = std::min(items.size(), first + kBatch);
    state.rows = 0;
    state.sharing.clear();
    state.held_kept.clear();
    state.held_problems.clear();
    // Every pixel's held lobe and Lambertian fit on its usable samples in
    // lanes from the planes; a row of doubles only for a pixel of its
    // region's shape test, whose own lobe the lane fitter fits.
    for (std::size_t i = first; i < last; ++i) {
      const PixelFit& kept = state.held_kept.emplace_back(FitInMap(*result_, items[i].pixel));
      state.held_problems.push_back({.pixel = items[i].pixel,
                                     .start_normal = kept.normal,
                                     .start_albedo = kept.albedo,
                                     .specular_albedo = items[i].lobe.specular_albedo,
                                     .exponent = items[i].lobe.exponent,
                                     .kept_x = kept.normal * kept.albedo / M_PI});
    }
    state.held_solutions.resize(state.held_problems.size());
    held_lobes_.Fit(state.held_problems, state.held_solutions);
    std::vector<std::size_t> rows;  // of the shape test's pixels, in the order of `sharing`
    for (std::size_t i = first; i < last; ++i) {
      const HeldLobeProblem& problem = state.held_problems[i - first];
      const HeldLobeSolution& held = state.held_solutions[i - first];
      SharingCandidate candidate;
      candidate.item = &items[i];
      candidate.kept = state.held_kept[i - first];
      candidate.lambertian = LambertianFit(held.lambertian_x, held.lambertian_chi2, held.used, 0);
      candidate.lambertian.ok = candidate.lambertian.ok && held.lambertian_ok;
      if (ladder_.NextWithSharedLobe(candidate.Fits()).action != LadderStep::Action::kFitSharedLobe) continue;
      const LobeSolution lobe{.ok = held.ok,
                              .normal = held.normal,
                              .diffuse_albedo = held.diffuse_albedo,
                              .specular_albedo = problem.specular_albedo,
                              .exponent = problem.exponent,
                              .chi2 = held.chi2,
                              .iterations = held.iterations};
      candidate.lobe = LobeFitFrom(lobe, held.used, PixelModel::kBlinnPhong);
      candidate.lobe.parameters = kSharedLobeParameters;
      candidate.lobe_fitted = true;
      if (items[i].test_shape) {
        PixelFit tested;
        rows.push_back(GatherRow(state, items[i].pixel, problem.kept_x, &tested));
      }
      state.sharing.push_back(candidate);
    }
    // The rows are complete (gathering may have moved them): now point at them.
    for (std::size_t i = 0, row = 0; i < state.sharing.size(); ++i) {
      if (!state.sharing[i].item->test_shape) continue;
      state.sharing[i].problem.observed = &state.observed[rows[row] * lights_];
      state.sharing[i].problem.inverse_sigma = &state.inverse_sigma[rows[row++] * lights_];
    }
    ClimbFromHeldLobes(ladder_, lobe_fitters_[thread], state.sharing,
                       [&](const SharingCandidate& candidate, const PixelFit& chosen) {
                         finish(*candidate.item, candidate.Fits(), chosen, candidate.lambertian.used);
                       });
  }
  state.rows = 0;
}

void TileRefiner::ShareLobe() {
  // The pixels that kept a lattice lobe hold it as step 5's pixels do theirs.
  std::size_t lattice_held = 0;
  for (const ThreadState& state : states_) lattice_held += state.lattice_held.size();
  if (lattice_held > 0) {
    held_lobe_.assign(result_->flags.total(), 0);
    for (const ThreadState& state : states_)
      for (const LatticeHeld& held : state.lattice_held) held_lobe_[held.pixel] = kHeldByLattice;
  }
  if (options_.method != Method::kAuto || !options_.selection.share_lobe) return;
  std::vector<GlossyPixel> glossy;
  std::size_t confident = 0;
  for (const ThreadState& state : states_) confident += state.glossy.size();
  glossy.reserve(confident);
  for (const ThreadState& state : states_) glossy.insert(glossy.end(), state.glossy.begin(), state.glossy.end());
  shape_rejected_ =
      ShareLobes(ladder_, options_.selection.glossy_region_fraction, *result_, std::move(glossy), threads_,
                 {.begin =
                      [this] {
                        held_lobe_.resize(result_->flags.total(), 0);
                        glossy_region_ = true;
                      },
                  .share = [this](int thread, std::span<const SharedLobeItem> items,
                                  std::vector<SharedShapeTest>* tests) { ShareLobe(thread, items, tests); },
                  .offer_ggx = [this](int thread, std::span<const int> pixels,
                                      SharedShapeTest* test) { OfferGgx(thread, pixels, test); },
                  .own_lobes = [this](const std::function<bool(int)>& rejects) {
                    return FitOwnLobesOfLattice(rejects);
                  }});
}

void TileRefiner::OfferGgx(int thread, std::span<const int> pixels, SharedShapeTest* test) {
  ThreadState& state = states_[thread];
  if (!lanes_) {
    for (const int p : pixels) {
      const PixelFit kept = FitInMap(*result_, p);
      const bool held = held_lobe_[p] != 0;
      const PixelFit chosen = per_pixel_.OfferGgx(p, kept, held, &state.scratch, test);
      if (!test && chosen.model == PixelModel::kGgx) RecordGgx(state, p, kept, held, chosen);
    }
    return;
  }
  for (std::size_t first = 0; first < pixels.size(); first += kBatch) {
    const std::size_t last = std::min(pixels.size(), first + kBatch);
    state.rows = 0;
    state.ggx_offers.clear();
    // The kept fits judged on their usable samples in lanes (PerPixelFits::
    // KeptOnUsable's answers): a lobe's chi-square at its parameters, a
    // Lambertian or trimmed fit's as step 5 takes it.
    state.held_kept.clear();
    state.held_problems.clear();
    for (std::size_t i = first; i < last; ++i) {
      const PixelFit& kept = state.held_kept.emplace_back(FitInMap(*result_, pixels[i]));
      const bool lobe = kept.model == PixelModel::kBlinnPhong;
      state.held_problems.push_back({.pixel = pixels[i],
                                     .start_normal = kept.normal,
                                     .start_albedo = kept.albedo,
                                     .specular_albedo = lobe ? kept.specular_albedo : 0.0,
                                     .exponent = lobe ? kept.exponent : 1.0,
                                     .kept_x = kept.normal * kept.albedo / M_PI});
    }
    state.held_solutions.resize(state.held_problems.size());
    held_lobes_.Judge(state.held_problems, state.held_solutions);
    std::vector<std::size_t> rows;
    for (std::size_t i = first; i < last; ++i) {
      const HeldLobeSolution& judged = state.held_solutions[i - first];
      GgxCandidate offer;
      offer.pixel = pixels[i], offer.held = held_lobe_[pixels[i]] != 0;
      offer.kept = state.held_kept[i - first];
      if (offer.kept.model == PixelModel::kBlinnPhong) {
        offer.on_samples = offer.kept;
        offer.on_samples.chi2 = judged.chi2;
        offer.on_samples.ok = judged.ok;
        offer.on_samples.used = judged.used;
        offer.on_samples.parameters = offer.held ? kSharedLobeParameters : kBlinnPhongParameters;
      } else {
        offer.on_samples = LambertianFit(judged.lambertian_x, judged.lambertian_chi2, judged.used, 0);
        offer.on_samples.ok = offer.on_samples.ok && judged.lambertian_ok;
        offer.on_samples.normal = offer.kept.normal;  // the kept fit is where the GGX fit starts
      }
      if (ladder_.NextWithGgx(GgxFits{&offer.on_samples}).action != LadderStep::Action::kFitGgx) continue;
      const std::size_t row = NewRow(state);
      int usable = 0;
      reader_.Row(offer.pixel, state.held_problems[i - first].kept_x, &state.observed[row * lights_],
                  &state.inverse_sigma[row * lights_], &usable);
      state.ggx_offers.push_back(offer);
      rows.push_back(row);
    }
    // The rows are complete (growing may have moved them): now point at them.
    for (std::size_t i = 0; i < rows.size(); ++i)
      state.ggx_offers[i].problem.observed = &state.observed[rows[i] * lights_],
      state.ggx_offers[i].problem.inverse_sigma = &state.inverse_sigma[rows[i] * lights_];
    if (test) {
      TestGgx(ladder_, ggx_fitters_[thread], state.ggx_offers, test);
      continue;
    }
    ClimbGgx(ladder_, ggx_fitters_[thread], state.ggx_offers, [&](const GgxCandidate& offer, const PixelFit& ggx) {
      RecordGgx(state, offer.pixel, offer.kept, offer.held, ggx);
    });
  }
}

std::vector<GlossyPixel> TileRefiner::FitOwnLobesOfLattice(const std::function<bool(int pixel)>& rejects) {
  std::vector<const LatticeHeld*> refit;
  for (const ThreadState& state : states_)
    for (const LatticeHeld& held : state.lattice_held)
      if (rejects(held.pixel)) refit.push_back(&held);
  auto normal_of = [](const LatticeHeld& held) {
    return Eigen::Vector3d(held.start_normal[0], held.start_normal[1], held.start_normal[2]);
  };
  std::vector<std::vector<GlossyPixel>> confident(threads_);
  std::atomic<std::size_t> next{0};
#pragma omp parallel num_threads(threads_)
  {
    const int thread = omp_get_thread_num();
    ThreadState& state = states_[thread];
    std::vector<int> used;
    for (std::size_t first; (first = next.fetch_add(kBatch)) < refit.size();) {
      const std::size_t last = std::min(refit.size(), first + kBatch);
      state.rows = 0;
      state.problems.clear();
      used.clear();
      for (std::size_t i = first; i < last; ++i) {
        // From where step 4 would have started it: the fit it climbed to.
        const LatticeHeld& held = *refit[i];
        const Eigen::Vector3d normal = normal_of(held);
        const std::size_t row = NewRow(state);
        reader_.Row(held.pixel, normal * held.start_albedo / M_PI, &state.observed[row * lights_],
                    &state.inverse_sigma[row * lights_], &used.emplace_back());
        state.problems.push_back({nullptr, nullptr, normal, held.start_albedo});
      }
      // The rows are complete (growing may have moved them): now point at them.
      for (std::size_t i = 0; i < state.problems.size(); ++i)
        state.problems[i].observed = &state.observed[i * lights_],
        state.problems[i].inverse_sigma = &state.inverse_sigma[i * lights_];
      state.solutions.assign(state.problems.size(), {});
      lobe_fitters_[thread].Fit(state.problems, state.solutions);
      for (std::size_t i = first; i < last; ++i) {
        const LatticeHeld& held = *refit[i];
        held_lobe_[held.pixel] = 0;
        ++state.lattice_lobes_own;
        const LobeSolution& solution = state.solutions[i - first];
        const PixelFit own = LobeFitFrom(solution, used[i - first], PixelModel::kBlinnPhong);
        if (!own.ok) continue;
        WriteFitToMap(held.pixel, own, result_);
        // Step 4's evidence: against the Lambertian fit on the same samples
        // (its criterion reads only the chi-square and the sample count).
        const PixelFit lambertian = LambertianFit(normal_of(held) * held.start_albedo / M_PI, held.lambertian_chi2,
                                                  own.used, 0);
        if (lambertian.Bic() - own.Bic() >= kConfidentLobeEvidence)
          confident[thread].push_back({held.pixel, static_cast<float>(solution.specular_albedo),
                                       static_cast<float>(solution.exponent)});
      }
    }
  }
  std::vector<GlossyPixel> all;
  for (const std::vector<GlossyPixel>& found : confident) all.insert(all.end(), found.begin(), found.end());
  return all;
}

void TileRefiner::RecordGgx(ThreadState& state, int p, const PixelFit& kept, bool held, const PixelFit& chosen) {
  WriteFitToMap(p, chosen, result_);
  ++state.ggx;
  switch (kept.model) {
    case PixelModel::kLambertian: ++state.ggx_from_lambertian; break;
    case PixelModel::kTrimmed: ++state.ggx_from_trimmed; break;
    default: ++(held ? state.ggx_from_held_lobe : state.ggx_from_blinn_phong); break;
  }
  state.samples_restored += static_cast<std::size_t>(std::max(0, chosen.used - kept.used));
}

void TileRefiner::OfferLowFrequency() {
  const Method method = options_.method;
  if (!(method == Method::kLowFrequency || (method == Method::kAuto && options_.selection.low_frequency))) return;
  // Listed before any thread starts: for `auto` the lobes (a matte scene
  // has almost none), for `low-frequency` every solved pixel.
  const LowFrequencyPlan plan = PlanLowFrequency(ladder_, *result_, held_lobe_, glossy_region_,
                                                 [this](std::span<const int> sample) {
    return ClimbLowFrequencyPixels(sample, true, false);
  });
  ClimbLowFrequencyPixels(plan.pixels, plan.test_lobe_shift, true);
  low_frequency_plan_ = {.pixels = {}, .test_lobe_shift = plan.test_lobe_shift, .sample = plan.sample};
}

LobeShiftTally TileRefiner::ClimbLowFrequencyPixels(std::span<const int> pixels, bool test_lobe_shift, bool write) {
  auto held = [this](int p) { return !held_lobe_.empty() && held_lobe_[p] != 0; };
  const int count = static_cast<int>(pixels.size());
  LobeShiftTally tally;
  if (count == 0) return tally;
  std::vector<LobeShiftTally> tallies(threads_);
  // Distant lights and one view: every pixel's samples share their half vectors.
  const LowFrequencyProblem lights{.lights = lights_,
                                   .wx = reader_.direction_axis(0),
                                   .wy = reader_.direction_axis(1),
                                   .wz = reader_.direction_axis(2),
                                   .stride = 1,
                                   .view = stack_.view_direction};
  const HalfVectorTable halves(lights);
#pragma omp parallel num_threads(std::min(threads_, 1 + count / 64))
  {
    ThreadState& state = states_[omp_get_thread_num()];
    LobeShiftTally& mine = tallies[omp_get_thread_num()];
    LowFrequencyFitter fitter(options_.selection.spike_fraction);
    state.rows = 0;
    const std::size_t row = NewRow(state);
    double* observed = &state.observed[row * lights_];
    double* inverse_sigma = &state.inverse_sigma[row * lights_];
    LowFrequencyProblem problem = lights;
    problem.observed = observed, problem.inverse_sigma = inverse_sigma, problem.halves = &halves;
#pragma omp for schedule(dynamic, 16)
    for (int i = 0; i < count; ++i) {
      const int p = pixels[i];
      const PixelFit kept = FitInMapWithChi2(*result_, p, held(p));
      int usable = 0;
      reader_.Row(p, kept.normal, observed, inverse_sigma, &usable);
      bool fell_back = false;
      LowFrequencyRule rule = LowFrequencyRule::kNone;
      const LowFrequencyOffer offer{.region_rejects_shape = !shape_rejected_.empty() && shape_rejected_[p] != 0,
                                    .test_lobe_shift = test_lobe_shift,
                                    .min_exponent = options_.blinn_phong.min_exponent};
      const PixelFit chosen =
          ClimbLowFrequency(ladder_, fitter, kept, problem, offer, &fell_back, write ? nullptr : &mine, &rule);
      if (!write) continue;
      if (chosen.model == PixelModel::kLowFrequency) RecordLowFrequency(state, p, kept, held(p), chosen, rule);
      state.fell_back += fell_back;
    }
    state.rows = 0;
  }
  for (const LobeShiftTally& t : tallies) tally += t;
  return tally;
}

void TileRefiner::RecordLowFrequency(ThreadState& state, int p, const PixelFit& kept, bool held,
                                     const PixelFit& low, LowFrequencyRule rule) {
  WriteFitToMap(p, low, result_);
  ++state.low_frequency;
  CountRule(rule, &state.low_rules);
  switch (kept.model) {
    case PixelModel::kLambertian: ++state.low_from_lambertian; break;
    case PixelModel::kTrimmed: ++state.low_from_trimmed; break;
    case PixelModel::kGgx: ++state.low_from_ggx; break;
    default: ++(held ? state.low_from_held_lobe : state.low_from_blinn_phong); break;
  }
  // The samples the kept fit had left out come back, less the spike the low-frequency fit leaves out.
  state.samples_restored += static_cast<std::size_t>(std::max(0, low.used + low.rejected - kept.used));
  state.rejected += static_cast<std::size_t>(low.rejected);
}

void TileRefiner::AddCounts(SolverSummary* summary) const {
  std::size_t failed = 0;
  // Steps 5-7 moved pixels between models counted on other threads: subtract
  // after summing.
  std::size_t from_lambertian = 0, from_trimmed = 0, from_blinn_phong = 0, from_held_lobe = 0, from_ggx = 0,
              restored = 0;
  for (const ThreadState& state : states_) {
    summary->pixels_lambertian += state.lambertian;
    summary->pixels_trimmed += state.trimmed;
    summary->pixels_irls += state.irls_fits;
    summary->pixels_blinn_phong += state.blinn_phong + state.shared_lobes + state.lattice_lobes;
    summary->pixels_shared_lobe += state.shared_lobes + state.lattice_lobes - state.lattice_lobes_own;
    summary->samples_rejected += state.rejected;
    summary->pixels_ggx += state.ggx;
    from_lambertian += state.shared_from_lambertian + state.ggx_from_lambertian;
    from_trimmed += state.shared_from_trimmed + state.ggx_from_trimmed;
    from_blinn_phong += state.ggx_from_blinn_phong + state.ggx_from_held_lobe;
    from_held_lobe += state.ggx_from_held_lobe;
    summary->pixels_low_frequency += state.low_frequency;
    from_lambertian += state.low_from_lambertian;
    from_trimmed += state.low_from_trimmed;
    from_blinn_phong += state.low_from_blinn_phong + state.low_from_held_lobe;
    from_held_lobe += state.low_from_held_lobe;
    from_ggx += state.low_from_ggx;
    summary->low_frequency_rules += state.low_rules;
    restored += state.samples_restored;
    summary->pixels_fell_back += state.fell_back;
    failed += state.failed;
  }
  summary->pixels_lambertian -= from_lambertian;
  summary->pixels_trimmed -= from_trimmed;
  summary->pixels_blinn_phong -= from_blinn_phong;
  summary->pixels_shared_lobe -= from_held_lobe;
  summary->pixels_ggx -= from_ggx;
  summary->samples_rejected -= restored;
  summary->pixels_solved -= failed;
  summary->pixels_rejected_by_model += failed;
  low_frequency_plan_.AddTo(summary);
}

}  // namespace photorig::solvers::ps::internal
