#include "photorig/solvers/brdf/rgl.h"

#include <algorithm>
#include <cmath>

namespace photorig::solvers::brdf {

namespace {

// The format's unit-square coordinates of a direction (Dupuy and Jakob 2018):
// theta is stretched by a square root so that the grid is dense near the pole.
double ThetaToU(double theta) { return std::sqrt(std::max(theta, 0.0) * (2.0 / M_PI)); }
double UToTheta(double u) { return u * u * (M_PI / 2.0); }
double PhiToU(double phi) { return (phi + M_PI) / (2.0 * M_PI); }
double UToPhi(double u) { return (2.0 * u - 1.0) * M_PI; }

// acos(z) without its loss of precision near the pole.
double Elevation(const Eigen::Vector3d& d) {
  const double dist = std::sqrt(d.x() * d.x() + d.y() * d.y() + (d.z() - 1.0) * (d.z() - 1.0));
  return 2.0 * std::asin(std::clamp(0.5 * dist, -1.0, 1.0));
}

Eigen::Vector3d Spherical(double theta, double phi) {
  return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

// The root t in [0, 1] of r0 t + (r1 - r0) t^2 / 2 = u: inverting the integral
// of a linear density, in the form that stays exact when r0 = r1.
double InvertLinearIntegral(double r0, double r1, double u) {
  const double disc = std::max(r0 * r0 + 2.0 * (r1 - r0) * u, 0.0);
  const double denom = r0 + std::sqrt(disc);
  return denom > 0.0 ? std::clamp(2.0 * u / denom, 0.0, 1.0) : 0.0;
}

// Largest i in [0, n - 2] with value(i) < x (0 when none is).
template <typename Value>
int FindInterval(int n, double x, const Value& value) {
  int lo = 0, hi = n - 2;
  while (lo < hi) {
    const int mid = (lo + hi + 1) / 2;
    if (value(mid) < x)
      lo = mid;
    else
      hi = mid - 1;
  }
  return lo;
}

// Trowbridge-Reitz NDF and its exact Smith projected area, the tabulation's parameterisation.
double GgxNdf(double a, double cos_m) {
  const double c2 = cos_m * cos_m, t = c2 * (a * a - 1.0) + 1.0;
  return a * a / (M_PI * t * t);
}
double GgxSigma(double a, double cos_i) {
  const double c2 = cos_i * cos_i;
  return 0.5 * (cos_i + std::sqrt(c2 + a * a * (1.0 - c2)));
}

}  // namespace

Warp2D::Warp2D(int nx, int ny, std::vector<std::vector<double>> params, std::vector<double> values, bool density)
    : nx_(nx), ny_(ny), params_(std::move(params)), data_(std::move(values)) {
  std::size_t slices = 1;
  strides_.assign(params_.size(), 0);
  for (int i = static_cast<int>(params_.size()) - 1; i >= 0; --i) {
    strides_[i] = params_[i].size() > 1 ? slices : 0;
    slices *= params_[i].size();
  }
  if (!density) return;
  const std::size_t n = std::size_t(nx_) * ny_;
  conditional_cdf_.assign(slices * n, 0.0);
  marginal_cdf_.assign(slices * ny_, 0.0);
  for (std::size_t s = 0; s < slices; ++s) {
    double* data = data_.data() + s * n;
    double* cond = conditional_cdf_.data() + s * n;
    double* marg = marginal_cdf_.data() + s * ny_;
    // Trapezoid sums of the bilinear interpolant, in index units.
    for (int y = 0; y < ny_; ++y)
      for (int x = 0; x + 1 < nx_; ++x)
        cond[y * nx_ + x + 1] = cond[y * nx_ + x] + 0.5 * (data[y * nx_ + x] + data[y * nx_ + x + 1]);
    for (int y = 0; y + 1 < ny_; ++y)
      marg[y + 1] = marg[y] + 0.5 * (cond[(y + 1) * nx_ - 1] + cond[(y + 2) * nx_ - 1]);
    const double total = marg[ny_ - 1];
    const double scale = total > 0.0 ? 1.0 / total : 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      data[i] *= scale;
      cond[i] *= scale;
    }
    for (int y = 0; y < ny_; ++y) marg[y] *= scale;
  }
}

Warp2D::Weights Warp2D::Interpolate(const std::vector<double>& param) const {
  Weights w;
  w.offsets.push_back(0);
  w.weights.push_back(1.0);
  for (std::size_t d = 0; d < params_.size(); ++d) {
    const std::vector<double>& nodes = params_[d];
    if (nodes.size() == 1) continue;
    const double p = param[d];
    const int i = FindInterval(static_cast<int>(nodes.size()), p, [&](int k) { return nodes[k]; });
    const double t = std::clamp((p - nodes[i]) / (nodes[i + 1] - nodes[i]), 0.0, 1.0);
    const std::size_t corners = w.offsets.size();
    for (std::size_t c = 0; c < corners; ++c) {
      w.offsets.push_back(w.offsets[c] + strides_[d] * (i + 1));
      w.weights.push_back(w.weights[c] * t);
      w.offsets[c] += strides_[d] * i;
      w.weights[c] *= 1.0 - t;
    }
  }
  return w;
}

double Warp2D::Lookup(const std::vector<double>& table, std::size_t stride, std::size_t index,
                      const Weights& w) const {
  double v = 0.0;
  for (std::size_t c = 0; c < w.offsets.size(); ++c)
    if (w.weights[c] != 0.0) v += w.weights[c] * table[w.offsets[c] * stride + index];
  return v;
}

Warp2D::Cell Warp2D::Locate(Eigen::Vector2d pos) const {
  const double sx = std::clamp(pos.x(), 0.0, 1.0) * (nx_ - 1), sy = std::clamp(pos.y(), 0.0, 1.0) * (ny_ - 1);
  const int px = std::min(static_cast<int>(sx), nx_ - 2), py = std::min(static_cast<int>(sy), ny_ - 2);
  return {px, py, std::size_t(py) * nx_ + px, sx - px, sy - py};
}

double Warp2D::Eval(Eigen::Vector2d pos, const std::vector<double>& param) const {
  const Weights w = Interpolate(param);
  const std::size_t n = std::size_t(nx_) * ny_;
  const auto [px, py, i, tx, ty] = Locate(pos);
  return (1 - ty) * ((1 - tx) * Lookup(data_, n, i, w) + tx * Lookup(data_, n, i + 1, w)) +
         ty * ((1 - tx) * Lookup(data_, n, i + nx_, w) + tx * Lookup(data_, n, i + nx_ + 1, w));
}

Eigen::Vector2d Warp2D::Invert(Eigen::Vector2d pos, const std::vector<double>& param) const {
  const Weights w = Interpolate(param);
  const std::size_t n = std::size_t(nx_) * ny_;
  const auto [px, py, i, tx, ty] = Locate(pos);
  // Along x: the conditional CDF at the patch's start plus the integral of the
  // density (linear in x at this y) across the patch, over the row's total.
  const double c0 = (1 - ty) * Lookup(data_, n, i, w) + ty * Lookup(data_, n, i + nx_, w);
  const double c1 = (1 - ty) * Lookup(data_, n, i + 1, w) + ty * Lookup(data_, n, i + nx_ + 1, w);
  const double row_start = (1 - ty) * Lookup(conditional_cdf_, n, i, w) + ty * Lookup(conditional_cdf_, n, i + nx_, w);
  const double r0 = Lookup(conditional_cdf_, n, std::size_t(py) * nx_ + nx_ - 1, w);
  const double r1 = Lookup(conditional_cdf_, n, std::size_t(py + 1) * nx_ + nx_ - 1, w);
  const double row_total = (1 - ty) * r0 + ty * r1;
  const double x = row_total > 0.0 ? (row_start + tx * (c0 + 0.5 * tx * (c1 - c0))) / row_total : 0.0;
  // Along y: the marginal CDF likewise.
  const double y = Lookup(marginal_cdf_, ny_, py, w) + ty * (r0 + 0.5 * ty * (r1 - r0));
  return {std::clamp(x, 0.0, 1.0), std::clamp(y, 0.0, 1.0)};
}

Eigen::Vector2d Warp2D::Sample(Eigen::Vector2d u, const std::vector<double>& param) const {
  const Weights w = Interpolate(param);
  const std::size_t n = std::size_t(nx_) * ny_;
  u = u.cwiseMax(0.0).cwiseMin(1.0);
  const int row = FindInterval(ny_, u.y(), [&](int k) { return Lookup(marginal_cdf_, ny_, k, w); });
  const double uy = u.y() - Lookup(marginal_cdf_, ny_, row, w);
  const std::size_t off = std::size_t(row) * nx_;
  const double r0 = Lookup(conditional_cdf_, n, off + nx_ - 1, w);
  const double r1 = Lookup(conditional_cdf_, n, off + 2 * nx_ - 1, w);
  const double ty = InvertLinearIntegral(r0, r1, uy);
  const double ux = u.x() * ((1 - ty) * r0 + ty * r1);
  auto conditional = [&](int k) {
    return (1 - ty) * Lookup(conditional_cdf_, n, off + k, w) + ty * Lookup(conditional_cdf_, n, off + nx_ + k, w);
  };
  const int col = FindInterval(nx_, ux, conditional);
  const double rest = ux - conditional(col);
  const std::size_t i = off + col;
  const double c0 = (1 - ty) * Lookup(data_, n, i, w) + ty * Lookup(data_, n, i + nx_, w);
  const double c1 = (1 - ty) * Lookup(data_, n, i + 1, w) + ty * Lookup(data_, n, i + nx_ + 1, w);
  const double tx = InvertLinearIntegral(c0, c1, rest);
  return {(col + tx) / (nx_ - 1), (row + ty) / (ny_ - 1)};
}

std::optional<Eigen::Vector3d> RglBrdf::Evaluate(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) const {
  if (!wi.allFinite() || !wo.allFinite()) return std::nullopt;  // as MerlTable::Evaluate
  if (wi.z() <= 0.0 || wo.z() <= 0.0) return std::nullopt;
  const Eigen::Vector3d wm = (wi + wo).normalized();
  const double theta_i = Elevation(wi), phi_i = std::atan2(wi.y(), wi.x());
  const double theta_m = Elevation(wm), phi_m = std::atan2(wm.y(), wm.x());
  const Eigen::Vector2d u_wi(ThetaToU(theta_i), PhiToU(phi_i));
  // Isotropic: the half vector's azimuth counts from the incident one.
  Eigen::Vector2d u_m(ThetaToU(theta_m), PhiToU(phi_m - phi_i));
  u_m.y() -= std::floor(u_m.y());
  const Eigen::Vector2d sample = vndf_.Invert(u_m, {phi_i, theta_i});
  Eigen::Vector3d f;
  for (int c = 0; c < 3; ++c) f[c] = std::max(0.0, rgb_.Eval(sample, {phi_i, theta_i, double(c)}));
  if (jacobian_) f *= ndf_.Eval(u_m) / (4.0 * sigma_.Eval(u_wi));
  return f;
}

core::Summary BuildRglBrdf(const std::string& path, const TensorFile& file, RglBrdf* brdf) {
  core::SolveTimer timer;
  auto fail = [&](const std::string& why) { return core::Ended(core::Termination::kInvalidInput, "RGL BRDF '" + path + "': " + why); };
  const char* kNeeded = "an RGL material needs theta_i, phi_i, ndf, sigma, vndf, luminance, rgb and jacobian";
  if (!file.Find("rgb") && file.Find("spectra"))
    return fail("a spectral file ('wavelengths' and 'spectra', no 'rgb'): only the RGB variant of the "
                "database's files (its _rgb.bsdf) is read");
  // Each field: present, of its type and rank, every extent in a sane range.
  std::string why;
  auto field = [&](const char* name, TensorType type, std::size_t ndim) -> const TensorField* {
    const TensorField* f = file.Find(name);
    if (!f) {
      why = std::string("no field '") + name + "' (" + kNeeded + ")";
      return nullptr;
    }
    if (f->type != type) {
      why = std::string("field '") + name + "' is " + TensorTypeName(f->type) + ", the format stores " +
            TensorTypeName(type);
      return nullptr;
    }
    if (f->shape.size() != ndim) {
      why = std::string("field '") + name + "' has " + std::to_string(f->shape.size()) + " dimensions, not " +
            std::to_string(ndim);
      return nullptr;
    }
    for (std::uint64_t extent : f->shape)
      if (extent < 1 || extent > (1u << 16)) {
        why = std::string("field '") + name + "' has an extent of " + std::to_string(extent) + " (1 to 65536)";
        return nullptr;
      }
    return f;
  };
  const TensorField* theta_i = field("theta_i", TensorType::kFloat32, 1);
  const TensorField* phi_i = theta_i ? field("phi_i", TensorType::kFloat32, 1) : nullptr;
  const TensorField* ndf = phi_i ? field("ndf", TensorType::kFloat32, 2) : nullptr;
  const TensorField* sigma = ndf ? field("sigma", TensorType::kFloat32, 2) : nullptr;
  const TensorField* vndf = sigma ? field("vndf", TensorType::kFloat32, 4) : nullptr;
  const TensorField* luminance = vndf ? field("luminance", TensorType::kFloat32, 4) : nullptr;
  const TensorField* rgb = luminance ? field("rgb", TensorType::kFloat32, 5) : nullptr;
  const TensorField* jacobian = rgb ? field("jacobian", TensorType::kUInt8, 1) : nullptr;
  if (!jacobian) return fail(why);
  const TensorField* description = file.Find("description");
  if (description && (description->type != TensorType::kUInt8 || description->shape.size() != 1))
    return fail("field 'description' is not a uint8 string");

  const std::uint64_t T = theta_i->shape[0], P = phi_i->shape[0];
  if (P > 2) return fail("anisotropic (" + std::to_string(P) + " phi_i values): only isotropic materials (at most 2) are read");
  auto shape_is = [](const TensorField* f, std::vector<std::uint64_t> s) { return f->shape == s; };
  auto shape_text = [](const TensorField* f) {
    std::string s;
    for (std::uint64_t e : f->shape) s += (s.empty() ? "" : " x ") + std::to_string(e);
    return s;
  };
  for (const TensorField* f : {ndf, sigma})
    if (f->shape[0] < 2 || f->shape[1] < 2) return fail("field '" + f->name + "' is " + shape_text(f) + ", each side needs 2 nodes or more");
  const std::uint64_t vy = vndf->shape[2], vx = vndf->shape[3], N = luminance->shape[2];
  if (vndf->shape[0] != P || vndf->shape[1] != T || vx < 2 || vy < 2)
    return fail("field 'vndf' is " + shape_text(vndf) + ", not phi_i x theta_i (" + std::to_string(P) + " x " +
                std::to_string(T) + ") x rows x columns of 2 or more");
  if (!shape_is(luminance, {P, T, N, N}) || N < 2)
    return fail("field 'luminance' is " + shape_text(luminance) + ", not phi_i x theta_i x N x N (N >= 2)");
  if (!shape_is(rgb, {P, T, 3, N, N}))
    return fail("field 'rgb' is " + shape_text(rgb) + ", not " + std::to_string(P) + " x " + std::to_string(T) +
                " x 3 x " + std::to_string(N) + " x " + std::to_string(N) + " (phi_i x theta_i x RGB x luminance's N x N)");
  if (jacobian->shape[0] != 1) return fail("field 'jacobian' holds " + std::to_string(jacobian->shape[0]) + " values, not 1");

  // Values: finite everywhere; the densities non-negative, sigma positive.
  std::vector<std::vector<double>> values;
  for (const TensorField* f : {theta_i, phi_i, ndf, sigma, vndf, luminance, rgb}) {
    const std::vector<float> v = f->Floats();
    for (std::size_t i = 0; i < v.size(); ++i)
      if (!std::isfinite(v[i]))
        return fail("field '" + f->name + "' cell " + std::to_string(i) + " is " + (std::isnan(v[i]) ? "NaN" : "infinite"));
    values.emplace_back(v.begin(), v.end());
  }
  auto increasing_within = [&](const std::vector<double>& v, double lo, double hi, const char* name) {
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (v[i] < lo || v[i] > hi) {
        why = std::string("field '") + name + "' value " + std::to_string(i) + " is " + std::to_string(v[i]) +
              ", outside [" + std::to_string(lo) + ", " + std::to_string(hi) + "] radians";
        return false;
      }
      if (i > 0 && !(v[i] > v[i - 1])) {
        why = std::string("field '") + name + "' is not strictly increasing at value " + std::to_string(i);
        return false;
      }
    }
    return true;
  };
  if (!increasing_within(values[0], 0.0, M_PI / 2 + 1e-6, "theta_i") ||
      !increasing_within(values[1], -M_PI - 1e-6, M_PI + 1e-6, "phi_i"))
    return fail(why);
  for (int k : {2, 4})
    for (std::size_t i = 0; i < values[k].size(); ++i)
      if (values[k][i] < 0.0)
        return fail("field '" + std::string(k == 2 ? "ndf" : "vndf") + "' cell " + std::to_string(i) + " is negative");
  for (std::size_t i = 0; i < values[3].size(); ++i)
    if (!(values[3][i] > 0.0)) return fail("field 'sigma' cell " + std::to_string(i) + " is not positive");
  const std::size_t slice = vx * vy;
  for (std::size_t s = 0; s < P * T; ++s) {
    double sum = 0.0;
    for (std::size_t i = 0; i < slice; ++i) sum += values[4][s * slice + i];
    if (!(sum > 0.0)) return fail("field 'vndf' slice " + std::to_string(s) + " is zero everywhere");
  }

