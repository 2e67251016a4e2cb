#pragma once
// Non-negative least squares, Lawson-Hanson active set, on the normal equations
// (G = A^T A, h = A^T b) so that tall problems are reduced once.

#include "photorig/solvers/core/summary.h"

#include <Eigen/Core>

#include <string>

namespace photorig::solvers::lighting {

struct NnlsOptions {
  // Active-set iterations before giving up; 0: 3 n + 10 for n unknowns, which
  // Lawson-Hanson needs rarely more than n of on well-posed problems.
  int max_iterations = 0;
  bool IsValid(std::string* why) const;
};

// kSuccess: the KKT conditions hold; kNoConvergence: the iteration limit came
// first (x is feasible, not optimal); kInvalidOptions / kInvalidInput: x untouched.
struct NnlsSummary : solvers::core::Summary {
  int iterations = 0;
  int active_count = 0;  // strictly positive entries
};

// Minimises ||A x - b||^2 subject to x >= 0 given G = A^T A and h = A^T b.
NnlsSummary SolveNnlsNormal(const Eigen::MatrixXd& gram, const Eigen::VectorXd& rhs, Eigen::VectorXd* x,
                            const NnlsOptions& options = {});
NnlsSummary SolveNnls(const Eigen::MatrixXd& a, const Eigen::VectorXd& b, Eigen::VectorXd* x,
                      const NnlsOptions& options = {});

}  // namespace photorig::solvers::lighting
