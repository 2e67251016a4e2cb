#pragma once
// Model selection: the record of one model's fit of a pixel, when a fit
// explains the pixel (chi-square against the noise), how two fits compare
// (the Bayesian information criterion), and the ladder of `auto` (and of the
// single-model methods) from the Lambertian pass's fit to the model kept.
// The per-pixel reference (per_pixel_fits.cpp) and the lane stages
// (tile_refiner.cpp) both climb it through ModelLadder::Next.

#include "photorig/solvers/ps/photometric_stereo.h"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace photorig::solvers::ps::internal {

// Quantile p of the chi-square distribution for 0..max_dof degrees of
// freedom, by Wilson-Hilferty: accurate to a few per cent for dof >= 3, plenty
// for a test threshold. Entry 0 is 0.
std::vector<double> ChiSquareQuantiles(int max_dof, double p);
// The same for one number of degrees of freedom (>= 1).
double ChiSquareQuantile(int dof, double p);

// The normal's two degrees of freedom, rho_d, rho_s and e.
inline constexpr int kBlinnPhongParameters = 5;
// The same with the lobe (rho_s and e) shared by the pixel's region (step 5):
// as many of its own as the Lambertian fit.
inline constexpr int kSharedLobeParameters = 3;
// The normal's two degrees of freedom, rho_d, rho_s and the roughness a.
inline constexpr int kGgxParameters = 5;

// A lobe step 5 holds for a pixel: the medians of rho_s and e over
// confidently glossy pixels (its region's, or its nearest ones').
struct SharedLobe {
  double specular_albedo = 0.0, exponent = 0.0;
};
// A lobe kept by an information criterion this much below the simpler fit's
// ("very strong" evidence on Kass and Raftery's scale) marks its pixel as
// glossy for step 5: its exponent is pooled and its region counted glossy.
inline constexpr double kConfidentLobeEvidence = 10.0;

// One model's fit of one pixel.
struct PixelFit {
  bool ok = false;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  double albedo = 0.0;
  double specular_albedo = 0.0;
  double exponent = 0.0;   // Blinn-Phong's e; GGX's roughness a (the model says which)
  double chi2 = 0.0;     // sum of squared residuals over variance, on the samples used
  int parameters = 3;
  int used = 0;          // samples with weight >= inlier threshold (all for least squares)
  int rejected = 0;
  PixelModel model = PixelModel::kLambertian;

  double Bic() const { return chi2 + parameters * std::log(std::max(used, 1)); }
  int Dof() const { return used - parameters; }
};

// The Lambertian fit x of a pixel with its chi-square on `used` samples,
// `rejected` of its usable ones left out.
inline PixelFit LambertianFit(const Eigen::Vector3d& x, double chi2, int used, int rejected) {
  PixelFit fit;
  const double length = x.norm();
  fit.ok = length > 0.0;
  fit.normal = fit.ok ? Eigen::Vector3d(x / length) : x;  // as x.normalized()
  fit.albedo = M_PI * length;
  fit.chi2 = chi2;
  fit.used = used;
  fit.rejected = rejected;
  return fit;
}

// The fits a pixel's climb has made so far, owned by the caller. Null: not
// fitted yet; kNoFit (or any fit with ok false): fitted, without an answer.
struct LadderFits {
  // The Lambertian fit on the usable samples, tested exactly. Never null.
  const PixelFit* lambertian = nullptr;
  // The same refitted without the usable samples it puts in attached shadow.
  const PixelFit* lit = nullptr;
  // Trimmed (`auto`, `blinn-phong`) or iteratively reweighted (`robust`).
  const PixelFit* robust = nullptr;
  // The Blinn-Phong fit, and the Lambertian fit on the samples it was fitted
  // to, which the information criterion weighs it against. (The lane stages
  // read those samples again in double; their `lambertian` was tested on the
  // float recheck's sums.) Both or neither.
  const PixelFit* blinn_phong = nullptr;
  const PixelFit* lobe_lambertian = nullptr;
};
inline const PixelFit kNoFit{};

