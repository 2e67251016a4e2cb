#pragma once
// Colour-correction models: camera RGB -> CIE XYZ through a feature expansion
// and a linear map, xyz = C^T f(s * rgb), with s the exposure normalisation.
//   linear        f = (r, g, b)                                    3 terms
//   affine        f = (r, g, b, 1)                                 4 terms
//   root-poly-2   f = (r, g, b, sqrt(rg), sqrt(gb), sqrt(rb))       6 terms
//   root-poly-3   + cbrt of r g^2, r b^2, g r^2, g b^2, b r^2, b g^2, rgb   13 terms
//   poly-2        f = (r, g, b, r^2, g^2, b^2, rg, gb, rb)          9 terms
//   poly-3        + r^3, g^3, b^3, r g^2, r b^2, g r^2, g b^2, b r^2, b g^2, rgb   19 terms
// Root-polynomial terms are homogeneous of degree 1 (Finlayson, Mackiewicz and
// Hurlbert 2015), so a root-polynomial model is exposure invariant like the
// linear one; the plain polynomial and affine models are not.

#include "photorig/solvers/color/spectrum.h"

#include <Eigen/Core>

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace photorig::solvers::color {

struct ModelSpec {
  enum class Kind { kLinear, kAffine, kRootPolynomial, kPolynomial };
  Kind kind = Kind::kLinear;
  int degree = 1;  // 2 or 3 for the (root-)polynomials

  std::string Name() const;
  int TermCount() const;
  bool IsExposureInvariant() const;
  static std::optional<ModelSpec> Parse(const std::string& name);  // nullopt for an unknown name
  static std::string KnownNames();                                  // "linear, affine, ...", for messages
  static std::vector<ModelSpec> All();               // simplest first
  bool operator==(const ModelSpec&) const = default;
};

// Feature vector of one normalised camera RGB; negative channels (noise on
// black) are taken as 0 inside roots.
Eigen::VectorXd ModelFeatures(const ModelSpec& spec, const Eigen::Vector3d& rgb);
// The same for `n` pixels at once, structure of arrays: features[t][i] is term
// t of pixel i (TermCount() separate arrays of n); features[0..2] hold the
// normalised r, g, b on entry. One loop per term, so the compiler vectorises
// them: this is the per-pixel path of applying a model.
constexpr int kMaxModelTerms = 19;
void FillModelFeatures(const ModelSpec& spec, int n, float* const* features);

enum class FitLoss { kXyzLeastSquares, kCiede2000 };
inline constexpr core::NameTable<FitLoss, 2> kFitLossNames = {
    {{FitLoss::kXyzLeastSquares, "xyz"}, {FitLoss::kCiede2000, "ciede2000"}}};
inline const char* FitLossName(FitLoss loss) { return core::NameOf(kFitLossNames, loss); }
inline std::optional<FitLoss> ParseFitLoss(std::string_view name) { return core::ParseName(kFitLossNames, name); }

struct ColorModel {
  ModelSpec spec;
  FitLoss loss = FitLoss::kXyzLeastSquares;
  Eigen::MatrixXd coefficients;  // TermCount() x 3
  double input_scale = 1.0;      // s: camera RGB (dark subtracted) -> white patch at its reference Y
  Illuminant illuminant = Illuminant::kD65;  // of the chart capture; XYZ is relative to its white
  Eigen::Vector3d white_xyz = Eigen::Vector3d::Ones();

  Eigen::Vector3d ToXyz(const Eigen::Vector3d& camera_rgb) const;
  bool IsValid(std::string* why) const;
};

}  // namespace photorig::solvers::color
