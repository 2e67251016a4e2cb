#pragma once
// The low-frequency reflectance of one pixel, `auto`'s step 7:
//
//   I_k = max(0, n . l_k) (a0 + a1 c_k + a2 c_k^2 + a3 d_k),   every a >= 0,
//   c_k = max(0, n . h_k) (the half vector's cosine), d_k = l_k . h_k (cos theta_d).
//
// An isotropic reflectance that may only grow towards the mirror direction
// and with the half angle, with no lobe width or shape to fit: a broad lobe
// seen by its tail, light the surface sends back to itself and a soft
// shoulder all take this form, while a Lambertian pixel is a0 alone. A sharp
// spike does not, so the pixel's brightest usable samples (spike_fraction of
// them) are left out. For a given normal the model is linear in a: the fit
// is variable projection, non-negative least squares for a (the last
// support if it is still optimal, else the best of the fifteen, each a small
// Cholesky solve) inside a Levenberg-Marquardt search over the normal's two
// tangent-plane angles with variable projection's Jacobian (Kaufman's form),
// from the model's Lambertian case (a0 alone) fitted to the same samples.
// Without a >= 0 the n . h terms trade against the normal.
//
// The misfit is unweighted: the model is an approximation, and where its
// residual is the reflectance it does not model rather than noise, weights
// of 1 / sigma would hand the fit to the darkest samples, where 8-bit
// quantisation and penumbrae are (on DiLiGenT's five objects a weighted
// fit was 0.4 deg worse on the mean). Chi-square, for the ladder, weighs
// each residual by its sigma.
//
// One pixel at a time in double; the sample loops run a few samples per
// pass, one per SIMD lane.

#include <Eigen/Core>

#include <array>
#include <span>
#include <vector>

namespace photorig::solvers::ps::internal {

// The model's parameters: the normal's two and a0..a3.
inline constexpr int kLowFrequencyParameters = 6;

struct LowFrequencySolution {
  bool ok = false;  // converged or stopped at a finite fit facing the view, on > 6 samples
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  // a0..a3 in the units of the samples: a Lambertian pixel of albedo rho has a0 = rho / pi.
  std::array<double, 4> a{};
  double chi2 = 0.0;  // on the samples fitted
  int used = 0;       // samples fitted
  int left_out = 0;   // the brightest usable samples, left out as a spike
  int iterations = 0;
  // The normal's uncertainty: two unit tangents at it (columns) and the
  // inverse covariance of its angles along them, J^T J (variable
  // projection's, with a re-solved) over the residual variance per degree
  // of freedom (unweighted, as the fit; at least the samples' mean noise
  // variance).
  Eigen::Matrix<double, 3, 2> tangents = Eigen::Matrix<double, 3, 2>::Zero();
  Eigen::Matrix2d normal_information = Eigen::Matrix2d::Zero();
};

struct HalfVectorTable;

// A pixel's samples: per light k, the direction towards the light (wx[k
// stride], wy[k stride], wz[k stride]), the observed value and its inverse
// sigma (0: unusable); `view` towards the camera (unit).
struct LowFrequencyProblem {
  int lights = 0;
  const double *wx = nullptr, *wy = nullptr, *wz = nullptr;
  int stride = 1;
  Eigen::Vector3d view = Eigen::Vector3d::UnitZ();
  const double* observed = nullptr;
  const double* inverse_sigma = nullptr;
  // Every light's half vector and cos theta_d where all pixels share them
  // (distant lights, one view; made from these directions and view); null:
  // computed per sample.
  const HalfVectorTable* halves = nullptr;