// Which of step 7's rules (ModelLadder::NextWithLowFrequency) gave `auto`'s
// pixel the low-frequency fit.
enum class LowFrequencyRule : std::uint8_t {
  kNone,                // not step 7's low-frequency fit, or the `low-frequency` method's
  kLobeShifted,         // the lobe-shift test found the lobe tilted
  kExplainsApart,       // the fit explains its samples, beyond the noise from the lobe
  kRegionRejectsShape,  // an inadequate Blinn-Phong lobe in a region that rejects the shape
  kStrongEvidence,      // the information criterion, by kConfidentLobeEvidence or more
};

// What a pixel's climb does next.
struct LadderStep {
  enum class Action {
    kKeep,        // `keep` is the pixel's answer
    kRefitLit,    // fit LadderFits::lit
    kTrim,        // fit LadderFits::robust by trimming
    kReweight,    // fit LadderFits::robust by IRLS
    kFitLobe,     // fit LadderFits::blinn_phong, starting from `start`
    kFitSharedLobe,  // step 5: fit SharedLobeFits::lobe with the lobe held, starting from `start`
    kFitOwnLobe,     // step 5's shape test: fit SharedLobeFits::own, starting from `start`
    kFitGgx,         // step 6: fit GgxFits::ggx, starting from `start`
    kFitLowFrequency  // step 7: fit LowFrequencyFits::low_frequency, starting from `start`
  };
  Action action = Action::kKeep;
  const PixelFit* keep = nullptr;   // kKeep: one of the fits asked about
  const PixelFit* start = nullptr;  // kFitLobe: the normal and albedo to start from
  // kKeep: the last fit the ladder asked for failed, and `keep` is a simpler
  // one below it (the model map says which).
  bool fell_back = false;
  // kKeep of a lobe fit: how far its information criterion is below the
  // simpler fit's (kConfidentLobeEvidence and more: a confidently glossy pixel).
  double evidence = 0.0;
  // kKeep of `auto`'s low-frequency fit: the rule that took it.
  LowFrequencyRule low_frequency_rule = LowFrequencyRule::kNone;
};

// Step 5's fits of a pixel that steps 1-4 kept without a lobe, in a glossy
// region: the fit kept, the Lambertian fit on all its usable samples
// (LambertianOnRow), the fit with a lobe held (SharedLobe), and, for a pixel
// of its region's shape test (test_shape, SharedShapeTest), its own lobe
// fitted from the grid at the kept normal (null: not fitted yet).
struct SharedLobeFits {
  const PixelFit* kept = nullptr;
  const PixelFit* lambertian = nullptr;
  const PixelFit* lobe = nullptr;
  bool test_shape = false;
  const PixelFit* own = nullptr;
};

// Whether a glossy region's pixels reject the lobe it shares, by a likelihood
// ratio: over pixels the held lobe explains (adequate, and below the
// Lambertian fit), the sum of its chi-square less that of the pixel's own
// lobe (at least 0: the own lobe nests the held one). Where the region's
// lobe is the pixels' own, that sum is chi-square with two degrees of
// freedom per pixel (the two the own lobe frees). Pixels the held lobe does
// not explain (a matte pixel, one with spikes from inter-reflection) say
// nothing about the lobe's shape.
//
// A region that test does not reject is tested on its own lobes too (on a
// metal every pixel's samples see the lobe, every pixel keeps one of its
// own, and the test has no pixel to judge): each against its GGX fit, on
// the same samples and with as many parameters. On a Blinn-Phong object GGX
// fits a pixel's samples about as well as the lobe that made them, so very
// strong evidence for GGX (kConfidentLobeEvidence) on most of them says the
// lobe is not Blinn-Phong.
struct SharedShapeTest {
  double chi2_gain = 0.0;
  int pixels = 0;
  int own_lobes = 0;      // own lobes tested against GGX
  int own_lobes_ggx = 0;  // of them, those GGX replaces on very strong evidence
};

