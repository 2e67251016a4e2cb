#pragma once
// The methods behind Reconstruct (reconstruct.h), one file each: art.cpp,
// sirt.cpp, sart.cpp (with its total-variation steps), cgls.cpp. Each keeps
// its own state and makes one iteration at a time; the loop around them, its
// stopping rules and the summary are Reconstruct's (reconstruct.cpp).

#include "photorig/solvers/tomography/projector.h"

#include <Eigen/Core>

#include <memory>

namespace photorig::solvers::tomography {
// Declared, not included: reconstruct.cpp runs the methods, so their header
// names its options only by reference (sart.cpp, which reads them, includes it).
struct ReconstructOptions;
}  // namespace photorig::solvers::tomography

namespace photorig::solvers::tomography::internal {

// sum of v_i^2 in double, over this process's share.
double SquaredNorm(const Eigen::VectorXf& v);
// r = mask (b - y): the residual over the valid rays.
void MaskedResidual(const Eigen::VectorXf& b, const Eigen::VectorXf& y, const Eigen::VectorXf& mask,
                    Eigen::VectorXf* r);
void ClampNonNegative(Eigen::VectorXf* x);
// 1 / sums, 0 where a sum is 0: R and C of SIRT and SART from W's row and column sums.
Eigen::VectorXf Reciprocals(const Eigen::VectorXf& sums);

// What the methods start from.
struct IterationInputs {
  const SystemMatrix& system;
  const Projector* whole;  // the same system when every row is in this process (ART and SART need it), else null
  const Eigen::VectorXf& b;            // the measurements, 0 on invalid rays
  const Eigen::VectorXf& mask;         // 1 on valid rays, 0 elsewhere
  const Eigen::VectorXf& row_sums;     // W 1
  const Eigen::VectorXf& column_sums;  // W^T mask
  double lambda = 0.0;                 // the relaxation
  bool non_negative = false;
  const ReconstructOptions& options;
  double discrepancy_target = 0.0;     // ReconstructionSummary::discrepancy_target
  double tv_strength = 0.0;            // 0: no total variation
  // Scratch for W x, ray-sized already: the methods' forward projections
  // reuse Reconstruct's buffer rather than allocate their own.
  Eigen::VectorXf* wx = nullptr;
};

struct StepResult {
  // The method can take no further step (CGLS at the least-squares point):
  // x and r are as before.
  bool converged = false;
  // The residual's norm as the method met it during the step, standing for
  // the exact one, which r then does not hold; negative when r is exact.
  double residual_met = -1.0;
};

class Iteration {
 public:
  virtual ~Iteration() = default;
  // One iteration (an ART sweep, a SART pass, ...) on *x; *r becomes the
  // residual mask (b - W x) unless the result says otherwise.
  virtual StepResult Step(Eigen::VectorXf* x, Eigen::VectorXf* r) = 0;
};

std::unique_ptr<Iteration> MakeArt(const IterationInputs& in);
std::unique_ptr<Iteration> MakeSirt(const IterationInputs& in);
std::unique_ptr<Iteration> MakeSart(const IterationInputs& in);
// r: the residual at the starting volume.
std::unique_ptr<Iteration> MakeCgls(const IterationInputs& in, const Eigen::VectorXf& r);

}  // namespace photorig::solvers::tomography::internal