  RglBrdf built;
  built.theta_i_ = values[0];
  built.phi_i_ = values[1];
  built.jacobian_ = jacobian->bytes[0] != 0;
  built.resolution_ = static_cast<int>(N);
  if (description) built.description_.assign(description->bytes.begin(), description->bytes.end());
  const int n = static_cast<int>(N);
  built.ndf_ = Warp2D(static_cast<int>(ndf->shape[1]), static_cast<int>(ndf->shape[0]), {}, values[2], false);
  built.sigma_ = Warp2D(static_cast<int>(sigma->shape[1]), static_cast<int>(sigma->shape[0]), {}, values[3], false);
  built.vndf_ = Warp2D(static_cast<int>(vx), static_cast<int>(vy), {values[1], values[0]}, values[4], true);
  built.rgb_ = Warp2D(n, n, {values[1], values[0], {0.0, 1.0, 2.0}}, values[6], false);
  *brdf = std::move(built);
  return timer.Succeeded();
}

core::Summary ReadRgl(const std::string& path, RglBrdf* brdf) {
  TensorFile file;
  const core::Summary read = ReadTensorFile(path, &file);
  if (!read.IsSolutionUsable()) return read;
  return BuildRglBrdf(path, file, brdf);
}

bool RglTabulation::IsValid(std::string* why) const {
  auto bad = [why](const std::string& what) {
    if (why) *why = what;
    return false;
  };
  if (theta_i_count < 2 || theta_i_count > 1024) return bad("theta_i_count must lie in [2, 1024]");
  if (!(theta_i_max_deg > 0.0 && theta_i_max_deg < 90.0)) return bad("theta_i_max_deg must lie in (0, 90)");
  if (sample_resolution < 2 || sample_resolution > 1024) return bad("sample_resolution must lie in [2, 1024]");
  if (ndf_resolution < 2 || ndf_resolution > 1024) return bad("ndf_resolution must lie in [2, 1024]");
  if (!(ndf_roughness > 0.0 && ndf_roughness <= 1.0)) return bad("ndf_roughness must lie in (0, 1]");
  return true;
}

