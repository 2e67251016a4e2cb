// What the two scalars, Dual (dual.h) and Var (tape.h), share: the elementary functions, each
// the rule of rules.h applied to the argument's value through the scalar's internal::Apply, and
// the traits Eigen needs of a scalar that stands for a double.
#pragma once

#include <concepts>
#include <limits>

#include <Eigen/Core>

#include "photorig/solvers/autodiff/rules.h"

namespace photorig::solvers::autodiff {

// Dual<N> and Var: each declares ValueOf(x), the double x stands for, and internal::Apply of a
// rule to it; both are found by argument-dependent lookup, after this header.
template <typename T>
concept DifferentiableScalar = requires(const T& x) {
  { ValueOf(x) } -> std::same_as<double>;
};

// Elementary functions; edge cases are documented in rules.h.
template <DifferentiableScalar T>
PHOTORIG_AUTODIFF_INLINE T sqrt(const T& x) {
  return Apply(internal::Sqrt(ValueOf(x)), x);
}
template <DifferentiableScalar T>
PHOTORIG_AUTODIFF_INLINE T exp(const T& x) {
  return Apply(internal::Exp(ValueOf(x)), x);
}
template <DifferentiableScalar T>
PHOTORIG_AUTODIFF_INLINE T log(const T& x) {
  return Apply(internal::Log(ValueOf(x)), x);
}
template <DifferentiableScalar T>
PHOTORIG_AUTODIFF_INLINE T sin(const T& x) {
  return Apply(internal::Sin(ValueOf(x)), x);
}
template <DifferentiableScalar T>
PHOTORIG_AUTODIFF_INLINE T cos(const T& x) {
  return Apply(internal::Cos(ValueOf(x)), x);
}
template <DifferentiableScalar T>
PHOTORIG_AUTODIFF_INLINE T abs(const T& x) {
  return Apply(internal::Abs(ValueOf(x)), x);
}
template <DifferentiableScalar T>
PHOTORIG_AUTODIFF_INLINE T atan2(const T& y, const T& x) {
  return Apply(internal::Atan2(ValueOf(y), ValueOf(x)), y, x);
}
template <DifferentiableScalar T>
PHOTORIG_AUTODIFF_INLINE T pow(const T& x, double e) {
  return Apply(internal::PowConstantExponent(ValueOf(x), e), x);
}
template <DifferentiableScalar T>
PHOTORIG_AUTODIFF_INLINE T pow(const T& x, const T& y) {
  return Apply(internal::Pow(ValueOf(x), ValueOf(y)), x, y);
}

namespace internal {

// Eigen::NumTraits of a scalar standing for a double; each specialisation adds the costs.
template <typename T>
struct DoubleNumTraits : Eigen::GenericNumTraits<T> {
  using Real = T;
  using NonInteger = Real;
  using Nested = Real;
  using Literal = Real;
  enum {
    IsComplex = 0,
    IsInteger = 0,
    IsSigned = 1,
    RequireInitialization = 1,
  };
  static Real epsilon() { return Real(std::numeric_limits<double>::epsilon()); }
  static Real dummy_precision() { return Real(1e-12); }
  static Real highest() { return Real(std::numeric_limits<double>::max()); }
  static Real lowest() { return Real(std::numeric_limits<double>::lowest()); }
  static int digits10() { return std::numeric_limits<double>::digits10; }
};

}  // namespace internal
}  // namespace photorig::solvers::autodiff
