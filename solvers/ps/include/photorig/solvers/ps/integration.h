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

#include "photorig/solvers/core/names.h"
#include "photorig/solvers/core/summary.h"

#include <opencv2/core.hpp>

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
  double min_normal_z = 0.05;
  bool IsValid(std::string* why) const;
};

struct IntegrationSummary : solvers::core::Summary {
  std::size_t pixels = 0;       // pixels that received a depth
  std::size_t pixels_dropped = 0;  // in the mask but too close to grazing
  double residual_rms = 0.0;    // RMS of (depth difference - integrated gradient) over neighbour pairs, in depth units
};

// normals: CV_32FC3 (x, y, z), NaN where unknown; mask: CV_8U (empty = every
// finite normal). *depth: CV_32F, NaN outside the integrated pixels.
IntegrationSummary IntegrateNormals(const IntegrationOptions& options, const cv::Mat& normals, const cv::Mat& mask,
                                    cv::Mat* depth);

}  // namespace photorig::solvers::ps
