#pragma once
// Isotropic measured materials of the EPFL RGL database (Dupuy and Jakob 2018,
// "An adaptive parameterization for efficient material acquisition and
// rendering"), read from their `.bsdf` tensor files (tensor_file.h) and
// evaluated as Mitsuba 3's `measured` plugin evaluates them.
//
// Fields (float32 unless said; the last two dimensions of a table are its
// rows (y) and columns (x), nodes at i / (n - 1) of the unit square):
//   theta_i [T], phi_i [P]        incident angles (radians) the tables are measured at;
//                                 P <= 2 is isotropic, the only kind read here
//   ndf   [Py, Px]                D(w_m) at u = (sqrt(theta_m / (pi/2)), (phi_m + pi) / (2 pi))
//   sigma [Py, Px]                projected microfacet area sigma(w_i) = integral of D <w_i, w_m>, same u grid
//   vndf  [P, T, Ny, Nx]          the visible-normal density D_wi(w_m) = <w_i, w_m> D / sigma(w_i) in
//                                 that u square (times its Jacobian 2 pi^2 u_x sin theta_m), phi_m
//                                 relative to phi_i
//   luminance [P, T, N, N]        the luminance of rgb in the sample square (for importance sampling only)
//   rgb   [P, T, 3, N, N]         the measurement, in the sample square: the VNDF's inverse warp of u_m
//   jacobian uint8 [1]            1: f_r = rgb * D(w_m) / (4 sigma(w_i)); 0: f_r = rgb
//   description uint8 [n]         free text (optional here)
// Spectral files (wavelengths + spectra, no rgb) are refused with that reason.
//
// Evaluation (Mitsuba's measured.cpp): w_m = normalize(w_i + w_o); u_m as above with
// phi_m - phi_i wrapped into [0, 1); the sample = the VNDF warp at (phi_i, theta_i)
// inverted at u_m (a marginal-then-conditional warp of the bilinear density,
// interpolated linearly between the tabulated incident angles); rgb bilinear at
// the sample (clamped at 0, as the database's own RGB loader does); times
// ndf(u_m) / (4 sigma(u_wi)) when `jacobian` is set.

#include "photorig/solvers/brdf/half_diff.h"
#include "photorig/solvers/brdf/tensor_file.h"
#include "photorig/solvers/core/summary.h"

#include <Eigen/Core>

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace photorig::solvers::brdf {

// A 2D table on the unit square, nodes at (i / (nx - 1), j / (ny - 1)),
// stacked in slices over parameters that are interpolated linearly
// (Mitsuba's Marginal2D): bilinear evaluation and, for a density, the warp
// from the unit square to the density and its inverse.
class Warp2D {
 public:
  Warp2D() = default;
  // `values`: [params[0].size() x params[1].size() x ... x ny x nx], the last
  // contiguous. `density`: build the normalised marginal and conditional CDFs
  // per slice (every slice must integrate to > 0).
  Warp2D(int nx, int ny, std::vector<std::vector<double>> params, std::vector<double> values, bool density);

  // Bilinear value at `pos` in [0, 1]^2 (clamped), parameters interpolated.
  double Eval(Eigen::Vector2d pos, const std::vector<double>& param = {}) const;
  // The point of the unit square that Sample maps to `pos` (density only).
  Eigen::Vector2d Invert(Eigen::Vector2d pos, const std::vector<double>& param = {}) const;
  // Unit square -> the density's domain (density only).
  Eigen::Vector2d Sample(Eigen::Vector2d u, const std::vector<double>& param = {}) const;

 private:
  struct Weights {
    std::vector<std::size_t> offsets;  // slice offsets of the 2^dims corners
    std::vector<double> weights;
  };
  Weights Interpolate(const std::vector<double>& param) const;
  // The grid cell holding a point of the unit square: its corner (px, py),
  // the corner's index i, and the point's fractions (tx, ty) across the cell.
  struct Cell {
    int px, py;
    std::size_t i;
    double tx, ty;
  };
  Cell Locate(Eigen::Vector2d pos) const;
  double Lookup(const std::vector<double>& table, std::size_t stride, std::size_t index, const Weights& w) const;

  int nx_ = 0, ny_ = 0;
  std::vector<std::vector<double>> params_;
  std::vector<std::size_t> strides_;  // in slices, per parameter
  std::vector<double> data_, marginal_cdf_, conditional_cdf_;
};

class RglBrdf {
 public:
  // f_r in 1/sr per channel (R, G, B); empty below the horizon.
  std::optional<Eigen::Vector3d> Evaluate(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) const;

  const std::string& description() const { return description_; }
  int theta_i_count() const { return static_cast<int>(theta_i_.size()); }
  int sample_resolution() const { return resolution_; }

 private:
  friend core::Summary BuildRglBrdf(const std::string& path, const TensorFile& file, RglBrdf* brdf);
  std::string description_;
  std::vector<double> theta_i_, phi_i_;
  bool jacobian_ = true;
  int resolution_ = 0;
  Warp2D ndf_, sigma_, vndf_, rgb_;
};

// Checks the fields of a tensor file as an isotropic RGB material and builds
// its evaluator. A missing field, a wrong dtype or shape, an anisotropic or
// spectral file, a NaN or infinite cell, a negative density or a
// non-positive sigma ends kInvalidInput naming `path`, the field and the fault.
core::Summary BuildRglBrdf(const std::string& path, const TensorFile& file, RglBrdf* brdf);

// ReadTensorFile, then BuildRglBrdf; never throws, `brdf` untouched on error.
core::Summary ReadRgl(const std::string& path, RglBrdf* brdf);

// How to tabulate a BRDF in the format.
struct RglTabulation {
  int theta_i_count = 16;     // incident elevations, uniform in u = sqrt(theta / (pi/2)) up to theta_i_max_deg
  double theta_i_max_deg = 85.0;
  int sample_resolution = 32;  // N x N nodes of the sample square (rgb, luminance)
  int ndf_resolution = 64;     // nodes of ndf, sigma and vndf along theta and phi
  // The parameterisation: a Trowbridge-Reitz (GGX) NDF of this roughness with
  // its exact Smith sigma. The BRDF being tabulated need not be microfacet at
  // all; the NDF only spreads the sample square over directions.
  double ndf_roughness = 0.5;
  std::string description = "photorig";

  bool IsValid(std::string* why) const;
};

// The fields of an isotropic RGB `.bsdf` holding `brdf` (1/sr per channel):
// ndf, sigma and vndf from the tabulation's NDF as the format defines them,
// rgb = f_r 4 sigma(w_i) / D(w_m) at each sample node's direction (the VNDF
// warp of that node), jacobian = 1.
core::Summary TabulateRgl(const std::function<Eigen::Vector3d(const DirectionPair&)>& brdf,
                    const RglTabulation& tabulation, TensorFile* file);

}  // namespace photorig::solvers::brdf
