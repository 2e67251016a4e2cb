#pragma once
// The stages of FitReflectance (fit_reflectance.cpp), in the order it runs
// them, and what they hand each other:
//   fit_gather.cpp     which pixels can be fitted, the noise model, and which
//                      of them choose the materials (not mixed, saw a highlight)
//   fit_materials.cpp  the number of materials and their lobes, then the
//                      materials that are one paint cut in two merged
//   fit_assign.cpp     a material for each pixel that saw no highlight
//   fit_albedo.cpp     each material's pixels: albedo, its deviation,
//                      residual, poor fits
//   fit_assign.cpp     a material for each mixed pixel that one explains
//   fit_warnings.cpp   what the lights could show of each material, and
//                      whether the lights' intensities agree with the fit
// grouping.cpp holds the statistics they share: k-means and the tests of
// whether two groups of pixels are one.

#include "photorig/solvers/reflectance/fit.h"

#include "samples.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <cstdint>
#include <limits>
#include <vector>

namespace photorig::solvers::reflectance::internal {

// ---- fit_gather.cpp ----

// The pixels with at least min_samples usable samples; the others are
// flagged kTooFewSamples in *flags.
std::vector<int> ActivePixels(const Samples& s, int min_samples, cv::Mat* flags);
// Counts the pixels *flags marks outside the mask, without a normal or with too few samples.
void CountUnfitted(const cv::Mat& flags, ReflectanceSummary* summary);

// Each active pixel's own Blinn-Phong lobe, fitted with equal weights and
// again with the samples weighted by the noise model.
struct OwnLobes {
  std::vector<PixelLobe> equal_weights;
  std::vector<PixelLobe> weighted;
};
// The noise model (given, or estimated from each pixel's own lobe fitted
// with equal weights), then every sample weighted by it and the own lobes
// refitted. Sets the summary's noise and noise_source.
OwnLobes WeightByNoise(const SensorNoise& given, const std::vector<int>& active, const core::ProgressCallback& progress,
                       Samples* s, ReflectanceSummary* summary);

// The active pixels by what they can tell about the materials.
struct PixelClasses {
  std::vector<Eigen::Vector2d> chroma;      // per gathered pixel (equal-weight albedo); empty for one channel
  std::vector<double> smallest_half_angle;  // per gathered pixel (SmallestHalfAngles), radians
  std::vector<std::uint8_t> seen;           // per gathered pixel: 1 when it saw a highlight
  std::vector<int> clustered;               // choose the materials and their lobes
  std::vector<int> mixed;                   // MixedPixels: assigned once the materials exist
  std::vector<int> unseen;                  // saw no highlight: assigned by colour or position
  std::vector<Eigen::VectorXd> features;    // per clustered pixel: chromaticity and own lobe
};
PixelClasses ClassifyPixels(const ReflectanceOptions& options, const Samples& s, const std::vector<int>& active,
                            const OwnLobes& own);

// ---- fit_materials.cpp ----

struct Partition {
  std::vector<std::vector<int>> groups;  // pixel indices (into Samples) per material
  std::vector<MaterialResult> materials;
  double bic = std::numeric_limits<double>::infinity();
};

// The clustering of the clustered pixels into k = 1..max_materials
// materials of least BIC; *bic_by_materials gets each k's BIC.
Partition ChooseMaterials(const ReflectanceOptions& options, const Samples& s, const PixelClasses& classes,
                          const std::vector<brdf::Model>& candidates, std::vector<double>* bic_by_materials);
// Merges the materials the clustering split but one paint explains; returns how many merges.
int MergeOnePaintSplits(const ReflectanceOptions& options, const Samples& s, const std::vector<brdf::Model>& candidates,
                        Partition* best);

// ---- fit_albedo.cpp ----

// What the per-material fit leaves for the stages after it.
struct FittedPixels {
  std::vector<int> material_of;     // per gathered pixel: its material's group, -1 for none
  std::vector<double> rms;          // per gathered pixel: RMS residual of the pixels written
  std::vector<double> typical_rms;  // per material: the median of its pixels' RMS residuals
  double chi_square = 0.0;          // over the materials' pixels
  long long residuals = 0;
};

// Pixel p's RMS residual in image units under a material (what the
// poor-fit test compares: a residual the model leaves, in the units the
// relit images are judged in) and its chi-square.
struct PixelResidual {
  double rms = 0.0, squared_sum = 0.0, chi_square = 0.0;
  long long count = 0;
};
// Also sets rho[channel], the pixel's albedo under the material.
PixelResidual ResidualOf(const Samples& s, int p, const PixelSums& sums, const MaterialFit& fit, double* rho);
// Writes pixel p's albedo, its deviation, residual and material m into *maps and fitted->rms.
PixelResidual WritePixel(const Samples& s, int p, int m, const PixelSums& sums, const MaterialFit& fit,
                         ReflectanceMaps* maps, FittedPixels* fitted);

// Sizes *maps and fits every material's pixels: albedos, deviations,
// residuals, poor-fit flags; appends the materials to maps->materials.
FittedPixels FitMaterialPixels(const ReflectanceOptions& options, const Samples& s, const cv::Mat& normals,
                               const PixelClasses& classes, const Partition& best, cv::Mat* flags,
                               ReflectanceMaps* maps, ReflectanceSummary* summary);

// ---- fit_assign.cpp ----

// Gives each unseen pixel a material; true when they formed one of their
// own, appended to *groups (fit_assign.cpp says how).
bool AssignUnseen(const Samples& s, const std::vector<Eigen::Vector2d>& chroma, const std::vector<int>& unseen,
                  double alpha, const std::vector<MaterialFit>& materials, std::vector<std::vector<int>>* groups);

// Flags the mixed pixels kMixed and gives each the material that explains
// it as well as the poor-fit test asks of that material's own pixels.
void AssignMixed(const ReflectanceOptions& options, const Samples& s, const std::vector<int>& mixed,
                 FittedPixels* fitted, cv::Mat* flags, ReflectanceMaps* maps, ReflectanceSummary* summary);

// ---- fit_warnings.cpp ----

void AddWarning(std::vector<Warning>* list, Warning w);
// What the lights could show of the material of `group`: its pixel counts,
// median smallest half angle, lights inside its lobe, and the warnings these raise.
void DescribeLighting(const ReflectanceOptions& options, const Samples& s, const std::vector<int>& group,
                      const PixelClasses& classes, MaterialFit* fit);
// Per light: measured over predicted radiance where the diffuse term
// dominates; lights off by more than max_intensity_error are listed.
void CheckLightIntensities(const ReflectanceOptions& options, const Samples& s, const std::vector<int>& active,
                           const FittedPixels& fitted, const ReflectanceMaps& maps, ReflectanceSummary* summary);

// ---- grouping.cpp ----

// Lloyd's k-means with k-means++ seeding; returns labels and the inertia.
double KMeans(const std::vector<Eigen::VectorXd>& x, int k, unsigned seed, std::vector<int>* labels);
double Median(std::vector<double> v);
// Whether two groups of pixels of one lobe model are one group cut in two.
bool SplitIsChance(const Samples& s, const std::vector<int>& a, const std::vector<int>& b, const MaterialFit& joint,
                   double alpha);
Eigen::Vector2d MeanChroma(const std::vector<Eigen::Vector2d>& chroma, const std::vector<int>& pixels);
// Whether two groups of pixels have one colour.
bool ColourIsOneGroup(const std::vector<Eigen::Vector2d>& chroma, const std::vector<int>& a, const std::vector<int>& b,
                      double alpha);

}  // namespace photorig::solvers::reflectance::internal
