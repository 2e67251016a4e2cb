#pragma once
// Spatially varying reflectance from a photometric stack with known normals:
// a diffuse albedo per pixel and channel, and a specular lobe shared by every
// pixel of a material. The number of materials and each material's lobe
// (none, Blinn-Phong, GGX; the models of photorig/solvers/brdf/models.h) are
// chosen by the Bayesian information criterion, so the result models no more
// than the data show.
//
// Per pixel p, light j and channel c the stack holds linear radiance
//   I_pjc = E_jc (rho_pc / pi + lobe_c(n_p, w_j, v)) (n_p . w_j)
// with E_jc the light's calibrated irradiance in that channel. For a fixed lobe
// shape the model is linear in the per-pixel albedos and the material's
// specular weight, so the solver eliminates the albedos exactly (a Schur
// complement per pixel) and searches the shape alone: a log-spaced grid, then
// golden-section refinement.
//
// Materials are k-means clusters (k = 1..max_materials) of per-pixel features:
// albedo chromaticity (three-channel stacks) and the pixel's own Blinn-Phong
// lobe (its weight and sharpness), of the pixels that saw a highlight (the
// others say nothing of a lobe, and take a material by their colour once the
// materials exist). Each k is scored by the BIC of the fit it leads to; the
// smallest wins.
//
// Every fit is weighted least squares under the sensor's noise model
// (SensorNoise: read noise plus shot noise that grows with the signal), so
// costs are chi-square values and every choice (a material's lobe, the number
// of materials, whether two materials are one) compares chi-square gains with
// the BIC's penalty: chi^2 + parameters ln(samples). With equal weights a
// bright highlight's shot noise would pass for structure that a split or a
// tiny lobe explains.

#include "photorig/solvers/brdf/models.h"
#include "photorig/solvers/camera/near_light.h"
#include "photorig/solvers/core/progress.h"
#include "photorig/solvers/core/summary.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace photorig::solvers::reflectance {

// Noise of one sample in image units, per channel:
//   variance = read_sigma^2 + shot_gain * max(signal, 0) + (relative * signal)^2
// For a linear camera shot_gain = camera gain / (electrons per DN); the
// relative term covers errors proportional to the signal (light-intensity
// flicker, a colour model's residual). All zero = unknown: FitReflectance
// estimates what is unknown from the data.
struct SensorNoise {
  Eigen::Vector3d read_sigma = Eigen::Vector3d::Zero();
  Eigen::Vector3d shot_gain = Eigen::Vector3d::Zero();
  Eigen::Vector3d relative = Eigen::Vector3d::Zero();
  double Variance(int channel, double signal) const;
  bool IsKnown() const { return read_sigma.maxCoeff() > 0.0 || shot_gain.maxCoeff() > 0.0 || relative.maxCoeff() > 0.0; }
};

// N images of C channels (C = 1 or 3), linear, dark already subtracted.
struct ReflectanceStack {
  std::vector<cv::Mat> images;                       // CV_32FC1 or CV_32FC3, same size
  std::vector<Eigen::Vector3d> light_directions;     // unit vectors towards each light
  // Per light and channel: the irradiance the light delivers at normal
  // incidence in image units per unit reflectance; (1, 1, 1) for a
  // calibrated stack whose albedo is relative. Empty = all ones.
  std::vector<Eigen::Vector3d> light_intensities;
  Eigen::Vector3d view_direction{0.0, 0.0, 1.0};     // towards the camera (orthographic)
  // Where each pixel sees the lights and the camera from, where that varies
  // over the image; empty: light_directions and view_direction for every
  // pixel. near_lights: one LED per image (a near dome); then points_mm
  // (CV_32FC3, the surface point each pixel sees, in the LEDs' frame) is
  // required, and a sample sees its LED along its own direction with
  // Intensity(j) times the LED's RelativeIrradiance there. views (CV_32FC3):
  // each pixel's unit vector towards the camera (a pinhole camera).
  std::vector<camera::NearLight> near_lights;
  cv::Mat points_mm;
  cv::Mat views;
  // Samples at or above this value are clipped by the sensor: left out of
  // every fit and counted (SaturatedHighlights).
  double saturation_level = std::numeric_limits<double>::infinity();
  // The sensor's noise. Where read_sigma is given but shot_gain is not (a
  // colour stack: demosaicing and the colour model change the shot noise per
  // channel) the shot and relative terms are estimated; all zero: all three.
  SensorNoise noise;