// Step 6's fits of a pixel in a region whose pixels reject one Blinn-Phong
// shape: the fit steps 1-5 kept, re-evaluated on all its usable samples
// (chi-square and parameters: a Lambertian or trimmed fit as
// LambertianOnRow, a lobe of its own 5, a lobe held by step 5 3), and the GGX
// fit of those samples (null: not fitted yet).
struct GgxFits {
  const PixelFit* kept = nullptr;
  const PixelFit* ggx = nullptr;
};

// Step 7's fits of a pixel: the fit steps 1-6 kept, with its chi-square and
// parameters (FitInMapWithChi2), and its low-frequency fit (null: not fitted yet).
struct LowFrequencyFits {
  const PixelFit* kept = nullptr;
  const PixelFit* low_frequency = nullptr;
  // The kept fit on the samples the low-frequency fit used (KeptOnLights).
  const PixelFit* kept_on_samples = nullptr;
  // The kept lobe's core lies within the samples the low-frequency fit
  // leaves out (SpikePinsNormal).
  bool spike_pins_normal = false;
  // The pixel's glossy region rejects one Blinn-Phong shape (step 5's
  // RejectsSharedShape).
  bool region_rejects_shape = false;
  // Of a kept Blinn-Phong lobe, where its region rejects the shape: its
  // exponent is at the fit's lower bound (BlinnPhongOptions::min_exponent),
  // and the chi-square of its own term over the usable samples (how far the
  // lobe moves them, in their noise; BlinnPhongTermChi2).
  bool lobe_at_exponent_bound = false;
  double lobe_term_chi2 = 0.0;
  // Test the kept lobe by the low-frequency fit's view of it (the lobe-shift
  // test, ModelLadder::NextWithLowFrequency), adequate or not.
  bool test_lobe_shift = false;
  // How far the low-frequency fit's normal lies from the one the same fit
  // makes of the kept lobe's own prediction of the same samples, in the
  // former's covariance: chi-square with two degrees of freedom where the
  // lobe is the pixel's reflectance (0: not measured).
  double lobe_shift_chi2 = 0.0;
  // How far the same fit of the lobe's prediction lands from the lobe's own
  // normal, in the same covariance: the low-frequency fit's bias on this
  // lobe (infinity: not measured).
  double lobe_bias_chi2 = std::numeric_limits<double>::infinity();
  // How far the low-frequency fit's normal lies from the lobe's, in the same
  // covariance (0: not measured).
  double lobe_offset_chi2 = 0.0;
};

class ModelLadder {
 public:
  // lights: the stack's light count (the largest sample count a pixel has).
  ModelLadder(Method method, const ModelSelectionOptions& options, int lights);

  // The fit's chi-square is below the adequacy quantile for its degrees of
  // freedom: its residual is at the noise level.
  bool Adequate(const PixelFit& fit) const {
    return fit.ok && fit.Dof() > 0 && fit.chi2 <= quantile_[fit.Dof()];
  }
  // The same below the stricter quantile `auto` keeps a Lambertian fit at.
  bool LambertianAdequate(const PixelFit& fit) const {
    return fit.ok && fit.Dof() > 0 && fit.chi2 <= lambertian_quantile_[fit.Dof()];
  }

  // The ladder itself. For `auto`, per pixel:
  //   1. the Lambertian fit, if adequate at the stricter lambertian_quantile,
  //      or if no sample is left to test or trim (3 usable);
  //   2. else its refit without the samples it puts in attached shadow, if
  //      adequate;
  //   3. else trimming (at most max_rejected_fraction of the samples); with
  //      no more samples than the lobe has parameters (a lobe would pass
  //      through every sample), the trimmed fit if adequate, else the
  //      Lambertian fit;
  //   4. else the Blinn-Phong fit from the trimmed one (or the Lambertian fit
  //      where trimming failed), kept if its information criterion is lower
  //      than the Lambertian fit's on the same samples; else the trimmed fit
  //      if adequate, else that Lambertian fit. An adequate trimmed fit does
  //      not end the climb: the samples it dropped are a highlight's core,
  //      and the lobe's shoulders it kept still tilt its normal.
  // `robust` keeps the IRLS fit, `blinn-phong` the lobe fitted from the
  // trimmed fit, `lambertian` and `l2` the Lambertian fit. Where the fit a
  // method asked for fails, it falls back: `blinn-phong` to the trimmed fit,
  // then the Lambertian fit; `robust` and `auto` to the Lambertian fit (the
  // step's fell_back). Only a pixel whose Lambertian fit fails too has none.
  // Inline: the lane stages ask it once per pixel and stage, with most of
  // `fits` known where they call.
  inline LadderStep Next(const LadderFits& fits) const;

