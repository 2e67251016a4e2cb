#pragma once
// Depth from a normal map. With z(x, y) the height towards the camera, a
// normal n gives the gradient dz/dx = -n_x / n_z, dz/dy = -n_y / n_z (y up,
// so one image row down is -dy).
//
//   Frankot-Chellappa: projects the gradient field onto the nearest integrable
//     one in the Fourier domain. One FFT each way: fast, but it treats the
//     image as periodic and fills pixels outside the mask with zero gradient,
//     so depth bends near mask borders.
//   Poisson (masked least squares): one unknown per mask pixel, one equation
//     per pair of 4-neighbours inside the mask. Exact for integrable fields on
//     any mask shape (holes, several objects); a sparse solve.
// Each connected region's depth is defined up to a constant: both methods put
// its mean at 0.
//
// Under a pinhole camera (IntegrateNormalsPerspective) the normals fix the
// log of each point's distance from the camera up to a constant, so the shape
// up to a scale; the same integrators solve for it.

#include "photorig/solvers/camera/camera.h"
#include "photorig/solvers/core/names.h"
#include "photorig/solvers/core/summary.h"

#include <opencv2/core.hpp>

#include <memory>
#include <optional>
#include <string>
#include <string_view>

namespace photorig::solvers::ps {

enum class Integrator { kFrankotChellappa, kPoisson };
inline constexpr core::NameTable<Integrator, 2> kIntegratorNames = {
    {{Integrator::kPoisson, "poisson"}, {Integrator::kFrankotChellappa, "frankot-chellappa"}}};
inline const char* IntegratorName(Integrator integrator) { return core::NameOf(kIntegratorNames, integrator); }
inline std::optional<Integrator> ParseIntegrator(std::string_view name) { return core::ParseName(kIntegratorNames, name); }

struct IntegrationOptions {
  Integrator integrator = Integrator::kPoisson;
  double pixel_pitch = 1.0;  // object-space size of a pixel; depth comes out in the same unit
  // Normals closer to grazing than this (n_z below it) give unbounded slopes;
  // such pixels are left out of the mask.
  // Perspective: the cosine between the normal and the pixel's ray.
  double min_normal_z = 0.05;
  // 1: one unknown per pixel. b > 1: the slopes averaged over blocks of b x b
  // pixels are integrated, and the depth interpolated bilinearly back to
  // every pixel: a surface smoothed over b pixels for about 1 / b^2 of the
  // unknowns (the near-light rounds need no more to place their points).
  int block_px = 1;
  bool IsValid(std::string* why) const;
};

struct IntegrationSummary : solvers::core::Summary {
  std::size_t pixels = 0;       // pixels that received a depth
  std::size_t pixels_dropped = 0;  // in the mask but too close to grazing
  // RMS of (depth difference - integrated gradient) over neighbour pairs, in
  // depth units (perspective: the log distance's, times the camera distance).
  double residual_rms = 0.0;
  // Poisson on more than a few thousand unknowns: the conjugate-gradient
  // iterations its multigrid-preconditioned solve took (0: solved directly).
  int iterations = 0;
};

// What the Poisson integrator keeps between calls: its equations' matrix
// depends on the integrated pixels alone (one row per pair of neighbours),
// so calls that integrate the same pixels again, such as the near-light
// solve's rounds, factor it once (or, above a few thousand pixels, build its
// multigrid levels once) and pay only for the solve. One per thread; a call
// on other pixels starts anew.
class IntegrationWorkspace {
 public:
  IntegrationWorkspace();
  ~IntegrationWorkspace();
  IntegrationWorkspace(IntegrationWorkspace&&) noexcept;
  IntegrationWorkspace& operator=(IntegrationWorkspace&&) noexcept;
  // Calls that found the pixels of the last factorisation (for tests and reports).
  int reuses() const;

  struct Factorisation;  // integration.cpp

 private:
  friend Factorisation& FactorisationOf(IntegrationWorkspace&);
  std::unique_ptr<Factorisation> factorisation_;
};

// normals: CV_32FC3 (x, y, z), NaN where unknown; mask: CV_8U (empty = every
// finite normal). *depth: CV_32F, NaN outside the integrated pixels.
// workspace: optional, kept between calls (above).
IntegrationSummary IntegrateNormals(const IntegrationOptions& options, const cv::Mat& normals, const cv::Mat& mask,
                                    cv::Mat* depth, IntegrationWorkspace* workspace = nullptr);

// The same for normals seen through the pinhole camera of `rays` (its frame:
// camera/camera.h): *height_mm is the surface's z in mm, each region scaled
// so its geometric-mean distance from the camera is the camera's distance_mm
// (an object on the sample plane); options.pixel_pitch is not used.
IntegrationSummary IntegrateNormalsPerspective(const IntegrationOptions& options, const camera::PixelRays& rays,
                                               const cv::Mat& normals, const cv::Mat& mask, cv::Mat* height_mm,
                                               IntegrationWorkspace* workspace = nullptr);

}  // namespace photorig::solvers::ps
