#pragma once
// The refinement of the Lambertian pass's answer by the methods that go
// beyond it (`robust`, `blinn-phong`, `auto`), tile by tile: each tile is
// screened right after the Lambertian pass wrote it, on the same thread
// (SolveLambertianTiles' visitor), and its doubtful pixels are refined once
// the thread has collected enough of them: at once in a glossy tile, whose
// samples are still in cache, and every few dozen tiles in a matte scene,
// whose pass then streams on undisturbed.
//
// A tile's pixels climb ModelLadder. The screen settles most of them from the
// Lambertian pass's confidence alone. With the lane fitter the others go
// through the ladder's stages many pixels at a time: the exact test and the
// lit refit in float lanes straight from the planes (`auto`), then trimming
// (sixteen per pass), IRLS (eight) and the Blinn-Phong fit (sixteen), on
// queues that collect pixels across tiles, so that a tile with a few doubtful
// pixels does not run a full set of lanes for one of them; a pixel's samples
// are copied out when it is queued. With the per-pixel fitter each doubtful
// pixel climbs the ladder on its own (PerPixelFits), the reference.

#include "kernels/held_lobe_fit.h"
#include "kernels/lobe_lane_fit.h"
#include "kernels/irls_lambertian_fit.h"
#include "kernels/lambertian_recheck.h"
#include "kernels/trimmed_lambertian_fit.h"
#include "lobe_sharing.h"
#include "model_selection.h"
#include "per_pixel_fits.h"
#include "sample_reader.h"

#include "photorig/solvers/ps/photometric_stereo.h"

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

namespace photorig::solvers::ps::internal {

class TileRefiner {
 public:
  // stack: the one the Lambertian pass solves (its noise model complete);
  // lambertian: that pass's options (the shadow threshold raised as it was);
  // result: the pass's output, refined in place. All must outlive this.
  TileRefiner(const PhotometricStereoOptions& options, const LambertianOptions& lambertian,
              const PhotometricStack& stack, const ModelLadder& ladder, int threads, NormalMap* result);
  ~TileRefiner();

  // SolveLambertianTiles' visitor: refines pixels [begin, begin + count).
  void RefineTile(int thread, int begin, int count);
  // SolveLambertianTiles' last call on a thread: fits what is still queued.
  void Finish(int thread);
  // `auto`'s step 5, once every tile is refined: in each connected region of
  // solved pixels where enough pixels kept a lobe with very strong evidence,
  // their median rho_s and e are the region's lobe, and the region's pixels
  // kept Lambertian or trimmed are offered it (ModelLadder::NextWithSharedLobe);
  // in a region whose pixels reject that one shape (tested on a sample,
  // ModelLadder::RejectsSharedShape), each is offered the lobe of its
  // nearest confidently glossy pixels instead, and then (step 6,
  // ModelLadder::NextWithGgx) a GGX lobe of its own. Runs its own threads.
  void ShareLobe();
  // `auto`'s step 7, after step 5 and 6: the pixels PlanLowFrequency lists
  // (the lobes that fail the adequacy test, or every lobe where a sample of
  // them fails the lobe-shift test) are offered the low-frequency
  // reflectance (ModelLadder::NextWithLowFrequency), one pixel at a time on
  // the refiner's threads. Runs its own threads.
  void OfferLowFrequency();

  // The counts of models, rejected samples and failed fits, into a summary of
  // the Lambertian pass (whose counts of solved and rejected pixels they correct).
  void AddCounts(SolverSummary* summary) const;

 private:
  struct ThreadBuffers;
  struct ThreadState;
  struct Queued;
  // A pixel that kept a lattice lobe: where step 4 would have started its
  // own lobe fit, and the Lambertian fit's chi-square on its samples.
  struct LatticeHeld {
    int pixel;
    float start_normal[3], start_albedo;
    float lambertian_chi2;
  };