  // Step 5 (`auto` only), once every pixel has climbed steps 1-4: a pixel
  // kept Lambertian or trimmed in a region that is glossy (enough of its
  // pixels kept a lobe with kConfidentLobeEvidence) is fitted with the
  // region's lobe held, its normal and rho_d free: as many parameters of its
  // own as the Lambertian fit (the region's two cost each of its pixels two
  // over the region's size: nothing), so the two compare by chi-square
  // alone, a likelihood ratio. Where the pixel's samples could show the lobe
  // and do not (a matte pixel in a glossy region), the held lobe misfits and
  // the Lambertian fit stays; where they cannot tell, the region's lobe
  // removes the tilt its tails put into the Lambertian normal. Elsewhere
  // `kept` stands.
  // In a region whose pixels reject the shared shape (RejectsSharedShape),
  // the lobe held is the one pooled from the pixel's nearest confidently
  // glossy pixels: there a lobe's best Blinn-Phong exponent varies over the
  // object. A pixel of the shape test (test_shape) is fitted its own lobe
  // too, for the test only.
  inline LadderStep NextWithSharedLobe(const SharedLobeFits& fits) const;
  // Step 4 with lattice lobes (ModelSelectionOptions::lattice_lobes): a
  // pixel the ladder sent to the lobe fit keeps the lobe of the lattice
  // pixels around it, held (`held`, kSharedLobeParameters), where that
  // explains its samples and its chi-square is below the Lambertian fit's on
  // them (`lambertian`): the held lobe costs the pixel no parameter, so the
  // two compare by the likelihood ratio, as in step 5. Else the pixel fits
  // its own lobe (Next's step 4).
  bool KeepsLatticeLobe(const PixelFit& held, const PixelFit& lambertian) const {
    return method_ == Method::kAuto && Adequate(held) && lambertian.ok && held.chi2 < lambertian.chi2;
  }
  // A pixel's part in its region's SharedShapeTest, from fits that climbed
  // NextWithSharedLobe with test_shape to the end.
  void AddToShapeTest(const SharedLobeFits& fits, SharedShapeTest* test) const;
  // An own lobe's part in its region's SharedShapeTest, from fits that
  // climbed NextWithGgx to the end (the kept lobe on its usable samples).
  void AddToShapeTest(const GgxFits& fits, SharedShapeTest* test) const;
  // The test's sum is above the adequacy quantile of chi-square with two
  // degrees of freedom per pixel, or GGX replaces most of the own lobes
  // tested on very strong evidence.
  bool RejectsSharedShape(const SharedShapeTest& test) const;

  // Step 6 (`auto` only), for the pixels of a region that RejectsSharedShape
  // (there the lobe is not Blinn-Phong): a GGX lobe of the pixel's own,
  // fitted from the kept normal, replaces the kept fit where its information
  // criterion is lower on the same samples. Only there: on a Blinn-Phong
  // object GGX fits a pixel's samples about as well as the lobe that made
  // them, and per pixel the criterion would pick either by chance.
  inline LadderStep NextWithGgx(const GgxFits& fits) const;

