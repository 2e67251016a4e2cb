// The shape of a function every differentiation method in this module accepts: written once,
// templated on the scalar type, in the Ceres style.
//
//   struct F {
//     int num_inputs() const;
//     int num_outputs() const;
//     template <typename T> bool operator()(const T* x, T* y) const;  // false: cannot evaluate
//   };
//
// T is double for plain evaluation and finite differences, Dual<N> for forward mode, Var for
// reverse mode (and ceres::Jet<double, N> works too, which the benchmark uses as reference).
#pragma once

#include <concepts>

namespace photorig::solvers::autodiff {

template <typename F>
concept DifferentiableFunction = requires(const F& f, const double* x, double* y) {
  { f.num_inputs() } -> std::convertible_to<int>;
  { f.num_outputs() } -> std::convertible_to<int>;
  { f(x, y) } -> std::convertible_to<bool>;
};

}  // namespace photorig::solvers::autodiff
