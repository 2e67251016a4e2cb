#include "photorig/color/model.h"

#include <cmath>
#include <stdexcept>

namespace photorig::color {

std::string ModelSpec::Name() const {
  switch (kind) {
    case Kind::kLinear: return "linear";
    case Kind::kAffine: return "affine";
    case Kind::kRootPolynomial: return "root-poly-" + std::to_string(degree);
    case Kind::kPolynomial: return "poly-" + std::to_string(degree);
  }
  return "?";
}

int ModelSpec::TermCount() const {
  switch (kind) {
    case Kind::kLinear: return 3;
    case Kind::kAffine: return 4;
    case Kind::kRootPolynomial: return degree == 2 ? 6 : 13;
    case Kind::kPolynomial: return degree == 2 ? 9 : 19;
  }
  return 0;
}

bool ModelSpec::IsExposureInvariant() const { return kind == Kind::kLinear || kind == Kind::kRootPolynomial; }

std::vector<ModelSpec> ModelSpec::All() {
  return {{Kind::kLinear, 1},         {Kind::kAffine, 1},     {Kind::kRootPolynomial, 2},
          {Kind::kPolynomial, 2},     {Kind::kRootPolynomial, 3}, {Kind::kPolynomial, 3}};
}

ModelSpec ModelSpec::Parse(const std::string& name) {
  std::string known;
  for (const ModelSpec& spec : All()) {
    if (spec.Name() == name) return spec;
    known += (known.empty() ? "" : ", ") + spec.Name();
  }
  throw std::invalid_argument("unknown colour model '" + name + "' (known: " + known + ")");
}

void FillModelFeatures(const ModelSpec& spec, double r, double g, double b, double* f) {
  const double rp = std::max(r, 0.0), gp = std::max(g, 0.0), bp = std::max(b, 0.0);
  f[0] = r, f[1] = g, f[2] = b;
  switch (spec.kind) {
    case ModelSpec::Kind::kLinear: return;
    case ModelSpec::Kind::kAffine: f[3] = 1.0; return;
    case ModelSpec::Kind::kRootPolynomial:
      f[3] = std::sqrt(rp * gp), f[4] = std::sqrt(gp * bp), f[5] = std::sqrt(rp * bp);
      if (spec.degree == 3) {
        f[6] = std::cbrt(rp * gp * gp), f[7] = std::cbrt(rp * bp * bp), f[8] = std::cbrt(gp * rp * rp);
        f[9] = std::cbrt(gp * bp * bp), f[10] = std::cbrt(bp * rp * rp), f[11] = std::cbrt(bp * gp * gp);
        f[12] = std::cbrt(rp * gp * bp);
      }
      return;
    case ModelSpec::Kind::kPolynomial:
      f[3] = r * r, f[4] = g * g, f[5] = b * b, f[6] = r * g, f[7] = g * b, f[8] = r * b;
      if (spec.degree == 3) {
        f[9] = r * r * r, f[10] = g * g * g, f[11] = b * b * b, f[12] = r * g * g, f[13] = r * b * b;
        f[14] = g * r * r, f[15] = g * b * b, f[16] = b * r * r, f[17] = b * g * g, f[18] = r * g * b;
      }
      return;
  }
}

Eigen::VectorXd ModelFeatures(const ModelSpec& spec, const Eigen::Vector3d& rgb) {
  Eigen::VectorXd f(spec.TermCount());
  FillModelFeatures(spec, rgb[0], rgb[1], rgb[2], f.data());
  return f;
}

const char* FitLossName(FitLoss loss) { return loss == FitLoss::kCiede2000 ? "ciede2000" : "xyz"; }

FitLoss ParseFitLoss(const std::string& name) {
  if (name == "xyz") return FitLoss::kXyzLeastSquares;
  if (name == "ciede2000") return FitLoss::kCiede2000;
  throw std::invalid_argument("unknown fit loss '" + name + "' (known: xyz, ciede2000)");
}

Eigen::Vector3d ColorModel::ToXyz(const Eigen::Vector3d& camera_rgb) const {
  return coefficients.transpose() * ModelFeatures(spec, input_scale * camera_rgb);
}

bool ColorModel::IsValid(std::string* why) const {
  auto fail = [why](const std::string& message) {
    if (why) *why = message;
    return false;
  };
  if (coefficients.rows() != spec.TermCount() || coefficients.cols() != 3)
    return fail(spec.Name() + " needs " + std::to_string(spec.TermCount()) + " x 3 coefficients, got " +
                std::to_string(coefficients.rows()) + " x " + std::to_string(coefficients.cols()));
  if (!coefficients.allFinite()) return fail("coefficients are not finite");
  if (!(input_scale > 0.0) || !std::isfinite(input_scale)) return fail("input_scale must be positive");
  if (!(white_xyz.minCoeff() > 0.0)) return fail("white_xyz must be positive");
  return true;
}

}  // namespace photorig::color
