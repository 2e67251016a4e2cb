// Forward-mode automatic differentiation: dual numbers a + v.eps with eps^2 = 0.
//
// Dual<N> carries the value and its derivatives w.r.t. N seeded inputs, N fixed at compile time
// (stored in an Eigen fixed-size vector, no heap; a drop-in for ceres::Jet<double, N>). DynamicDual = Dual<kDynamic> chooses the
// number of components at run time; there an empty tangent stands for a constant (all zeros), so
// constants built from a double mix freely with seeded variables of any size.
//
// Every elementary function applies the rule in rules.h. Where a rule's derivative is infinite
// or NaN (sqrt at 0, pow(0, e) with e < 1), only tangent components that are non-zero receive
// it: a derivative w.r.t. an input the argument does not depend on stays exactly 0.
#pragma once

#include <cassert>
#include <cmath>
#include <compare>

#include <Eigen/Core>

#include "photorig/solvers/autodiff/scalar.h"

namespace photorig::solvers::autodiff {

inline constexpr int kDynamic = Eigen::Dynamic;

namespace internal {

// Tangent arithmetic. Fixed-size tangents use plain loops over raw storage: they inline and
// vectorise, whereas Eigen's assignment kernels, inside the large expressions forward mode
// produces, were left as out-of-line calls and cost 15% of a Blinn-Phong gradient. For the
// dynamic variant an empty tangent (a constant) acts as zeros of the other operand's size.

template <int N>
using Tangent = Eigen::Matrix<double, N, 1>;

template <int N>
PHOTORIG_AUTODIFF_INLINE Tangent<N> ZeroTangent() {
  Tangent<N> zero;
  if constexpr (N != Eigen::Dynamic) {
    for (int k = 0; k < N; ++k) {
      zero.data()[k] = 0.0;
    }
  }
  return zero;
}

// a * x.
template <int N>
PHOTORIG_AUTODIFF_INLINE Tangent<N> Scale(double a, const Tangent<N>& x) {
  if constexpr (N == Eigen::Dynamic) {
    return a * x;
  } else {
    Tangent<N> out;
    for (int k = 0; k < N; ++k) {
      out.data()[k] = a * x.data()[k];
    }
    return out;
  }
}

// a * x + b * y.
template <int N>
PHOTORIG_AUTODIFF_INLINE Tangent<N> Combine(double a, const Tangent<N>& x, double b,
                                            const Tangent<N>& y) {
  if constexpr (N == Eigen::Dynamic) {
    if (x.size() == 0) {
      return b * y;
    }
    if (y.size() == 0) {
      return a * x;
    }
    assert(x.size() == y.size() && "DynamicDual operands seeded with different sizes");
    return a * x + b * y;
  } else {
    Tangent<N> out;
    for (int k = 0; k < N; ++k) {
      out.data()[k] = a * x.data()[k] + b * y.data()[k];
    }
    return out;
  }
}

}  // namespace internal

template <int N>
struct Dual {
  static_assert(N > 0 || N == kDynamic, "Dual<N> needs N > 0 or N == kDynamic");
  using Tangent = internal::Tangent<N>;

  Dual() = default;
  // A constant: all derivatives zero.
  explicit Dual(double v) : value(v) {}
  Dual(double v, const Tangent& t) : value(v), tangent(t) {}
  // Independent input number `index`: its tangent is the unit vector e_index.
  Dual(double v, int index) requires(N != kDynamic) : value(v) { tangent[index] = 1.0; }
  Dual(double v, int index, int size) requires(N == kDynamic)
      : value(v), tangent(Tangent::Unit(size, index)) {}

  Dual& operator+=(const Dual& y) { return *this = *this + y; }
  Dual& operator-=(const Dual& y) { return *this = *this - y; }
  Dual& operator*=(const Dual& y) { return *this = *this * y; }
  Dual& operator/=(const Dual& y) { return *this = *this / y; }
  Dual& operator+=(double s) { return *this = *this + s; }
  Dual& operator-=(double s) { return *this = *this - s; }
  Dual& operator*=(double s) { return *this = *this * s; }
  Dual& operator/=(double s) { return *this = *this / s; }

