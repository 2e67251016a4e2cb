// SIRT: every ray at once, sigma += lambda C W^T R (b - W sigma) (reconstruct.h).
#include "iteration.h"

namespace photorig::solvers::tomography::internal {
namespace {

class Sirt final : public Iteration {
 public:
  explicit Sirt(const IterationInputs& in)
      : in_(in), inv_rows_(Reciprocals(in.row_sums)), inv_columns_(Reciprocals(in.column_sums)) {}

  StepResult Step(Eigen::VectorXf* x, Eigen::VectorXf* r) override {
    in_.system.Back(r->cwiseProduct(inv_rows_), &g_);
    *x += static_cast<float>(in_.lambda) * inv_columns_.cwiseProduct(g_);
    if (in_.non_negative) ClampNonNegative(x);
    in_.system.Forward(*x, in_.wx);
    MaskedResidual(in_.b, *in_.wx, in_.mask, r);
    return {};
  }

 private:
  IterationInputs in_;
  Eigen::VectorXf inv_rows_, inv_columns_;  // R and C
  Eigen::VectorXf g_;
};

}  // namespace

std::unique_ptr<Iteration> MakeSirt(const IterationInputs& in) { return std::make_unique<Sirt>(in); }

}  // namespace photorig::solvers::tomography::internal
