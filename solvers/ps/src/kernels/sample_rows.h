#pragma once
// One pixel's samples over every light as rows of doubles, for the per-pixel
// fits and for the rows the lane fitters start from: reading a row and
// testing a Lambertian solution on it, and the sums of the refit without
// samples the solution leaves in attached shadow. Multi-versioned loops over
// plain arrays (lane_math.h), no Eigen.

namespace photorig::solvers::ps::internal {

// One pixel's samples over every light: b = (I - D) / s, 1 / sigma with
// sigma^2 = Var(I - D) / s^2 (0 for a shadowed or clipped sample, whose b is
// 0), and chi-square of the Lambertian solution x on the usable samples.
// Plain arrays, so the loop vectorises; the raw values are read beforehand
// (GCC does not vectorise a load through a per-lane pointer, and a loop with
// one stays scalar throughout).
struct RowInputs {
  int lights;
  const float* const* planes;
  const float* dark;  // null: no dark frame
  double shadow_threshold, saturation_level;
  const double* scales;
  const double* inverse_scales;
  double read_variance, shot_gain;
  const double* directions;  // 3 per light
};

// `observed` holds the raw values I on entry, dark is D.
void ReadRow(const RowInputs& in, double dark, const double* x, double* observed, double* inverse_sigma, double* chi2,
             int* usable);

// FitLit's pass over every light's sample (a row as ReadRow writes it: b, and
// 1 / sigma, 0 where unusable): the normal equations of the usable samples
// the solution x lights (w . x > 0), chi-square of x on them, how many usable
// samples x leaves in attached shadow or, compared with the solution
// `previous`, moves across the terminator, and the largest squared
// standardised residual of x among the lit and among the unlit samples.
struct LitSums {
  double gxx = 0, gyy = 0, gzz = 0, gxy = 0, gxz = 0, gyz = 0, rx = 0, ry = 0, rz = 0;
  double chi2 = 0, used = 0, unlit = 0, moved = 0;
  double worst_lit = 0, worst_unlit = 0;
};
LitSums SumLitSamples(int lights, const double* wx, const double* wy, const double* wz, const double* observed,
                      const double* inverse_sigma, const double* x, const double* previous);

}  // namespace photorig::solvers::ps::internal