  double value = 0.0;
  Tangent tangent = internal::ZeroTangent<N>();
};

using DynamicDual = Dual<kDynamic>;

template <int N>
PHOTORIG_AUTODIFF_INLINE double ValueOf(const Dual<N>& x) {
  return x.value;
}

namespace internal {

// c * t, except that zero components of t stay zero when c is infinite or NaN.
template <int N>
PHOTORIG_AUTODIFF_INLINE Tangent<N> MaskedScale(double c, const Tangent<N>& t) {
  if (std::isfinite(c)) [[likely]] {
    return Scale<N>(c, t);
  }
  return t.unaryExpr([c](double component) { return component == 0.0 ? 0.0 : c * component; });
}

template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> Apply(const UnaryRule& rule, const Dual<N>& x) {
  return Dual<N>(rule.value, MaskedScale<N>(rule.d_x, x.tangent));
}

template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> Apply(const BinaryRule& rule, const Dual<N>& x, const Dual<N>& y) {
  if (std::isfinite(rule.d_x) && std::isfinite(rule.d_y)) [[likely]] {
    return Dual<N>(rule.value, Combine<N>(rule.d_x, x.tangent, rule.d_y, y.tangent));
  }
  return Dual<N>(rule.value, Combine<N>(1.0, MaskedScale<N>(rule.d_x, x.tangent), 1.0,
                                        MaskedScale<N>(rule.d_y, y.tangent)));
}

}  // namespace internal

// Arithmetic. Values are computed exactly as the double expression would be.

template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> operator+(const Dual<N>& x) {
  return x;
}
template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> operator-(const Dual<N>& x) {
  return Dual<N>(-x.value, internal::Scale<N>(-1.0, x.tangent));
}

template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> operator+(const Dual<N>& x, const Dual<N>& y) {
  return Dual<N>(x.value + y.value, internal::Combine<N>(1.0, x.tangent, 1.0, y.tangent));
}
template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> operator-(const Dual<N>& x, const Dual<N>& y) {
  return Dual<N>(x.value - y.value, internal::Combine<N>(1.0, x.tangent, -1.0, y.tangent));
}
template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> operator*(const Dual<N>& x, const Dual<N>& y) {
  return Dual<N>(x.value * y.value, internal::Combine<N>(y.value, x.tangent, x.value, y.tangent));
}
template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> operator/(const Dual<N>& x, const Dual<N>& y) {
  const double inverse = 1.0 / y.value;
  const double quotient = x.value / y.value;
  return Dual<N>(quotient,
                 internal::Combine<N>(inverse, x.tangent, -quotient * inverse, y.tangent));
}

template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> operator+(const Dual<N>& x, double s) {
  return Dual<N>(x.value + s, x.tangent);
}
template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> operator+(double s, const Dual<N>& x) {
  return Dual<N>(s + x.value, x.tangent);
}
template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> operator-(const Dual<N>& x, double s) {
  return Dual<N>(x.value - s, x.tangent);
}
template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> operator-(double s, const Dual<N>& x) {
  return Dual<N>(s - x.value, internal::Scale<N>(-1.0, x.tangent));
}
template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> operator*(const Dual<N>& x, double s) {
  return Dual<N>(x.value * s, internal::Scale<N>(s, x.tangent));
}
template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> operator*(double s, const Dual<N>& x) {
  return Dual<N>(s * x.value, internal::Scale<N>(s, x.tangent));
}
template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> operator/(const Dual<N>& x, double s) {
  return Dual<N>(x.value / s, internal::Scale<N>(1.0 / s, x.tangent));
}
template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> operator/(double s, const Dual<N>& x) {
  const double quotient = s / x.value;
  return Dual<N>(quotient, internal::Scale<N>(-quotient / x.value, x.tangent));
}

// Comparisons look at the value only (as for ceres::Jet), so control flow follows the double
// evaluation exactly.
template <int N>
PHOTORIG_AUTODIFF_INLINE bool operator==(const Dual<N>& x, const Dual<N>& y) {
  return x.value == y.value;
}
template <int N>
PHOTORIG_AUTODIFF_INLINE std::partial_ordering operator<=>(const Dual<N>& x, const Dual<N>& y) {
  return x.value <=> y.value;
}
template <int N>
PHOTORIG_AUTODIFF_INLINE bool operator==(const Dual<N>& x, double s) {
  return x.value == s;
}
template <int N>
PHOTORIG_AUTODIFF_INLINE std::partial_ordering operator<=>(const Dual<N>& x, double s) {
  return x.value <=> s;
}

// The other elementary functions are scalar.h's.
template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> pow(double x, const Dual<N>& y) {
  const internal::BinaryRule rule = internal::Pow(x, y.value);
  return internal::Apply(internal::UnaryRule{rule.value, rule.d_y}, y);
}

// Selections return one argument unchanged, ties resolved as std::max/min/clamp do: max and min
// return the first argument, clamp returns x. So max(Dual(0), c) at c == 0 has derivative 0
// (the zero subgradient at a clamp), while max(c, Dual(0)) would pass c's derivative through.
template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> max(const Dual<N>& x, const Dual<N>& y) {
  return x < y ? y : x;
}
template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> min(const Dual<N>& x, const Dual<N>& y) {
  return y < x ? y : x;
}
template <int N>
PHOTORIG_AUTODIFF_INLINE Dual<N> clamp(const Dual<N>& x, const Dual<N>& lo, const Dual<N>& hi) {
  return x < lo ? lo : (hi < x ? hi : x);
}

}  // namespace photorig::solvers::autodiff

namespace Eigen {

// Lets Eigen matrices hold Dual scalars: Matrix<Dual<N>, 3, 1> supports dot(), norm(),
// normalized() and the rest of the dense API.
template <int N>
struct NumTraits<photorig::solvers::autodiff::Dual<N>>
    : photorig::solvers::autodiff::internal::DoubleNumTraits<photorig::solvers::autodiff::Dual<N>> {
  enum {
    ReadCost = N == Eigen::Dynamic ? HugeCost : N + 1,
    AddCost = N == Eigen::Dynamic ? HugeCost : N + 1,
    MulCost = N == Eigen::Dynamic ? HugeCost : 2 * N + 1,
  };
};

// Mixed double/Dual expressions (Vector3d.dot(Vector3<Dual>), Matrix3d * Vector3<Dual>) use the
// cheap scalar-times-Dual operators instead of promoting the doubles to zero-tangent Duals.
template <int N, typename BinaryOp>
struct ScalarBinaryOpTraits<photorig::solvers::autodiff::Dual<N>, double, BinaryOp> {
  using ReturnType = photorig::solvers::autodiff::Dual<N>;
};
template <int N, typename BinaryOp>
struct ScalarBinaryOpTraits<double, photorig::solvers::autodiff::Dual<N>, BinaryOp> {
  using ReturnType = photorig::solvers::autodiff::Dual<N>;
};

}  // namespace Eigen