core::Summary TabulateRgl(const std::function<Eigen::Vector3d(const DirectionPair&)>& brdf, const RglTabulation& tab,
                    TensorFile* file) {
  core::SolveTimer timer;
  std::string why;
  if (!tab.IsValid(&why)) return core::Ended(core::Termination::kInvalidOptions, why);
  const double a = tab.ndf_roughness;
  const int T = tab.theta_i_count, M = tab.ndf_resolution, N = tab.sample_resolution;
  auto node = [](int i, int n) { return double(i) / (n - 1); };

  std::vector<float> theta_i(T), phi_i = {0.0f};
  const double u_max = ThetaToU(tab.theta_i_max_deg * M_PI / 180.0);
  for (int k = 0; k < T; ++k) theta_i[k] = static_cast<float>(UToTheta(node(k, T) * u_max));

  std::vector<float> ndf(std::size_t(M) * M), sigma(std::size_t(M) * M);
  for (int y = 0; y < M; ++y)
    for (int x = 0; x < M; ++x) {
      const double theta = UToTheta(node(x, M));
      ndf[y * M + x] = static_cast<float>(GgxNdf(a, std::cos(theta)));
      sigma[y * M + x] = static_cast<float>(GgxSigma(a, std::cos(theta)));
    }

  // The visible normals seen from each incident elevation (phi_i = 0), as a
  // density in the u square: D_wi(w_m) times d(solid angle) / d(u) = 2 pi^2 u sin theta_m.
  std::vector<float> vndf(std::size_t(T) * M * M);
  for (int k = 0; k < T; ++k) {
    const Eigen::Vector3d wi = Spherical(theta_i[k], 0.0);
    const double sigma_i = GgxSigma(a, wi.z());
    for (int y = 0; y < M; ++y)
      for (int x = 0; x < M; ++x) {
        const double theta_m = UToTheta(node(x, M));
        const Eigen::Vector3d wm = Spherical(theta_m, UToPhi(node(y, M)));
        const double jac = 2.0 * M_PI * M_PI * node(x, M) * std::sin(theta_m);
        vndf[(std::size_t(k) * M + y) * M + x] =
            static_cast<float>(std::max(0.0, wi.dot(wm)) * GgxNdf(a, wm.z()) / sigma_i * jac);
      }
  }
  // The warp exactly as a reader builds it from the stored floats, so that a
  // node's direction here is the direction a reader inverts back to that node.
  const std::vector<double> theta_i_d(theta_i.begin(), theta_i.end());
  const Warp2D warp(M, M, {{0.0}, theta_i_d}, std::vector<double>(vndf.begin(), vndf.end()), true);

  std::vector<float> rgb(std::size_t(T) * 3 * N * N), luminance(std::size_t(T) * N * N);
  for (int k = 0; k < T; ++k) {
    const Eigen::Vector3d wi = Spherical(theta_i[k], 0.0);
    const double sigma_i = GgxSigma(a, wi.z());
    for (int y = 0; y < N; ++y)
      for (int x = 0; x < N; ++x) {
        const Eigen::Vector2d u_m = warp.Sample({node(x, N), node(y, N)}, {0.0, theta_i_d[k]});
        const Eigen::Vector3d wm = Spherical(UToTheta(u_m.x()), UToPhi(u_m.y()));
        Eigen::Vector3d wo = 2.0 * wm.dot(wi) * wm - wi;
        // Nodes on the edge of the visible region reflect to the horizon or
        // just past it; they only feed interpolation there, so take the value
        // just above the horizon.
        wo.z() = std::max(wo.z(), 1e-4);
        wo.normalize();
        const Eigen::Vector3d f = brdf({wi, wo}) * (4.0 * sigma_i / GgxNdf(a, wm.z()));
        for (int c = 0; c < 3; ++c) rgb[((std::size_t(k) * 3 + c) * N + y) * N + x] = static_cast<float>(f[c]);
        luminance[(std::size_t(k) * N + y) * N + x] =
            static_cast<float>(std::max(0.0, 0.2126 * f[0] + 0.7152 * f[1] + 0.0722 * f[2]));
      }
  }
  // BuildRglBrdf refuses a table that is not finite: it is never made.
  for (std::size_t i = 0; i < rgb.size(); ++i)
    if (!std::isfinite(rgb[i])) {
      const std::size_t x = i % N, y = i / N % N, c = i / (std::size_t(N) * N) % 3, k = i / (std::size_t(N) * N * 3);
      return core::Ended(core::Termination::kInvalidInput,
                   "field 'rgb' cell " + std::to_string(i) + " (theta_i " + std::to_string(theta_i[k] * 180.0 / M_PI) +
                       " deg, channel " + "RGB"[c] + ", sample " + std::to_string(x) + ", " + std::to_string(y) +
                       ") is " + (std::isnan(rgb[i]) ? "NaN" : "infinite") +
                       " (beyond a float's range or undefined there), which no reader accepts");
    }
  TensorFile out;
  const auto t = static_cast<std::uint64_t>(T), m = static_cast<std::uint64_t>(M), n = static_cast<std::uint64_t>(N);
  out.fields.push_back(TensorField::FromBytes("description", {tab.description.size()},
                                              {tab.description.begin(), tab.description.end()}));
  out.fields.push_back(TensorField::FromBytes("jacobian", {1}, {1}));
  out.fields.push_back(TensorField::FromFloats("theta_i", {t}, theta_i));
  out.fields.push_back(TensorField::FromFloats("phi_i", {1}, phi_i));
  out.fields.push_back(TensorField::FromFloats("ndf", {m, m}, ndf));
  out.fields.push_back(TensorField::FromFloats("sigma", {m, m}, sigma));
  out.fields.push_back(TensorField::FromFloats("vndf", {1, t, m, m}, vndf));
  out.fields.push_back(TensorField::FromFloats("luminance", {1, t, n, n}, luminance));
  out.fields.push_back(TensorField::FromFloats("rgb", {1, t, 3, n, n}, rgb));
  *file = std::move(out);
  return timer.Succeeded();
}

}  // namespace photorig::solvers::brdf
