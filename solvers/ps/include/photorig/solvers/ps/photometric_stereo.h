#pragma once
// Photometric stereo behind one entry point: pick a method, or let `kAuto`
// pick per pixel the simplest reflectance model the data support.
//
//   kL2          Lambertian least squares on every sample (fastest; biased by
//                shadows, highlights and clipping).
//   kLambertian  Lambertian least squares on the unshadowed, unsaturated
//                samples of each pixel (per-sample thresholds).
//   kRobust      kLambertian, then iteratively reweighted least squares with a
//                robust loss, which down-weights samples no Lambertian surface
//                explains (specular highlights, partial shadows).
//   kBlinnPhong  diffuse + normalised Blinn-Phong lobe fitted per pixel by
//                Levenberg-Marquardt, started from the trimmed Lambertian fit
//                (see BlinnPhongOptions for how the derivatives are computed).
//   kAuto        per pixel: kLambertian if its residual is at the noise level
//                (chi-square test), or once refitted without usable samples
//                the fit itself puts in attached shadow; else kBlinnPhong
//                started from Lambertian with the worst samples trimmed
//                greedily, kept where the Bayesian information criterion
//                prefers it to the Lambertian fit, else the trimmed fit
//                (PixelModel::kTrimmed) if that is adequate while rejecting
//                few samples, else the Lambertian fit. Then, in each region
//                of the image glossy enough to know its lobe, the pixels
//                kept without one take that lobe where it explains their
//                samples better (ModelSelectionOptions::share_lobe); in a
//                region whose pixels reject one Blinn-Phong shape, each
//                pixel takes a GGX lobe of its own (PixelModel::kGgx) where
//                the information criterion prefers it. Last, a pixel whose
//                lobe fails the adequacy test (unless a spike its samples
//                see pins its normal) takes the low-frequency reflectance
//                of kLowFrequency where the criterion prefers it, by very
//                strong evidence, on the samples that fit uses
//                (ModelSelectionOptions::low_frequency).
//   kLowFrequency  per pixel, I = max(0, n.l)(a0 + a1 n.h + a2 (n.h)^2 +
//                a3 cos theta_d) with every a >= 0, fitted without the
//                pixel's brightest samples (ModelSelectionOptions::
//                spike_fraction): a reflectance that only grows towards the
//                mirror direction and with the half angle, with no lobe
//                shape to assume. Wrong by degrees where a lobe model is
//                exact (it drops the highlight that pins the normal); on
//                real objects whose gloss is not one lobe (painted, glazed,
//                sheen) the most accurate single method
//                (docs/photometric-stereo-accuracy.md).
//   Where a method's own fit fails, the pixel falls back to a simpler one
//   (SolverSummary::pixels_fell_back).

#include "photorig/solvers/autodiff/blinn_phong_jacobian.h"
#include "photorig/solvers/ps/lambertian.h"
#include "photorig/solvers/ps/stack.h"
#include "photorig/solvers/ps/summary.h"
#include "photorig/solvers/core/names.h"
#include "photorig/solvers/core/progress.h"

#include <optional>
#include <string>
#include <string_view>

