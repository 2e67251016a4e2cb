#pragma once
// What a photometric-stereo solve did, how long it took, and how many pixels
// it could not resolve. Solvers return this instead of throwing.

#include "photorig/solvers/core/summary.h"

#include <cstddef>
#include <string>

namespace photorig::solvers::ps {

// kSuccess: every pixel in the mask was either solved or flagged with a reason.
// kInvalidOptions, kInvalidInput, kFailure (degenerate lights): no result; see message.
using solvers::core::Termination;

// Of `auto`'s low-frequency pixels, how many each rule of step 7 gave the
// fit: the lobe-shift test found the lobe tilted; the fit explains its
// samples to the noise beyond the noise from the lobe, in a scene that
// opened the test; an inadequate Blinn-Phong lobe in a region that rejects
// the shape; the information criterion's very strong evidence.
struct LowFrequencyRuleCounts {
  std::size_t lobe_shifted = 0, explains_apart = 0, region_rejects_shape = 0, strong_evidence = 0;
  LowFrequencyRuleCounts& operator+=(const LowFrequencyRuleCounts& other) {
    lobe_shifted += other.lobe_shifted, explains_apart += other.explains_apart;
    region_rejects_shape += other.region_rejects_shape, strong_evidence += other.strong_evidence;
    return *this;
  }
};

struct SolverSummary : solvers::core::Summary {
  std::string method;

  double condition_number = 0.0;  // of the full light matrix A (K x 3)
  int light_count = 0;

  std::size_t pixels_total = 0;
  std::size_t pixels_solved = 0;
  std::size_t pixels_outside_mask = 0;
  std::size_t pixels_too_few_lights = 0;
  std::size_t pixels_ill_conditioned = 0;
  std::size_t pixels_rejected_by_model = 0;
  std::size_t samples_rejected = 0;   // shadowed or saturated samples left out of fits
  std::size_t pixels_on_light_subsets = 0;  // solved on their usable samples only (some shadowed or clipped)
  // Pixels explained by each model (kAuto's choices; one model for the others).
  std::size_t pixels_lambertian = 0;
  std::size_t pixels_trimmed = 0;  // Lambertian with its worst samples left out
  std::size_t pixels_irls = 0;     // Lambertian by iteratively reweighted least squares
  std::size_t pixels_blinn_phong = 0;
  // Of pixels_blinn_phong: fitted by `auto`'s step 5 with the exponent their
  // region shares (pixels whose own samples could not tell the lobe apart).
  std::size_t pixels_shared_lobe = 0;
  // Diffuse + GGX lobe: `auto`'s step 6, in regions whose lobe is not Blinn-Phong.
  std::size_t pixels_ggx = 0;
  // Low-frequency reflectance: `auto`'s step 7, where no model above explains the pixel.
  std::size_t pixels_low_frequency = 0;
  LowFrequencyRuleCounts low_frequency_rules;  // of those, by the rule of step 7 that took each
  // Step 7's lobe-shift test (ModelSelectionOptions::lobe_shift_test): of
  // the sample of lobes tried first, how many it tested and found shifted,
  // and whether it then tested every lobe (they failed it as a whole).
  std::size_t lobe_shift_sample_tested = 0;
  std::size_t lobe_shift_sample_shifted = 0;
  bool lobe_shift_every_lobe = false;
  // Pixels whose method's own fit failed and which kept a simpler fit instead
  // (`blinn-phong`: the trimmed, then the Lambertian fit; `robust` and `auto`:
  // the Lambertian fit), counted among the models above by the fit they kept.
  std::size_t pixels_fell_back = 0;
  // Whether the noise model used by the adequacy tests was (partly) estimated
  // from the residuals rather than given with the stack.
  bool noise_estimated = false;
  double noise_read_sigma = 0.0;  // the noise model the tests used, input units
  double noise_shot_gain = 0.0;
  double shadow_threshold = 0.0;  // I - D at or below which a sample counted as shadowed, input units
  // Of solve_ms: the Lambertian pass with each tile refined as it is written
  // (`auto`'s steps 1-4, and each thread's last queued fits: the slower
  // thread's end), `auto`'s steps 5-6 (the shared lobe, GGX) and step 7
  // (the low-frequency fit; all of `low-frequency`'s fit). Under near lights
  // tiles_ms is every round's per-pixel fits (NearLightSummary::depth_ms apart).
  double tiles_ms = 0.0;
  double shared_lobe_ms = 0.0;
  double low_frequency_ms = 0.0;

  std::string BriefReport() const;
};

}  // namespace photorig::solvers::ps
