// Value and partial derivatives of the elementary functions. Forward mode (dual.h) and reverse
// mode (tape.h) both apply these rules, so every edge case is decided once, here.
#pragma once

#include <cmath>

// The operators of Dual and Var are a handful of instructions each; left to its heuristics the
// compiler declines to inline some of them into large expressions, which costs a call and a trip
// through memory per operation. They are forced inline.
#define PHOTORIG_AUTODIFF_INLINE [[gnu::always_inline]] inline

namespace photorig::solvers::autodiff::internal {

struct UnaryRule {
  double value;
  double d_x;
};

struct BinaryRule {
  double value;
  double d_x;
  double d_y;
};

// d sqrt(x) = 1 / (2 sqrt(x)); +inf at x = 0 (the tangent masking in dual.h and the zero-adjoint
// skip in tape.h keep that infinity out of derivatives that do not depend on x).
PHOTORIG_AUTODIFF_INLINE UnaryRule Sqrt(double x) {
  const double root = std::sqrt(x);
  return {root, 0.5 / root};
}

PHOTORIG_AUTODIFF_INLINE UnaryRule Exp(double x) {
  const double e = std::exp(x);
  return {e, e};
}

PHOTORIG_AUTODIFF_INLINE UnaryRule Log(double x) { return {std::log(x), 1.0 / x}; }

PHOTORIG_AUTODIFF_INLINE UnaryRule Sin(double x) { return {std::sin(x), std::cos(x)}; }

PHOTORIG_AUTODIFF_INLINE UnaryRule Cos(double x) { return {std::cos(x), -std::sin(x)}; }

// Subgradient choice: d|x| = 0 at x = 0.
PHOTORIG_AUTODIFF_INLINE UnaryRule Abs(double x) {
  return {std::abs(x), x > 0.0 ? 1.0 : (x < 0.0 ? -1.0 : 0.0)};
}

// x^e for a constant e. Away from 0 the derivative e x^e / x reuses the power (one pow, not
// two). At x = 0: e > 1 gives 0, e = 1 gives 1, 0 < e < 1 gives +inf (the true, unbounded
// slope), e = 0 gives 0 (x^0 is the constant 1), e < 0 gives -inf next to a value of +inf.
PHOTORIG_AUTODIFF_INLINE UnaryRule PowConstantExponent(double x, double e) {
  const double power = std::pow(x, e);
  if (x != 0.0) {
    return {power, e * power / x};
  }
  return {power, e == 0.0 ? 0.0 : e * std::pow(x, e - 1.0)};
}

// x^y with both arguments variable. Both partials need log(x) (d/dy x^y = x^y log x), so for
// x > 0 the power is computed as exp(y log x) from that same log: half the cost of pow + log.
// Its error is |y log x| ulps relative, i.e. at most ~0.4 ulp of 1 in absolute terms for
// 0 < x <= 1 (a cosine raised to a shininess), where the power itself is at most 1.
// At x = 0 the exponent derivative is the limit of x^y log(x), 0 for y > 0, rather than
// 0 * -inf = NaN. For x < 0 it is NaN (log of a negative number): use the constant-exponent
// overload when y does not vary.
PHOTORIG_AUTODIFF_INLINE BinaryRule Pow(double x, double y) {
  if (x > 0.0) {
    const double log_x = std::log(x);
    const double power = std::exp(y * log_x);
    return {power, y * power / x, power * log_x};
  }
  const UnaryRule base = PowConstantExponent(x, y);
  return {base.value, base.d_x, (x == 0.0 && y > 0.0) ? 0.0 : base.value * std::log(x)};
}

// atan2(y, x): d/dy = x / r^2, d/dx = -y / r^2. At the origin the angle is discontinuous and no
// derivative exists; we return zero partials there (a documented choice, not NaN).
PHOTORIG_AUTODIFF_INLINE BinaryRule Atan2(double y, double x) {
  const double r2 = x * x + y * y;
  if (r2 == 0.0) {
    return {std::atan2(y, x), 0.0, 0.0};
  }
  return {std::atan2(y, x), x / r2, -y / r2};
}

}  // namespace photorig::solvers::autodiff::internal