  // Step 7 (`auto`, ModelSelectionOptions::low_frequency), once steps 1-6
  // are done: the low-frequency reflectance (no lobe shape; the brightest
  // spike_fraction of the samples left out as a spike it cannot make) is
  // fitted to a pixel that kept a lobe (steps 4-6) that fails the adequacy
  // test, and kept where its region rejects one Blinn-Phong shape (a
  // Blinn-Phong lobe whose own term the samples see, its exponent above the
  // fit's lower bound: outright where determined) or where the information
  // criterion is lower than
  // the kept fit's on the same samples (the ones it fitted) by
  // kConfidentLobeEvidence or more: very strong evidence, as the two are not
  // nested and the ladder chose the kept fit already (with any lower
  // criterion, 0.5-4 % of the pixels of simulated Blinn-Phong scenes switch
  // by chance and their mean error rises by up to 0.5 %). Not offered to a
  // lobe whose core (the half vectors within its half maximum) holds at
  // least one of the pixel's samples and no more than the fit leaves out: a
  // sampled spike's position pins the normal, and that fit would drop it.
  // With test_lobe_shift (a scene whose lobes fail the lobe-shift test as a
  // whole, LobesFailShiftTest), every lobe but a pinned spike is offered the
  // fit, and takes it outright where determined and LobeShifted: the
  // low-frequency fit of its samples lands further from where it lands on
  // the lobe's own prediction of them than the noise explains, and further
  // than that is from the lobe's normal, and beyond the noise from the
  // lobe's normal; or where the fit is determined and adequate and its
  // normal lies beyond the noise from the lobe's, adequate lobe or not.
  // The `low-frequency` method keeps the fit wherever it succeeds (else the
  // Lambertian fit, fell_back).
  inline LadderStep NextWithLowFrequency(const LowFrequencyFits& fits) const;
  // A pixel's lobe-shift chi-square (LowFrequencyFits::lobe_shift_chi2) is
  // above the adequacy quantile of chi-square with two degrees of freedom.
  bool LobeShifted(double lobe_shift_chi2) const { return lobe_shift_chi2 > two_dof_quantile_; }
  // A lobe's own term moves its samples further than two free parameters
  // fit to noise alone (the same quantile): the samples see the lobe.
  bool LobeTermSeen(double lobe_term_chi2) const { return lobe_term_chi2 > two_dof_quantile_; }
  // Of `tested` lobes of a scene (a sample spread over its lobes), `shifted`
  // are LobeShifted: more than chance gives at the adequacy level (the
  // binomial tail at or beyond `shifted` is below 1 - adequacy_quantile).
  bool LobesFailShiftTest(int shifted, int tested) const;

  // Per usable sample count, the Lambertian pass's confidence at or above
  // which a pixel passes step 1 without a closer look (infinity where none
  // does, and for every count unless the method is `auto`): the confidence is
  // dof / chi-square with the noise variance averaged over the samples, so
  // the threshold is dof / quantile[dof]. (The exact test weights each sample
  // by its own variance; the two differ only near the threshold.) Float, as
  // the confidence is.
  std::vector<float> ScreenThresholds() const;

  // The confidence (WriteFitToMap's min(1, dof / chi-square)) at or above
  // which a fit with dof > 0 degrees of freedom is adequate.
  float AdequateConfidence(int dof) const { return static_cast<float>(dof / quantile_[dof]); }

  // The adequacy quantile per degree of freedom, 0..lights.
  const std::vector<double>& quantiles() const { return quantile_; }
  // Trimming drops samples beyond this squared number of sigmas together.
  double gross_u2() const { return gross_u2_; }
  // At most this many of `usable` samples may be trimmed.
  int MaxRejected(int usable) const { return static_cast<int>(max_rejected_fraction_ * usable); }
  Method method() const { return method_; }
  // `auto` tries step 7's lobe-shift test (ModelSelectionOptions::lobe_shift_test).
  bool lobe_shift_test() const { return method_ == Method::kAuto && low_frequency_ && lobe_shift_test_; }

 private:
  static LadderStep Keep(const PixelFit& fit) { return {LadderStep::Action::kKeep, &fit, nullptr}; }
  static LadderStep KeepLowFrequency(const PixelFit& low, LowFrequencyRule rule) {
    LadderStep step = Keep(low);
    step.low_frequency_rule = rule;
    return step;
  }
  // `asked` failed: keep `fallback` instead, or `asked` (no normal) where it failed too.
  static LadderStep FallBack(const PixelFit& asked, const PixelFit& fallback) {
    if (asked.ok || !fallback.ok) return Keep(asked);
    return {LadderStep::Action::kKeep, &fallback, nullptr, true};
  }

