#include "photorig/solvers/color/model.h"
#include "photorig/solvers/core/summary.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace photorig::solvers::color {

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

std::optional<ModelSpec> ModelSpec::Parse(const std::string& name) {
  for (const ModelSpec& spec : All()) {
    if (spec.Name() == name) return spec;
  }
  return std::nullopt;
}

std::string ModelSpec::KnownNames() {
  std::string known;
  for (const ModelSpec& spec : All()) known += (known.empty() ? "" : ", ") + spec.Name();
  return known;
}

namespace {

// Every feature expansion, for doubles (fitting) and floats (applying): f[0..2]
// hold r, g, b on entry, the other terms are filled. Loops run over pixels
// inside each term; the term arrays never overlap (ivdep), so they vectorise.
// Negative channels count as 0 inside roots.
template <typename T>
void Features(const ModelSpec& spec, int n, T* const* f) {
  const T zero = 0;
  const T* r = f[0];
  const T* g = f[1];
  const T* b = f[2];
  switch (spec.kind) {
    case ModelSpec::Kind::kLinear: return;
    case ModelSpec::Kind::kAffine:
#pragma GCC ivdep
      for (int i = 0; i < n; ++i) f[3][i] = 1;
      return;
    case ModelSpec::Kind::kRootPolynomial:
#pragma GCC ivdep
      for (int i = 0; i < n; ++i) {
        const T rp = std::max(r[i], zero), gp = std::max(g[i], zero), bp = std::max(b[i], zero);
        f[3][i] = std::sqrt(rp * gp), f[4][i] = std::sqrt(gp * bp), f[5][i] = std::sqrt(rp * bp);
      }
      // cbrt(r g^2) = cbrt(r) cbrt(g)^2: three cube roots per pixel instead of seven.
      if (spec.degree == 3)
  #pragma GCC ivdep
      for (int i = 0; i < n; ++i) {
          const T cr = std::cbrt(std::max(r[i], zero)), cg = std::cbrt(std::max(g[i], zero));
          const T cb = std::cbrt(std::max(b[i], zero));
          f[6][i] = cr * cg * cg, f[7][i] = cr * cb * cb, f[8][i] = cg * cr * cr;
          f[9][i] = cg * cb * cb, f[10][i] = cb * cr * cr, f[11][i] = cb * cg * cg;
          f[12][i] = cr * cg * cb;
        }
      return;
    case ModelSpec::Kind::kPolynomial:
#pragma GCC ivdep
      for (int i = 0; i < n; ++i) {
        const T x = r[i], y = g[i], z = b[i];
        f[3][i] = x * x, f[4][i] = y * y, f[5][i] = z * z, f[6][i] = x * y, f[7][i] = y * z, f[8][i] = x * z;
      }
      if (spec.degree == 3)
  #pragma GCC ivdep
      for (int i = 0; i < n; ++i) {
          const T x = r[i], y = g[i], z = b[i];
          f[9][i] = x * x * x, f[10][i] = y * y * y, f[11][i] = z * z * z, f[12][i] = x * y * y;
          f[13][i] = x * z * z, f[14][i] = y * x * x, f[15][i] = y * z * z, f[16][i] = z * x * x;
          f[17][i] = z * y * y, f[18][i] = x * y * z;
        }
      return;
  }
}

}  // namespace

void FillModelFeatures(const ModelSpec& spec, int n, float* const* features) { Features(spec, n, features); }

Eigen::VectorXd ModelFeatures(const ModelSpec& spec, const Eigen::Vector3d& rgb) {
  Eigen::VectorXd f(spec.TermCount());
  f.head<3>() = rgb;
  double* terms[kMaxModelTerms];
  for (int t = 0; t < spec.TermCount(); ++t) terms[t] = f.data() + t;
  Features(spec, 1, terms);
  return f;
}

Eigen::Vector3d ColorModel::ToXyz(const Eigen::Vector3d& camera_rgb) const {
  return coefficients.transpose() * ModelFeatures(spec, input_scale * camera_rgb);
}

bool ColorModel::IsValid(std::string* why) const {
  if (coefficients.rows() != spec.TermCount() || coefficients.cols() != 3)
    return core::Refuse(why, spec.Name() + " needs " + std::to_string(spec.TermCount()) + " x 3 coefficients, got " +
                             std::to_string(coefficients.rows()) + " x " + std::to_string(coefficients.cols()));
  if (!coefficients.allFinite()) return core::Refuse(why, "coefficients are not finite");
  if (!(input_scale > 0.0) || !std::isfinite(input_scale)) return core::Refuse(why, "input_scale must be positive");
  if (!(white_xyz.minCoeff() > 0.0)) return core::Refuse(why, "white_xyz must be positive");
  return true;
}

}  // namespace photorig::solvers::color