  int width() const { return images.empty() ? 0 : images.front().cols; }
  int height() const { return images.empty() ? 0 : images.front().rows; }
  int channels() const { return images.empty() ? 0 : images.front().channels(); }
  int light_count() const { return static_cast<int>(images.size()); }
  Eigen::Vector3d Intensity(int light) const;  // (1, 1, 1) when none are given
  bool IsValid(std::string* why) const;
};

// Why a pixel has (or lacks) reflectance. Stored in ReflectanceMaps::flags.
enum class PixelFlag : std::uint8_t {
  kFitted = 0,
  kOutsideMask = 1,    // masked out by the caller
  kNoNormal = 2,       // the normal map is NaN here
  kTooFewSamples = 3,  // fewer than min_samples lit, unsaturated samples
  kPoorFit = 4,        // residual far above its material's: the model does not explain it
  // The demosaiced colour mixes two paints or the background (MixedPixels):
  // kept out of the choice of materials, then given the material that
  // explains it best (albedo filled) or, where none does, left without one.
  kMixed = 5,
};
const char* PixelFlagName(PixelFlag flag);

// Conditions under which the data cannot support what was fitted; each is
// raised on the materials it concerns and listed in the summary.
enum class Warning : std::uint8_t {
  kTooFewHighlightLights,  // a lobe seen under fewer than min_highlight_lights lights: shape unreliable
  kHighlightsUnobserved,   // most of a material's pixels saw no highlight: its lobe is unconstrained there
  kSaturatedHighlights,    // clipped samples in a material: its lobe's peak was never measured
  kInconsistentIntensities // a light's images disagree with the others by more than max_intensity_error
};
const char* WarningName(Warning warning);

struct MaterialFit {
  brdf::Model model = brdf::Model::kLambertian;  // kLambertian: no lobe
  Eigen::Vector3d specular = Eigen::Vector3d::Zero();  // k_s (Blinn-Phong) or F0 (GGX), per channel
  double shape = 0.0;                                  // exponent e (Blinn-Phong) or roughness a (GGX)
  Eigen::Vector3d specular_sigma = Eigen::Vector3d::Zero();  // one standard deviation
  double shape_sigma = 0.0;                                  // of the shape, relative (sigma / shape)
  int pixels = 0;
  double rms_residual = 0.0;          // image units, over its samples
  double bic = 0.0;                   // of the chosen lobe
  double bic_lambertian = 0.0;        // of no lobe, for comparison
  double min_half_angle_deg = 0.0;    // median over pixels of the smallest angle between n and h
  // Pixels that saw a highlight (ReflectanceMaps::highlight_seen); the lobe
  // was chosen and fitted on these alone. Under half of `pixels`: the lobe is
  // unconstrained (kHighlightsUnobserved), whatever model it shows.
  int highlight_pixels = 0;
  int highlight_lights = 0;           // lights that put samples inside the fitted lobe's half width
  std::vector<Warning> warnings;
};

struct ReflectanceMaps {
  cv::Mat albedo;        // CV_32FC(C) diffuse rho_d; NaN where not fitted
  cv::Mat albedo_sigma;  // CV_32FC(C) one standard deviation; NaN where not fitted
  cv::Mat material;      // CV_8U index into `materials`; 255 where not fitted
  cv::Mat flags;         // CV_8U PixelFlag
  cv::Mat rms_residual;  // CV_32F per pixel, image units; NaN where not fitted
  cv::Mat normals;       // CV_32FC3, the normals the reflectance was fitted with
  // CV_8U per pixel: 1 when one of its usable samples has its half vector
  // within unobserved_half_angle_deg of the normal (it saw a highlight), 0
  // when none has (its lobe was never seen: it took its material by colour
  // or by its neighbours), 255 where no reflectance was fitted.
  cv::Mat highlight_seen;
  std::vector<MaterialFit> materials;
};