  Method method_;
  std::vector<double> quantile_, lambertian_quantile_;
  double gross_u2_, max_rejected_fraction_, adequacy_quantile_;
  // Chi-square's quantile at adequacy_quantile with two degrees of freedom.
  double two_dof_quantile_;
  bool low_frequency_, lobe_shift_test_;
};

inline LadderStep ModelLadder::Next(const LadderFits& fits) const {
  using Action = LadderStep::Action;
  const PixelFit& lambertian = *fits.lambertian;
  switch (method_) {
    case Method::kL2:
    case Method::kLambertian:
    case Method::kLowFrequency: return Keep(lambertian);  // kLowFrequency: its fit comes in step 7
    case Method::kRobust:
      if (!fits.robust) return {Action::kReweight};
      return FallBack(*fits.robust, lambertian);
    case Method::kBlinnPhong:
      if (!fits.robust) return {Action::kTrim};
      if (!fits.blinn_phong) return {Action::kFitLobe, nullptr, fits.robust->ok ? fits.robust : &lambertian};
      return FallBack(*fits.blinn_phong, fits.robust->ok ? *fits.robust : *fits.lobe_lambertian);
    case Method::kAuto: break;
  }
  // A richer model is fitted only where the samples can tell it apart: with
  // no sample to spare nothing can be tested or trimmed.
  if (LambertianAdequate(lambertian) || !(lambertian.Dof() > 0)) return Keep(lambertian);
  if (!fits.lit) return {Action::kRefitLit};
  if (Adequate(*fits.lit)) return Keep(*fits.lit);
  if (!fits.robust) return {Action::kTrim};
  const PixelFit& trimmed = *fits.robust;
  // A trimmed fit adequate with nothing dropped is the Lambertian fit itself,
  // between the two quantiles.
  const bool trimmed_adequate = Adequate(trimmed);  // it trimmed at most its allowance
  const PixelFit& adequate_simpler = trimmed.rejected > 0 ? trimmed : lambertian;
  if (lambertian.used <= kBlinnPhongParameters) return Keep(trimmed_adequate ? adequate_simpler : lambertian);
  if (!fits.blinn_phong) return {Action::kFitLobe, nullptr, trimmed.ok ? &trimmed : &lambertian};
  // The information criterion decides between the models fitted to all
  // usable samples; where the lobe does not pay for its parameters, an
  // adequate simpler fit stands.
  const PixelFit& lobe = *fits.blinn_phong;
  if (lobe.ok && lobe.Bic() < fits.lobe_lambertian->Bic()) {
    LadderStep step = Keep(lobe);
    step.evidence = fits.lobe_lambertian->Bic() - lobe.Bic();
    return step;
  }
  const PixelFit& simpler = trimmed_adequate ? adequate_simpler : *fits.lobe_lambertian;
  return lobe.ok ? Keep(simpler) : FallBack(lobe, simpler);
}

inline LadderStep ModelLadder::NextWithSharedLobe(const SharedLobeFits& fits) const {
  const PixelFit& kept = *fits.kept;
  const bool simpler = kept.model == PixelModel::kLambertian || kept.model == PixelModel::kTrimmed;
  // As in step 4: a lobe is fitted only where a sample is left to test it.
  if (method_ != Method::kAuto || !kept.ok || !simpler || !fits.lambertian->ok ||
      fits.lambertian->used <= kSharedLobeParameters)
    return Keep(kept);
  if (!fits.lobe) return {LadderStep::Action::kFitSharedLobe, nullptr, &kept};
  if (fits.test_shape && !fits.own && fits.lambertian->used > kBlinnPhongParameters)
    return {LadderStep::Action::kFitOwnLobe, nullptr, &kept};
  const PixelFit& lobe = *fits.lobe;
  if (lobe.ok && lobe.chi2 < fits.lambertian->chi2) return Keep(lobe);
  return Keep(kept);
}