  // Light k's direction l, half vector h = (l + view) / |l + view| and cos theta_d = l . h.
  void Geometry(int k, Eigen::Vector3d* l, Eigen::Vector3d* h, double* cos_d) const;
};

// The half vectors and cos theta_d of a problem's lights, once for every
// pixel that shares them: a step-7 pixel otherwise normalises one per
// sample twice (its fit and its spike test).
struct HalfVectorTable {
  std::vector<double> x, y, z, cos_d;
  // From `problem`'s directions and view (its halves unused).
  explicit HalfVectorTable(const LowFrequencyProblem& problem);
};

// Samples per pass of the fit's sample loops (four doubles: one AVX2 register).
inline constexpr int kLowFrequencySampleLanes = 4;

// A fit's samples as plain arrays, for its multi-versioned loops: light and
// half vectors by axis, cos theta_d, value and inverse sigma; padded_count
// entries, a whole number of passes, the samples beyond the fit's all zero
// (a zero light direction and value add nothing to any sum).
struct LowFrequencySamples {
  const double *lx, *ly, *lz, *hx, *hy, *hz, *d, *b, *inverse_sigma;
  int padded_count;
};

class LowFrequencyFitter {
 public:
  // spike_fraction in [0, 0.5): the share of a pixel's usable samples left
  // out, brightest first.
  explicit LowFrequencyFitter(double spike_fraction) : spike_fraction_(spike_fraction) {}

  LowFrequencySolution Fit(const LowFrequencyProblem& problem);
  // The same fit of the last Fit's samples (used_lights()) with other
  // values, one per sample in that order: what the fit makes of a model's
  // prediction of the pixel.
  LowFrequencySolution FitSameSamples(std::span<const double> values);
  // How many of `usable` samples a fit leaves out.
  int LeftOut(int usable) const { return static_cast<int>(spike_fraction_ * usable); }
  // The lights of the samples the last Fit used.
  std::span<const int> used_lights() const { return order_; }

 private:
  // The sum of squared residuals at `normal` with its non-negative a, the
  // a's support (a bit mask; `support` is tried first) and the normal
  // equations' sums (NormalEquationSums).
  struct Evaluation {
    double misfit = 0.0;
    std::array<double, 4> a{};
    int support = 0;
    std::array<double, 14> sums{};
  };
  Evaluation Evaluate(const Eigen::Vector3d& normal, int support) const;
  // Chi-square of the fit (each residual over its sample's sigma).
  double Chi2(const Eigen::Vector3d& normal, const std::array<double, 4>& a) const;
  // The Gauss-Newton system of the misfit in the two tangent angles t1, t2
  // at `normal`, with a re-solved (variable projection).
  void TangentSystem(const Eigen::Vector3d& normal, const Evaluation& at, const Eigen::Vector3d& t1,
                     const Eigen::Vector3d& t2, Eigen::Matrix2d* jtj, Eigen::Vector2d* jtr) const;

  // Levenberg-Marquardt from `normal` to the misfit's nearest minimum:
  // returns the normal, *at its evaluation, *iterations how many it took.
  Eigen::Vector3d Search(Eigen::Vector3d normal, const Eigen::Vector3d& view, Evaluation* at, int* iterations) const;
  // The fit of the compacted samples, from the Lambertian case's normal.
  LowFrequencySolution Solve();
  // The variance per sample the fit's normal_information divides by, at a misfit
  // (sum of squared residuals) of the compacted samples.
  double ResidualVariance(double misfit) const;
  LowFrequencySamples Samples() const {
    return {lx_.data(), ly_.data(), lz_.data(), hx_.data(),          hy_.data(),
            hz_.data(), d_.data(),  b_.data(),  inverse_sigma_.data(), static_cast<int>(b_.size())};
  }
  // Sizes the sample arrays for `count` samples, zero beyond them (Samples()).
  void ResizeSamples(int count);

  double spike_fraction_;
  // The samples fitted, compacted: light and half vectors, cos theta_d,
  // value and inverse sigma; count_ of them, then zeros to a whole pass.
  std::vector<double> lx_, ly_, lz_, hx_, hy_, hz_, d_, b_, inverse_sigma_;
  int count_ = 0;
  std::vector<int> order_;
  double b2_ = 0.0;  // sum of b^2
  double mean_noise_variance_ = 0.0;  // of the compacted samples (Solve's)
  Eigen::Vector3d view_ = Eigen::Vector3d::UnitZ();
  int left_out_ = 0;
};

}  // namespace photorig::solvers::ps::internal