  // The Lambertian pass's solution x = albedo / pi n of pixel p.
  Eigen::Vector3d PassSolution(int p) const;
  // fell_back: `chosen` stands in for a fit that failed (LadderStep's);
  // evidence: LadderStep's, for a kept lobe.
  void Record(ThreadState& state, int p, const PixelFit& chosen, bool fell_back, double evidence = 0.0);
  // Step 5 on `items`: with `tests` (per region), their parts in their
  // regions' shape tests (items with test_shape), the map unchanged; else
  // the fits the ladder keeps, into the map.
  void ShareLobe(int thread, std::span<const SharedLobeItem> items, std::vector<SharedShapeTest>* tests);
  // Pixel p, kept as `kept`, takes the lobe fitted with its region's exponent.
  void RecordSharedLobe(ThreadState& state, int p, const PixelFit& kept, const PixelFit& lobe, int usable);
  // Step 6 for `pixels`: their GGX fits (in lanes, kBatch at a time, or one
  // by one), into the map where the ladder takes them; with `test`, their
  // parts in their region's shape test instead (LobeSharingFits::offer_ggx).
  void OfferGgx(int thread, std::span<const int> pixels, SharedShapeTest* test);
  // Step 5, where a region rejects one lobe shape (rejects(pixel)): a
  // lattice lobe stood in for a pixel's own on the premise that one shape
  // spans its neighbourhood, so each lattice-held pixel there fits the lobe
  // of its own step 4 would have fitted, from where step 4 would have
  // started it, before step 5 pools the nearest lobes and steps 6 and 7
  // judge it as its own. Returns those confidently glossy.
  std::vector<GlossyPixel> FitOwnLobesOfLattice(const std::function<bool(int pixel)>& rejects);
  // Pixel p, kept as `kept` (held: a lobe step 5 held), takes the GGX fit `ggx`.
  void RecordGgx(ThreadState& state, int p, const PixelFit& kept, bool held, const PixelFit& ggx);
  // Step 7's climb of `pixels` (OfferLowFrequency), into the map if `write`;
  // returns their lobe-shift tests.
  LobeShiftTally ClimbLowFrequencyPixels(std::span<const int> pixels, bool test_lobe_shift, bool write);
  // Pixel p, kept as `kept` (held as RecordGgx's), takes the low-frequency fit `low` by `rule`.
  void RecordLowFrequency(ThreadState& state, int p, const PixelFit& kept, bool held, const PixelFit& low,
                          LowFrequencyRule rule);
  // Climbs the ladder from `fits` as far as it goes without a lane stage: keeps
  // the pixel's answer, or queues it for the stage the ladder asks for.
  // samples: the pixel's samples as copied for trimming, if they were;
  // values: its raw values as copied for the recheck, if they were.
  void Climb(int thread, int p, const Eigen::Vector3d& x, const LadderFits& fits, const float* samples = nullptr,
             const float* values = nullptr);
  // A new row of the thread's rows (observed and inverse_sigma), its index.
  std::size_t NewRow(ThreadState& state) const;
  // Pixel p's samples as a new row of the thread's rows (from the planes, or
  // from their copy `samples`), and the Lambertian fit x tested on them.
  std::size_t GatherRow(ThreadState& state, int p, const Eigen::Vector3d& x, PixelFit* lambertian,
                        const float* samples = nullptr);
  // The exact test and lit refit of the thread's doubtful pixels from
  // `first` on, and their climbs; RefineTile collects them until there are
  // kDeferredDoubtful. copied: their samples are in the thread's copies
  // (doubtful_samples, from `first` on), not only in the planes.
  void ClimbDoubtful(int thread, std::size_t first, bool copied);
  // Lattice lobes (ModelSelectionOptions::lattice_lobes) for the glossy tile
  // of pixels [begin, end), once its lattice pixels have fitted their own
  // lobes: each pixel waiting for them is fitted with the median lobe of
  // the adequate confident lattice lobes nearest it in its row held, and keeps it
  // where the ladder does (KeepsLatticeLobe); the others, and every pixel
  // with fewer than kMinLatticeLobes of them in its row, are queued for
  // their own lobes. glossy_first: the thread's first glossy pixel recorded
  // for the tile.
  void HoldLatticeLobes(int thread, int begin, int end, std::size_t glossy_first);
  // The buffers of finished solves' threads, taken by a new solve's and given back when it ends.
  struct ThreadBufferPool;
  static ThreadBufferPool& BufferPool();
  static ThreadBuffers TakeThreadBuffers();
  static void GiveThreadBuffers(ThreadBuffers&& buffers);
  // The lane stages, on the thread's queues.
  void Trim(int thread);
  void Reweight(int thread);
  void FitLobes(int thread);
  // Runs the stages whose queues are full (all: every non-empty one) and
  // moves the rows still queued to the front.
  void Flush(int thread, bool all);

  const PhotometricStereoOptions& options_;
  const PhotometricStack& stack_;
  const ModelLadder& ladder_;
  NormalMap* result_;
  const bool lanes_;
  const int lights_;
  const std::vector<float> screen_threshold_;
  const SampleReader reader_;
  const RecheckLanes recheck_;
  const HeldLobeLanes held_lobes_;  // step 5's held lobes, straight from the planes
  const PerPixelFits per_pixel_;
  const int threads_;
  // Step 5 found a glossy region.
  bool glossy_region_ = false;
  // Step 7's plan, for the summary (its pixels dropped).
  LowFrequencyPlan low_frequency_plan_;
  std::vector<ThreadState> states_;
  std::vector<LobeLaneFitter> lobe_fitters_, ggx_fitters_;
  std::vector<TrimmedLambertianLanes> trimmers_;
  // In a glossy tile, only every 8th of the pixels that reach the lobe fit fits its own first.
  const bool lattice_lobes_;
  // Per pixel: non-zero where step 5 (1) or step 4's lattice lobes (2) gave
  // it a held lobe (as many parameters of its own as the Lambertian fit).
  std::vector<std::uint8_t> held_lobe_;
  // Per pixel: 1 where step 5 found the pixel's region rejecting one Blinn-Phong shape (empty: nowhere).
  std::vector<std::uint8_t> shape_rejected_;
};

}  // namespace photorig::solvers::ps::internal
