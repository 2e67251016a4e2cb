// Jacobians by forward and reverse mode of functions written as in function.h.
//
// Forward mode costs one pass per kStride inputs and wins when inputs are few; reverse mode
// costs one recording plus one backward sweep per output and wins when outputs are few (a scalar
// loss: the gradient for a small constant times one evaluation, whatever the number of inputs).
#pragma once

#include <algorithm>
#include <vector>

#include <Eigen/Core>

#include "photorig/solvers/autodiff/dual.h"
#include "photorig/solvers/autodiff/function.h"
#include "photorig/solvers/autodiff/tape.h"

namespace photorig::solvers::autodiff {

// Value and Jacobian (num_outputs x num_inputs) by forward mode. Each pass seeds kStride inputs
// with Dual<kStride>; with kStride == kDynamic a single DynamicDual pass carries all of them.
// Returns false, leaving the outputs unspecified, if f fails.
template <int kStride, DifferentiableFunction F>
bool ForwardJacobian(const F& f, const double* x, Eigen::VectorXd* value,
                     Eigen::MatrixXd* jacobian) {
  const int num_inputs = f.num_inputs();
  const int num_outputs = f.num_outputs();
  const int stride = kStride == kDynamic ? std::max(num_inputs, 1) : kStride;
  std::vector<Dual<kStride>> inputs(num_inputs);
  std::vector<Dual<kStride>> outputs(num_outputs);
  value->resize(num_outputs);
  jacobian->resize(num_outputs, num_inputs);
  // At least one pass, so a function of no inputs still gets evaluated.
  for (int begin = 0; begin == 0 || begin < num_inputs; begin += stride) {
    const int count = std::min(stride, num_inputs - begin);
    for (int j = 0; j < num_inputs; ++j) {
      const int k = j - begin;
      if (k < 0 || k >= count) {
        inputs[j] = Dual<kStride>(x[j]);
      } else if constexpr (kStride == kDynamic) {
        inputs[j] = Dual<kStride>(x[j], k, stride);
      } else {
        inputs[j] = Dual<kStride>(x[j], k);
      }
    }
    if (!f(inputs.data(), outputs.data())) {
      return false;
    }
    for (int i = 0; i < num_outputs; ++i) {
      const auto& tangent = outputs[i].tangent;
      if (tangent.size() == 0) {  // A DynamicDual constant: independent of x.
        jacobian->row(i).segment(begin, count).setZero();
      } else {
        jacobian->row(i).segment(begin, count) = tangent.head(count).transpose();
      }
    }
  }
  for (int i = 0; i < num_outputs; ++i) {
    (*value)[i] = outputs[i].value;
  }
  return true;
}

// Value and Jacobian by reverse mode: one recording on `tape` (reset first, memory kept), then
// one backward sweep per output. Returns false, leaving the outputs unspecified, if f fails or
// the tape could not record it (Tape::ok()).
template <DifferentiableFunction F>
bool ReverseJacobian(const F& f, const double* x, Tape* tape, Eigen::VectorXd* value,
                     Eigen::MatrixXd* jacobian) {
  const int num_inputs = f.num_inputs();
  const int num_outputs = f.num_outputs();
  tape->Reset();
  std::vector<Var> inputs(num_inputs);
  std::vector<Var> outputs(num_outputs);
  for (int j = 0; j < num_inputs; ++j) {
    inputs[j] = tape->Variable(x[j]);
  }
  if (!f(inputs.data(), outputs.data()) || !tape->ok()) {
    return false;
  }
  value->resize(num_outputs);
  jacobian->resize(num_outputs, num_inputs);
  for (int i = 0; i < num_outputs; ++i) {
    (*value)[i] = outputs[i].value();
    tape->Backward(outputs[i]);
    for (int j = 0; j < num_inputs; ++j) {
      (*jacobian)(i, j) = tape->Adjoint(inputs[j]);
    }
  }
  return true;
}

}  // namespace photorig::solvers::autodiff
