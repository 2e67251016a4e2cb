#pragma once
// The per-pixel reference: a pixel's climb of the model ladder one fit at a
// time, each fit in double on the pixel's own samples (IRLS by the lane
// fitter with a single problem). The lane stages (tile_refiner.cpp) climb the
// same ladder with many pixels per fit; the tests check that both pick the
// same models. Also the fitter of `--derivative forward | reverse | symbolic |
// central-difference`.

#include "kernels/lobe_lane_fit.h"
#include "kernels/irls_lambertian_fit.h"
#include "kernels/low_frequency_fit.h"
#include "model_selection.h"
#include "sample_reader.h"

#include "photorig/solvers/autodiff/tape.h"

#include <Eigen/Core>

#include <span>
#include <vector>

namespace photorig::solvers::ps::internal {

// The `robust` fit of a pixel from its IRLS solution.
PixelFit IrlsFit(const RobustSolution& solution);
// The lobe (kBlinnPhong or kGgx) fitted to `used` samples.
PixelFit LobeFitFrom(const LobeSolution& solution, int used, PixelModel model);
// Step 7's low-frequency fit: albedo pi (a0 + a3), the reflectance away from
// the mirror direction with the half angle 0; specular_albedo pi (a1 + a2),
// its rise at the mirror direction; `rejected` the samples left out as a spike.
PixelFit LowFrequencyFitFrom(const LowFrequencySolution& solution);

// Step 5's Lambertian fit of a row's usable samples, the one the shared lobe
// must beat: least squares (unweighted, as the Lambertian pass fits), with
// the lower of its chi-square and that of `kept` (the solution steps 1-4
// kept, albedo / pi times the normal) under the clamp max(0, w . x) the lobe
// model has too; for a pixel that left out samples it put in attached
// shadow, the latter.
PixelFit LambertianOnRow(const SampleReader& reader, const double* observed, const double* inverse_sigma,
                         const Eigen::Vector3d& kept);
// The same with each light's direction (wx[k s], wy[k s], wz[k s]) at
// stride s: the stack's shared directions, or a pixel's own under near lights.
PixelFit LambertianOnRow(int lights, const double* wx, const double* wy, const double* wz, int stride,
                         const double* observed, const double* inverse_sigma, const Eigen::Vector3d& kept);

// A kept fit (Lambertian, trimmed, IRLS, Blinn-Phong or GGX; its normal,
// albedo and lobe) judged on the samples of `lights` only, each light's
// direction (wx[k s], wy[k s], wz[k s]) at stride s: its chi-square there,
// used that many samples, its own parameters (step 7 weighs it against the
// low-frequency fit of the same samples). predicted (if not null): the
// kept fit's value of each of those samples, in the order of `lights`.
PixelFit KeptOnLights(const PixelFit& kept, std::span<const int> lights, const double* wx, const double* wy,
                      const double* wz, int stride, const Eigen::Vector3d& view, const double* observed,
                      const double* inverse_sigma, std::vector<double>* predicted = nullptr);

// Whether a lobe fit's core, the half vectors within its half maximum of its
// normal (Blinn-Phong: cos^e = 1/2; GGX's distribution: cos^2 = (1 - sqrt 2
// a^2) / (1 - a^2)), holds between 1 and spike_samples of the usable
// samples: a spike the samples see, no wider than what step 7's fit leaves
// out. False for a fit without a lobe.
bool SpikePinsNormal(const PixelFit& kept, const LowFrequencyProblem& samples, int spike_samples);

// The chi-square of a Blinn-Phong fit's lobe term alone (rho_s (e + 2) /
// (2 pi) (n.h)^e n.l) over the usable samples: how far the lobe moves them,
// in their noise.
double BlinnPhongTermChi2(const PixelFit& kept, const LowFrequencyProblem& samples);

// Chi-square of a Blinn-Phong fit (normal, rho_d, rho_s, e) on samples seen
// from `view`: one row of `directions` (towards the light) per sample.
double BlinnPhongChi2(const Eigen::Matrix<double, Eigen::Dynamic, 3>& directions, const Eigen::VectorXd& observed,
                      const Eigen::VectorXd& inverse_sigma, const Eigen::Vector3d& view, const PixelFit& fit);

// The samples of one pixel as plain arrays, for loops the compiler vectorises.
struct TrimScratch {
  std::vector<double> wx, wy, wz, b, inverse_variance, u2;
};

// What one thread's per-pixel fits reuse from pixel to pixel.
struct PixelScratch {
  PixelSamples samples;
  TrimScratch trim;
  solvers::autodiff::Tape tape;
};

class PerPixelFits {
 public:
  // All must outlive this; irls (per thread) only for `robust`.
  PerPixelFits(const ModelLadder& ladder, const SampleReader& reader, const Eigen::Vector3d& view,
               const BlinnPhongOptions& blinn_phong)
      : ladder_(ladder), reader_(reader), view_(view), blinn_phong_(blinn_phong) {}

  // The model the ladder keeps for `pixel`, from the Lambertian pass's
  // solution x (albedo / pi times the normal); fell_back and evidence as
  // LadderStep's.
  PixelFit Refine(int pixel, const Eigen::Vector3d& x, PixelScratch* scratch, RobustLambertianLanes* irls,
                  bool* fell_back, double* evidence) const;
  // Step 5 for `pixel`, which steps 1-4 left with `kept`, with the lobe
  // `shared` held and, with test_shape, its own lobe fitted too
  // (NextWithSharedLobe): the fit the ladder keeps (`kept` or the held lobe).
  // With `test`, the pixel's part in its region's SharedShapeTest is added to it.
  PixelFit ShareLobe(int pixel, const PixelFit& kept, const SharedLobe& shared, bool test_shape, PixelScratch* scratch,
                     SharedShapeTest* test = nullptr) const;
  // Step 6 for `pixel`, which steps 1-5 left with `kept` (held_lobe: a lobe
  // step 5 held) in a region whose pixels reject one Blinn-Phong shape
  // (ModelLadder::NextWithGgx): its GGX fit where the ladder takes it, else
  // `kept`. With `test`, also the pixel's part in its region's shape test.
  PixelFit OfferGgx(int pixel, const PixelFit& kept, bool held_lobe, PixelScratch* scratch,
                    SharedShapeTest* test = nullptr) const;
  // Step 6's first half: `kept` judged on the samples a GGX fit takes (every
  // usable one, left in scratch->samples), as NextWithGgx compares them.
  PixelFit KeptOnUsable(int pixel, const PixelFit& kept, bool held_lobe, PixelScratch* scratch) const;

 private:
  const ModelLadder& ladder_;
  const SampleReader& reader_;
  Eigen::Vector3d view_;
  const BlinnPhongOptions& blinn_phong_;
};

}  // namespace photorig::solvers::ps::internal
