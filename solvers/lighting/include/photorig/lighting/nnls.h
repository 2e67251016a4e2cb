#pragma once
// Non-negative least squares, Lawson-Hanson active set, on the normal equations
// (G = A^T A, h = A^T b) so that tall problems are reduced once.

#include <Eigen/Core>

#include <string>

namespace photorig::lighting {

struct NnlsSummary {
  bool converged = false;
  int iterations = 0;
  int active_count = 0;  // strictly positive entries
  std::string message;
};

// Minimises ||A x - b||^2 subject to x >= 0 given G = A^T A and h = A^T b.
NnlsSummary SolveNnlsNormal(const Eigen::MatrixXd& gram, const Eigen::VectorXd& rhs, Eigen::VectorXd* x,
                            int max_iterations = -1);
NnlsSummary SolveNnls(const Eigen::MatrixXd& a, const Eigen::VectorXd& b, Eigen::VectorXd* x);

}  // namespace photorig::lighting