namespace photorig::solvers::ps {

enum class Method { kL2, kLambertian, kRobust, kBlinnPhong, kAuto, kLowFrequency };
inline constexpr core::NameTable<Method, 6> kMethodNames = {{{Method::kL2, "l2"},
                                                             {Method::kLambertian, "lambertian"},
                                                             {Method::kRobust, "robust"},
                                                             {Method::kBlinnPhong, "blinn-phong"},
                                                             {Method::kAuto, "auto"},
                                                             {Method::kLowFrequency, "low-frequency"}}};
inline const char* MethodName(Method method) { return core::NameOf(kMethodNames, method); }
inline std::optional<Method> ParseMethod(std::string_view name) { return core::ParseName(kMethodNames, name); }

struct RobustOptions {
  enum class Loss {
    kCauchy,  // smooth, never rejects a sample entirely; c = 2.385
    kHuber,   // convex, bounded influence but no rejection; c = 1.345
    kTukey    // redescending: gross outliers get weight 0; c = 4.685
  };
  // Tukey's biweight by default: specular highlights are gross outliers, and
  // only a redescending loss removes their pull entirely. It is not convex, so
  // the first `warmup_iterations` use the Cauchy loss to reach its basin.
  Loss loss = Loss::kTukey;
  int warmup_iterations = 3;
  int max_iterations = 20;
  double relative_tolerance = 1e-6;  // stop when |dx| <= tol * |x|
  // A sample whose final weight is below this counts as rejected.
  double inlier_weight = 0.5;
  bool IsValid(std::string* why) const;
};

struct BlinnPhongOptions {
  // How the lobe fits (Blinn-Phong, and `auto`'s GGX) run. kLanes: sixteen
  // pixels at once, one per SIMD lane, with the closed-form derivatives
  // evaluated in float (the tests check them against forward-mode automatic
  // differentiation); several times faster than one pixel at a time
  // (docs/performance.md).
  // kPerPixel: one pixel at a time with Jacobians by `derivative`: the
  // reference, and the way to compare derivative methods.
  enum class Fitter { kLanes, kPerPixel };
  Fitter fitter = Fitter::kLanes;
  solvers::autodiff::DerivativeMethod derivative = solvers::autodiff::DerivativeMethod::kForward;  // kPerPixel only
  int max_iterations = 40;
  // Stop when a step lowers the cost (chi-square) by less than this fraction
  // (the lane fitter also stops when the linearised model promises less).
  // The lane fitter evaluates in float and takes changes below 1e-5 of the
  // cost for rounding, so with it tolerances below 1e-5 act as 1e-5: on a
  // chi-square near its degrees of freedom that is a change far below 1.
  double relative_tolerance = 1e-6;
  double min_exponent = 1.0;     // below this the lobe is indistinguishable from the diffuse term
  double max_exponent = 2000.0;  // narrower lobes fall between the lights of any practical dome
  bool IsValid(std::string* why) const;
};

// How the Blinn-Phong fit gets its Jacobians, as requests name it: the lane
// fitter (closed form), or one pixel at a time by an autodiff method.
enum class BlinnPhongDerivative { kLanes, kForward, kReverse, kSymbolic, kCentralDifference };
inline constexpr core::NameTable<BlinnPhongDerivative, 5> kBlinnPhongDerivativeNames = {
    {{BlinnPhongDerivative::kLanes, "lanes"},
     {BlinnPhongDerivative::kForward, "forward"},
     {BlinnPhongDerivative::kReverse, "reverse"},
     {BlinnPhongDerivative::kSymbolic, "symbolic"},
     {BlinnPhongDerivative::kCentralDifference, "central-difference"}}};
// Sets options->fitter (and options->derivative for the per-pixel fit).
void UseDerivative(BlinnPhongDerivative derivative, BlinnPhongOptions* options);

struct ModelSelectionOptions {
  // A fit is adequate when its chi-square statistic is below this quantile of
  // the chi-square distribution with n - p degrees of freedom.
  double adequacy_quantile = 0.999;
  // kAuto keeps the Lambertian fit on the usable samples without looking
  // further only below this quantile (at most adequacy_quantile).
  // A lobe's tails add less than the 0.999 quantile allows (about 1.76 times
  // the noise variance for 50 samples) and still tilt the normal; below it, a
  // fit between the two quantiles is weighed against the Blinn-Phong fit by
  // the information criterion. Equal by default: 0.99 gains about 1 % of mean
  // error on glossy realistic scenes (docs/photometric-stereo.md) but sends
  // 1 % of a matte object's pixels, by chance, to a lobe fit they do not
  // need, doubling matte auto's time (docs/performance.md).
  double lambertian_quantile = 0.999;
  // kAuto prefers the trimmed Lambertian fit over kBlinnPhong only when it
  // rejects at most this fraction of a pixel's usable samples.
  double max_rejected_fraction = 0.25;
  // Trimming drops samples beyond this many noise sigmas together, with every
  // sample within a factor 2 of the worst residual, in one round (otherwise
  // one sample per round); a pixel with more of them than max_rejected_fraction
  // allows goes straight to the Blinn-Phong fit. 5 sigma: a sample of a good
  // fit lies beyond it with probability 6e-7.
  double gross_outlier_sigma = 5.0;
  // kAuto's step 5 (docs/photometric-stereo.md, "The `auto` ladder"): one
  // lobe per material. In a connected region of solved pixels where at least
  // glossy_region_fraction of the pixels (and 16 or more) kept a lobe with
  // very strong evidence (information criterion 10 below the Lambertian
  // fit's), the pixels kept Lambertian or trimmed are fitted with the lobe
  // held at the region's median rho_s and exponent (at their nearest glossy
  // pixels' where a likelihood-ratio test on a sample of them rejects one
  // shape for the region, as a GGX lobe's, or GGX replaces most of a
  // sample of the region's own lobes on very strong evidence, as on a
  // metal), and keep it where it lowers
  // chi-square below the Lambertian fit's. Their own samples cannot tell the
  // lobe apart, yet it tilts their normals (on the realistic shiny spheres,
  // a tenth to a third of the pixels). 5 %: fifty times the rate at which
  // chance sends a matte pixel to the lobe.
  bool share_lobe = true;
  double glossy_region_fraction = 0.05;
  // kAuto's step 7: a pixel whose kept lobe fails the adequacy test (a lobe
  // of another shape, a shoulder, light the surface sends back to itself)
  // is fitted kLowFrequency's reflectance, and keeps it where the
  // information criterion on the samples it fitted is lower by
  // kConfidentLobeEvidence (PixelModel::kLowFrequency; the ladder's
  // NextWithLowFrequency). spike_fraction (both methods): the share of a
  // pixel's usable samples, brightest first, that fit leaves out as a spike
  // it cannot make. 10 %: the samples a highlight of half-width 6.7 deg (a
  // Blinn-Phong exponent of 100) covers under a dome whose half vectors
  // span 22 deg (DiLiGenT's 96 lights): (1 - cos 6.7 deg) / (1 - cos 21.6
  // deg) = 0.097.
  bool low_frequency = true;
  double spike_fraction = 0.10;
  // Step 7's lobe-shift test: were a kept lobe the pixel's reflectance, the
  // low-frequency fit of its samples would land where it lands on the
  // lobe's own prediction of them, within the noise. Where it lands further
  // off (chi-square of the shift above adequacy_quantile), and further than
  // that is from the lobe's normal (the fit's own bias on the lobe), the
  // lobe has tilted its normal to absorb what it does not model (light the
  // surface sends back to itself, a soft shadow) and the low-frequency fit
  // is taken, adequate lobe or not (never a sampled spike that pins its
  // normal). Only in a scene with a glossy region (step 5's, so only with
  // share_lobe): tried on 256 of its lobes first, and on every lobe where
  // they fail it more often than chance at that level. On the simulated
  // scenes it changes nothing; on DiLiGenT's five objects `auto` goes from
  // 8.07 to 7.47 deg (docs/photometric-stereo-accuracy.md).
  bool lobe_shift_test = true;
  // kAuto's step 4 with the lane fitter, in a tile of kDeferredDoubtful (512)
  // or more doubtful pixels (a glossy stretch of the image): only every 8th
  // pixel (pixel index a multiple of 8) of those the ladder sends to the lobe
  // fit fits its own lobe first; each of the others is fitted with the median
  // rho_s and exponent of the lattice lobes nearest it in its row that are
  // confident and adequate held (as step 5 holds a region's lobe), and keeps
  // that where it is adequate and its chi-square below the Lambertian fit's
  // on the same samples, else fits its own lobe as before. A material's lobe
  // varies slowly over its surface and costs a pixel nothing it must pay
  // for itself; its own five-parameter fit is the slow part of the climb.
  // Where step 5's shape test rejects one lobe shape for the region, the
  // pixel fits its own lobe before step 5 pools lobes (held ones are never
  // pooled). The per-pixel fitter fits every pixel's own lobe (the
  // reference).
  bool lattice_lobes = true;
  bool IsValid(std::string* why) const;
};

struct PhotometricStereoOptions {
  Method method = Method::kAuto;
  LambertianOptions lambertian;  // thresholds shared by every method
  RobustOptions robust;
  BlinnPhongOptions blinn_phong;
  ModelSelectionOptions selection;
  // When the stack's noise model lacks a shot-noise gain, fit one (and the read
  // noise, if unknown too) to the residuals before testing adequacy. Off: the
  // stack's noise model is taken as complete.
  bool estimate_noise = true;
  // When > 0, samples within this many read-noise sigmas of the dark level
  // count as shadowed too: the shadow threshold becomes the larger of
  // lambertian.shadow_threshold and this multiple of the read noise. The read
  // noise is the stack's (from dark frames) or, where the stack has none (a
  // data set without dark frames), estimated from the residuals as above (then
  // for `lambertian` too, and once more at the raised threshold). A noise
  // lift of three sigmas puts one shadowed sample in 740 above it. 0: the
  // absolute threshold only. SolverSummary::shadow_threshold reports the one used.
  double shadow_threshold_read_sigmas = 0.0;
  // Pixels solved so far, under the method's name as the stage: the Lambertian
  // pass and the refinement run tile by tile together, so one count covers
  // both. Called on the thread that called SolvePhotometricStereo, about
  // every percent of the image. Empty: no reports.
  solvers::core::ProgressCallback progress;
  // A stack must carry signal: at least three of its images (a normal needs
  // three lights) must each have min_signal_pixels pixels this many read-noise
  // sigmas above the dark, else the solve ends kFailure rather than solve
  // noise (a black stack from lights that never came on). Noise alone puts
  // one pixel in 3.5 million above 5 sigma. Tested only where the stack has
  // a dark and its read noise (a black level to measure against); it stops
  // reading as soon as three images pass, so it costs next to nothing on a
  // healthy stack. 0: off.
  double min_signal_read_sigmas = 5.0;
  int min_signal_pixels = 16;
  bool IsValid(std::string* why) const;
};

// Never throws on bad data; see SolverSummary and the per-pixel flags.
SolverSummary SolvePhotometricStereo(const PhotometricStereoOptions& options, const PhotometricStack& stack,
                                     NormalMap* result);

}  // namespace photorig::solvers::ps