struct ReflectanceOptions {
  // Largest number of materials tried (1 = one material for the whole object). Default 4.
  int max_materials = 4;
  // Lobes a material may have; kLambertian (no lobe) is always a candidate. Default both.
  std::vector<brdf::Model> lobes = {brdf::Model::kBlinnPhong, brdf::Model::kGgx};
  // Samples with n . w below this are left out (grazing light, attached shadow). Default 0.05.
  double min_cosine = 0.05;
  // Pixels with fewer lit, unsaturated samples are flagged kTooFewSamples. Default 6.
  int min_samples = 6;
  // A pixel whose residual exceeds this many times its material's is flagged kPoorFit. Default 6.
  double poor_fit_ratio = 6.0;
  // False-alarm probability of the mixed-pixel test (three-channel stacks):
  // a pixel is flagged kMixed when its albedo chromaticity lies between those
  // of two opposite neighbours and differs from each by more than the
  // chi-square (2 dof) quantile at this level, or when its demosaicing window
  // reaches off the object. 0 turns the test off. Default 0.001.
  double mixed_pixel_alpha = 1e-3;
  // False-alarm probability of telling two materials of one lobe model apart:
  // materials the clustering split are merged unless their pixels' own lobe
  // weights form two groups at this level (docs/reflectance.md). Default 0.001.
  double split_alpha = 1e-3;
  // Pixels per material used for the lobe-shape search (a deterministic
  // subsample); the albedos are then solved for every pixel. Default 2000.
  int shape_search_pixels = 2000;
  // k-means restarts per k (deterministic seeds). Default 4.
  int kmeans_restarts = 4;
  // Fewer distinct lights inside a lobe's half width raise kTooFewHighlightLights. Default 3.
  int min_highlight_lights = 3;
  // A pixel saw a highlight when one of its usable (lit, unclipped) samples
  // has its half vector within this angle of the normal: a lobe at least
  // this wide puts half its peak or more into that sample. Only such pixels
  // choose the materials and their lobes; a material most of whose pixels
  // saw none raises kHighlightsUnobserved. Default 20 degrees.
  double unobserved_half_angle_deg = 20.0;
  // Clipped samples above this fraction of a material's samples raise kSaturatedHighlights. Default 0.002.
  double max_saturated_fraction = 0.002;
  // A light whose median ratio of measured to predicted radiance is off by
  // more than this raises kInconsistentIntensities. Default 0.08.
  double max_intensity_error = 0.08;
  // Reports "per-pixel", "materials k=..", "albedo" stages.
  core::ProgressCallback progress;

  bool IsValid(std::string* why) const;
};

struct ReflectanceSummary : core::Summary {
  int pixels_fitted = 0;
  int pixels_outside_mask = 0;
  int pixels_no_normal = 0;
  int pixels_too_few_samples = 0;
  int pixels_poor_fit = 0;
  int pixels_mixed = 0;           // flagged kMixed (kept out of the choice of materials)
  int pixels_mixed_assigned = 0;  // of those, given the material that explains them
  int pixels_highlight_unseen = 0;  // fitted pixels that saw no highlight (highlight_seen = 0)
  int materials_unobserved = 0;     // materials formed by pixels that saw no highlight, told apart by colour
  long long saturated_samples = 0;
  int materials = 0;
  std::vector<double> bic_by_materials;  // [k - 1]: BIC of the best fit with k materials
  SensorNoise noise;                     // the noise model the fit weighted by
  std::string noise_source;              // "given", "estimated" or "read noise given, shot noise estimated"
  double reduced_chi_square = 0.0;       // chi^2 per residual of the chosen fit (about 1 when the noise model holds)
  int materials_merged = 0;              // materials the clustering split whose pixels form one group (split test)
  std::vector<Warning> warnings;         // the union over materials, plus stack-wide ones
  std::vector<int> inconsistent_lights;  // lights behind kInconsistentIntensities
  std::vector<double> light_intensity_ratio;  // per light: median measured / predicted
};

// Fits the reflectance of every masked pixel with a finite normal. `normals`
// is CV_32FC3 of the stack's size; `mask` optional CV_8U (zero = skip).
ReflectanceSummary FitReflectance(const ReflectanceOptions& options, const ReflectanceStack& stack,
                                  const cv::Mat& normals, const cv::Mat& mask, ReflectanceMaps* maps);

}  // namespace photorig::solvers::reflectance