inline LadderStep ModelLadder::NextWithGgx(const GgxFits& fits) const {
  const PixelFit& kept = *fits.kept;
  // As in step 4: a lobe is fitted only where a sample is left to test it.
  if (method_ != Method::kAuto || !kept.ok || kept.used <= kGgxParameters) return Keep(kept);
  if (!fits.ggx) return {LadderStep::Action::kFitGgx, nullptr, &kept};
  const PixelFit& ggx = *fits.ggx;
  if (!(ggx.ok && ggx.Bic() < kept.Bic())) return Keep(kept);
  LadderStep step = Keep(ggx);
  step.evidence = kept.Bic() - ggx.Bic();
  return step;
}

inline LadderStep ModelLadder::NextWithLowFrequency(const LowFrequencyFits& fits) const {
  const PixelFit& kept = *fits.kept;
  if (method_ == Method::kLowFrequency) {
    if (!kept.ok) return Keep(kept);
    if (!fits.low_frequency) return {LadderStep::Action::kFitLowFrequency, nullptr, &kept};
    return FallBack(*fits.low_frequency, kept);
  }
  if (method_ != Method::kAuto || !low_frequency_ || !kept.ok || !(kept.Dof() > 0)) return Keep(kept);
  // A fit without a lobe was weighed against a lobe by steps 4-6 already,
  // and no richer model paid for its parameters (on a matte object these
  // are the noise's chance failures; offering them the fit too changed no
  // figure of the simulated or DiLiGenT scenes and cost matte `auto` 0.4x
  // `l2`); a spike that pins the normal is what the low-frequency fit
  // leaves out; an adequate lobe explains its samples, unless the lobe-shift
  // test is asked for.
  const bool lobe = kept.model == PixelModel::kBlinnPhong || kept.model == PixelModel::kGgx;
  if (!lobe || fits.spike_pins_normal) return Keep(kept);
  const bool adequate = Adequate(kept);
  if (adequate && !fits.test_lobe_shift) return Keep(kept);
  if (!fits.low_frequency) return {LadderStep::Action::kFitLowFrequency, nullptr, &kept};
  const PixelFit& low = *fits.low_frequency;
  // The low-frequency fit is taken outright only where its samples determine
  // it (as many degrees of freedom left as it has parameters; under a
  // 12-light dome they do not, and its normal follows the noise).
  const bool determined = low.ok && low.Dof() >= low.parameters;
  // The lobe-shift test: were the lobe the pixel's reflectance, the
  // low-frequency fit of the samples would land where it lands on the
  // lobe's own prediction of them, give or take the noise. Where it lands
  // further off, the samples hold something the lobe has not explained and
  // has tilted its normal to absorb (light the surface sends back to
  // itself, a soft shadow, a lobe of another shape), which the fit that
  // assumes no lobe shape takes: provided the samples move it further than
  // it is off on the lobe's prediction (its own bias on this lobe), and its
  // normal lies beyond the noise from the lobe's (else the two agree, and
  // the lobe's fit need not be repeated). Where
  // the lobe is sharper than its quadratic can follow, that bias is large,
  // changes with whatever else the lobe fit absorbs, and the shift measures
  // the change rather than a tilt (on a Blinn-Phong lobe of exponent 20
  // beside a retro-reflecting diffuse, 13 of 1,024 pixels took fits 10 deg
  // off without this condition).
  if (fits.test_lobe_shift && determined && LobeShifted(fits.lobe_offset_chi2) && LobeShifted(fits.lobe_shift_chi2) &&
      fits.lobe_bias_chi2 < fits.lobe_shift_chi2)
    return KeepLowFrequency(low, LowFrequencyRule::kLobeShifted);
  // Two explanations of the samples in a scene whose lobes, as a whole, are
  // not the shape its samples have (test_lobe_shift): the low-frequency fit
  // explains them to the noise (its spike left out) and determines its
  // normal, and the lobe's normal lies beyond that noise from it. The
  // low-frequency normal rests on the samples and no lobe shape; the lobe's
  // also on its Blinn-Phong or GGX shape, which these samples do not need
  // and the scene has shown to be wrong, so the difference is that shape's
  // tilt, even where the lobe's own chi-square passes and the test above
  // sees no shift (the lobe then bends the low-frequency fit as far as the
  // samples do). A scene whose lobes have the samples' shape passes the
  // test as a whole and never comes here (an exact e = 20 lobe beside a
  // retro-reflecting diffuse: 3 of 138 sampled lobes shift).
  if (fits.test_lobe_shift && determined && Adequate(low) && LobeShifted(fits.lobe_offset_chi2))
    return KeepLowFrequency(low, LowFrequencyRule::kExplainsApart);
  if (adequate) return Keep(kept);
  // A Blinn-Phong lobe that leaves its samples unexplained, in a region
  // that rejects one Blinn-Phong shape (step 5): the pixel and its region
  // both say the shape is wrong, so the residuals are systematic and the
  // normal has tilted to absorb them; no criterion on those residuals can
  // weigh the lobe fairly against a fit that assumes no lobe shape, which
  // is taken outright where determined. Only where the pixel's lobe has a
  // shape to be wrong: its exponent above the fit's lower bound (there the
  // lobe is as broad as the diffuse term) and its own term seen in the
  // samples (LobeTermSeen). A lobe below the noise, or a narrow one whose
  // tail touches a sample or two, cannot have tilted the normal by its
  // shape; what the pixel leaves unexplained is then not the lobe's, and
  // the fit that drops its brightest samples loses what pins the normal
  // (on a measured felt whose sharp lobe falls between the lights, taking
  // it raised those pixels' error from 2.1 to 3.1 deg). A GGX lobe is the
  // shape step 6 offered such a region instead: what it leaves may be
  // foreign light, judged below.
  const bool misspecified = fits.region_rejects_shape && kept.model == PixelModel::kBlinnPhong &&
                            !fits.lobe_at_exponent_bound && LobeTermSeen(fits.lobe_term_chi2);
  if (misspecified && determined) return KeepLowFrequency(low, LowFrequencyRule::kRegionRejectsShape);
  // The two are not nested and the ladder chose the kept fit already: the
  // low-frequency fit replaces it on very strong evidence only. Where even
  // the low-frequency fit leaves residuals far above the noise, chi-square
  // differences overstate the evidence by that factor: they are divided by
  // its chi-square per degree of freedom (a quasi-likelihood criterion's
  // variance inflation, at least 1).
  const PixelFit& judged = *fits.kept_on_samples;
  if (low.ok && judged.ok && low.Dof() > 0) {
    const double inflation = std::max(1.0, low.chi2 / low.Dof());
    const double penalty = (low.parameters - judged.parameters) * std::log(std::max(low.used, 1));
    if ((judged.chi2 - low.chi2) / inflation - penalty > kConfidentLobeEvidence)
      return KeepLowFrequency(low, LowFrequencyRule::kStrongEvidence);
  }
  return Keep(kept);
}

inline void ModelLadder::AddToShapeTest(const GgxFits& fits, SharedShapeTest* test) const {
  const PixelFit& kept = *fits.kept;
  if (!kept.ok || kept.model != PixelModel::kBlinnPhong) return;
  ++test->own_lobes;
  if (fits.ggx && fits.ggx->ok && kept.Bic() - fits.ggx->Bic() >= kConfidentLobeEvidence) ++test->own_lobes_ggx;
}

inline void ModelLadder::AddToShapeTest(const SharedLobeFits& fits, SharedShapeTest* test) const {
  if (!fits.lobe || !fits.own || !fits.own->ok || !Adequate(*fits.lobe) ||
      !(fits.lobe->chi2 < fits.lambertian->chi2))
    return;
  // The held lobe is the own lobe with rho_s and e fixed, so the own fit's
  // best is never worse: a negative difference is an own fit that stopped
  // short of it (from its exponent grid), and the pixel's ratio is then 0.
  test->chi2_gain += std::max(0.0, fits.lobe->chi2 - fits.own->chi2);
  ++test->pixels;
}

}  // namespace photorig::solvers::ps::internal
