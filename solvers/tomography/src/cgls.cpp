// CGLS: conjugate gradients on the normal equations W^T W sigma = W^T b (reconstruct.h).
#include "iteration.h"

namespace photorig::solvers::tomography::internal {
namespace {

class Cgls final : public Iteration {
 public:
  Cgls(const IterationInputs& in, const Eigen::VectorXf& r) : in_(in) {
    in.system.Back(r, &s_);
    p_ = s_;
    gamma_ = in.system.SumOverVoxels(SquaredNorm(s_));
    gamma_floor_ = gamma_ * 1e-12;
  }

  StepResult Step(Eigen::VectorXf* x, Eigen::VectorXf* r) override {
    in_.system.Forward(p_, &q_);
    q_ = q_.cwiseProduct(in_.mask);
    const double delta = in_.system.SumOverRays(SquaredNorm(q_));
    // At the least-squares point (|W^T r| down by 1e6, float precision) a
    // further step divides rounding noise by rounding noise.
    if (delta <= 0.0 || gamma_ <= gamma_floor_) return {true, -1.0};
    const auto alpha = static_cast<float>(gamma_ / delta);
    *x += alpha * p_;
    *r -= alpha * q_;
    in_.system.Back(*r, &s_);
    const double gamma_next = in_.system.SumOverVoxels(SquaredNorm(s_));
    p_ = s_ + static_cast<float>(gamma_next / gamma_) * p_;
    gamma_ = gamma_next;
    return {};
  }

 private:
  IterationInputs in_;
  Eigen::VectorXf s_, p_, q_;                 // W^T r, the search direction, W p
  double gamma_ = 0.0, gamma_floor_ = 0.0;    // |W^T r|^2 now, and where float precision ends
};

}  // namespace

std::unique_ptr<Iteration> MakeCgls(const IterationInputs& in, const Eigen::VectorXf& r) {
  return std::make_unique<Cgls>(in, r);
}

}  // namespace photorig::solvers::tomography::internal
