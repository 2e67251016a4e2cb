#pragma once
// `auto`'s steps 5 and 6 (model_selection.h) apart from how a pixel's samples
// are read: the plan over the image (which connected regions of solved
// pixels are glossy and the lobe each shares, the pixels offered it, the test
// of a region's shape on a sample of them, the lobes pooled from the nearest
// glossy pixels where a region rejects one shape, and the pixels then offered
// a GGX lobe), and the climbs of a batch of such pixels in lanes. The distant
// solve (TileRefiner) reads a pixel's samples under the stack's shared
// lights, the near-light solve with each pixel's own light and view vectors;
// both hand their rows to the same plan and climbs.

#include "kernels/lobe_lane_fit.h"
#include "kernels/low_frequency_fit.h"
#include "model_selection.h"

#include "photorig/solvers/ps/photometric_stereo.h"

#include <algorithm>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

namespace photorig::solvers::ps::internal {

// The fit a solved pixel p kept, as the map holds it (its chi-square is not kept).
PixelFit FitInMap(const NormalMap& map, int p);
// The same with its parameters (held: a lobe step 5 held, 3) and its
// chi-square as the map's confidence gives it: dof / confidence, or dof
// where the confidence is capped at 1 (a fit at or below the noise, which
// every adequacy test passes alike).
PixelFit FitInMapWithChi2(const NormalMap& map, int p, bool held);
// Writes `fit` as pixel p's answer: normal, albedo, model, lobe, samples used
// and confidence. Inline: the distant stages record every doubtful pixel through it.
inline void WriteFitToMap(int pixel, const PixelFit& fit, NormalMap* out) {
  out->normals.ptr<cv::Vec3f>()[pixel] = cv::Vec3f(float(fit.normal.x()), float(fit.normal.y()), float(fit.normal.z()));
  out->albedo.ptr<float>()[pixel] = static_cast<float>(fit.albedo);
  out->model.ptr<std::uint8_t>()[pixel] = static_cast<std::uint8_t>(fit.model);
  out->specular.ptr<cv::Vec2f>()[pixel] = cv::Vec2f(float(fit.specular_albedo), float(fit.exponent));
  out->usable_lights.ptr<std::uint16_t>()[pixel] = static_cast<std::uint16_t>(fit.used);
  // chi2 / dof is the residual variance relative to the noise: confidence = its
  // inverse, capped; 0 for a fit with no degree of freedom left to test it.
  const int dof = fit.Dof();
  out->confidence.ptr<float>()[pixel] =
      dof > 0 ? static_cast<float>(std::min(1.0, 1.0 / std::max(fit.chi2 / dof, 1e-12))) : 0.0f;
}

// A pixel that kept a lobe with kConfidentLobeEvidence, and its rho_s and e.
struct GlossyPixel {
  int pixel;
  float specular_albedo, exponent;
  // A lattice lobe held (step 4), not the pixel's own: it counts towards its
  // region's glossiness but is not pooled, being a median of pooled lobes.
  bool held = false;
};

// The median of `values` (not empty; reordered; the upper middle of an even
// count): rho_s and e are pooled so, one at a time, wherever a lobe is held.
inline float MedianOf(std::span<float> values) {
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

// A pixel offered a held lobe by step 5, in its region, and whether it takes
// part in its region's shape test (then the map is left as it is).
struct SharedLobeItem {
  int pixel, region;
  SharedLobe lobe;
  bool test_shape;
};

// The fits steps 5 and 6 ask of the caller, each on one of `threads` threads.
struct LobeSharingFits {
  // Once, before any fit, where some region is glossy (the state the fits
  // keep is made only then: a matte scene costs nothing).
  std::function<void()> begin;
  // Step 5's fits of `items`: with `tests` (one per region), each item's
  // part in its region's shape test (ModelLadder::AddToShapeTest), the map
  // unchanged; else the fits the ladder keeps, into the map.
  std::function<void(int thread, std::span<const SharedLobeItem> items, std::vector<SharedShapeTest>* tests)> share;
  // Step 6's fits of `pixels` (indices into the map), into the map where
  // the ladder keeps them; with `test`, each pixel's part in its region's
  // shape test instead (ModelLadder::AddToShapeTest's of a GGX fit), the
  // map unchanged.
  std::function<void(int thread, std::span<const int> pixels, SharedShapeTest* test)> offer_ggx;
  // Optional, once the shape tests are done and some region rejects its
  // shape, before the pooled lobes are drawn: each pixel holding a lattice
  // lobe (step 4) whose region rejects (rejects(pixel)) fits the lobe of its
  // own step 4 would have fitted, into the map; returns those of them
  // confidently glossy (the held lobe stood in on the premise of one shape).
  std::function<std::vector<GlossyPixel>(const std::function<bool(int pixel)>& rejects)> own_lobes;
};

// Whether some 8-connected region of solved pixels (flags kSolved) could be
// glossy in ShareLobes' sense: 16 or more of `glossy` in it, and at least
// `fraction` of its area. Exact, and settled by floods from the glossy
// pixels that stop at glossy.size() / fraction pixels: a matte scene with a
// few glossy pixels costs a few thousand pixels, not a labelling of the image.
bool AnyRegionCouldBeGlossy(const cv::Mat& flags, std::span<const GlossyPixel> glossy, double fraction);

// Steps 5 and 6 over `map` (its flags and models as steps 1-4 left them),
// `glossy` its confidently glossy pixels, on `threads` threads. A scene with
// fewer than 16 confidently glossy pixels, or no glossy region, costs nothing.
// Returns per pixel 1 where its region rejects one Blinn-Phong shape (empty
// where none does), for step 7 (LowFrequencyFits::region_rejects_shape).
std::vector<std::uint8_t> ShareLobes(const ModelLadder& ladder, double glossy_region_fraction, const NormalMap& map,
                                     std::vector<GlossyPixel> glossy, int threads, const LobeSharingFits& fits);

// One pixel of a step-5 batch: the fit steps 1-4 kept, its Lambertian fit on
// every usable sample (LambertianOnRow), its samples as a lobe fit reads
// them (`problem`: observed, inverse_sigma and, under near lights, geometry
// and view; the climb sets the rest), and the fits the climb makes.
struct SharingCandidate {
  const SharedLobeItem* item = nullptr;
  PixelFit kept, lambertian, lobe, own;
  LobeProblem problem;
  bool lobe_fitted = false, own_fitted = false;
  SharedLobeFits Fits() const {
    return {&kept, &lambertian, lobe_fitted ? &lobe : nullptr, item->test_shape, own_fitted ? &own : nullptr};
  }
};

// Step 5's climb of `batch` (pixels the ladder asks a held lobe of) in
// `fitter`'s lanes: every held lobe, then the own lobes a shape test asks
// for; done(candidate, chosen) with the fit the ladder keeps (in the shape
// test, its part is taken from candidate.Fits()).
void ClimbSharedLobes(const ModelLadder& ladder, LobeLaneFitter& fitter, std::span<SharingCandidate> batch,
                      const std::function<void(const SharingCandidate&, const PixelFit& chosen)>& done);
// The same climb from held lobes fitted already (each candidate's `lobe`,
// lobe_fitted): the own lobes a shape test asks for, from the candidates'
// rows (problem.observed, problem.inverse_sigma), then done().
void ClimbFromHeldLobes(const ModelLadder& ladder, LobeLaneFitter& fitter, std::span<SharingCandidate> batch,
                        const std::function<void(const SharingCandidate&, const PixelFit& chosen)>& done);

// One pixel of a step-6 batch: the fit steps 1-5 kept, that fit judged on
// every usable sample (`on_samples`, where the GGX fit starts), whether step
// 5 held its lobe, and its samples as the GGX fit reads them.
struct GgxCandidate {
  int pixel = 0;
  bool held = false;
  PixelFit kept, on_samples;
  LobeProblem problem;
};

// Step 6's GGX fits of `batch` in `fitter`'s lanes; keep(candidate, ggx) for
// each pixel whose GGX fit the ladder keeps.
void ClimbGgx(const ModelLadder& ladder, LobeLaneFitter& fitter, std::span<GgxCandidate> batch,
              const std::function<void(const GgxCandidate&, const PixelFit& ggx)>& keep);
// The same fits of `batch` for a region's shape test: each pixel's part,
// GGX kept or not, into `test` (ModelLadder::AddToShapeTest's).
void TestGgx(const ModelLadder& ladder, LobeLaneFitter& fitter, std::span<GgxCandidate> batch, SharedShapeTest* test);

// The solved pixels of `map` step 7 offers the low-frequency fit
// (ModelLadder::NextWithLowFrequency asks for it); held: step 5's held
// lobes (empty: none); test_lobe_shift: as LowFrequencyFits has it (every
// lobe, adequate or not). An adequate fit is settled from the map's
// confidence alone, so a matte scene costs one pass over four of its maps.
std::vector<int> LowFrequencyCandidates(const ModelLadder& ladder, const NormalMap& map,
                                        const std::vector<std::uint8_t>& held, bool test_lobe_shift);

// How step 7 takes a pixel: as LowFrequencyFits has them.
struct LowFrequencyOffer {
  bool region_rejects_shape = false;
  bool test_lobe_shift = false;
  // BlinnPhongOptions::min_exponent, the lobe fit's lower bound.
  double min_exponent = 0.0;
};

// Lobe-shift tests run (a lobe's low-frequency fits both succeeded) and
// how many of them found the lobe shifted (ModelLadder::LobeShifted).
struct LobeShiftTally {
  int tested = 0;
  int shifted = 0;
  LobeShiftTally& operator+=(const LobeShiftTally& other) {
    tested += other.tested, shifted += other.shifted;
    return *this;
  }
};

// Step 7's climb of one pixel (ModelLadder::NextWithLowFrequency): `kept`
// as FitInMapWithChi2 gives it, its samples in `problem` (the low-frequency
// fit's units: a lobe fit's, the samples over their gains). Returns the fit
// the ladder keeps, *fell_back where it stands in for a failed low-frequency
// fit (the `low-frequency` method's), and *rule (if not null) the rule that
// took it; adds its lobe-shift test to *tally (if not null: a sample's
// climb, which measures the shift even where the two normals agree and the
// lobe stands).
PixelFit ClimbLowFrequency(const ModelLadder& ladder, LowFrequencyFitter& fitter, const PixelFit& kept,
                           const LowFrequencyProblem& problem, const LowFrequencyOffer& offer, bool* fell_back,
                           LobeShiftTally* tally = nullptr, LowFrequencyRule* rule = nullptr);

// One more pixel given the low-frequency fit by `rule` in *counts.
void CountRule(LowFrequencyRule rule, LowFrequencyRuleCounts* counts);

// How many of a scene's lobes step 7 tests first, spread over them: if
// chance explains their shifts, no other lobe is tested (a scene whose
// lobes are its reflectance pays these fits only: about 1 ms, 1 % of
// `auto` on the shiny sphere); four or more shifted at the adequacy level
// 0.999 open the test to every lobe (chance gives four of 256 with
// probability 1.4e-4).
inline constexpr int kLobeShiftSample = 256;

// Step 7's pixels and whether the lobe-shift test runs on them. `auto`, in a
// scene with a glossy region (step 5's: glossy_region), climbs the
// sample of its lobes with climb_sample (lobe-shift test on, nothing
// written) and returns every lobe with the test where they fail it as a
// whole (ModelLadder::LobesFailShiftTest), else the lobes that fail the
// adequacy test, without it (also where the test is off,
// ModelLadder::lobe_shift_test, or no region is glossy); `low-frequency`
// every solved pixel.
struct LowFrequencyPlan {
  std::vector<int> pixels;
  bool test_lobe_shift = false;
  LobeShiftTally sample;  // the sample's tests
  // Into a summary's lobe_shift_ counts.
  void AddTo(SolverSummary* summary) const;
};
// held: per pixel, non-zero where the map's lobe is held (empty: none is).
LowFrequencyPlan PlanLowFrequency(const ModelLadder& ladder, const NormalMap& map, const std::vector<std::uint8_t>& held,
                                  bool glossy_region,
                                  const std::function<LobeShiftTally(std::span<const int> sample)>& climb_sample);

}  // namespace photorig::solvers::ps::internal
