#include "photorig/solvers/lighting/nnls.h"

#include <Eigen/Dense>

#include <string>
#include <vector>

namespace photorig::solvers::lighting {

bool NnlsOptions::IsValid(std::string* why) const {
  if (max_iterations < 0) {
    if (why) *why = "max_iterations must be >= 0 (0: 3 n + 10), got " + std::to_string(max_iterations);
    return false;
  }
  return true;
}

NnlsSummary SolveNnlsNormal(const Eigen::MatrixXd& gram, const Eigen::VectorXd& rhs, Eigen::VectorXd* x,
                            const NnlsOptions& options) {
  const solvers::core::SolveTimer timer;
  NnlsSummary summary;
  if (solvers::core::EndIfInvalid(options, &summary)) return summary;
  const Eigen::Index n = rhs.size();
  if (gram.rows() != n || gram.cols() != n || x == nullptr) {
    summary.End(solvers::core::Termination::kInvalidInput, "gram matrix and right-hand side sizes differ");
    return summary;
  }
  if (!gram.allFinite() || !rhs.allFinite()) {
    summary.End(solvers::core::Termination::kInvalidInput, "gram matrix or right-hand side has NaN or infinite entries");
    return summary;
  }
  const int max_iterations = options.max_iterations > 0 ? options.max_iterations : static_cast<int>(3 * n + 10);
  bool converged = false;
  x->setZero(n);
  std::vector<bool> passive(static_cast<std::size_t>(n), false);
  const double tolerance = 1e-12 * std::max(1.0, gram.diagonal().cwiseAbs().maxCoeff());

  // Solves the unconstrained problem on the passive set; zero elsewhere.
  auto solve_passive = [&]() {
    std::vector<Eigen::Index> index;
    for (Eigen::Index i = 0; i < n; ++i) {
      if (passive[static_cast<std::size_t>(i)]) index.push_back(i);
    }
    Eigen::MatrixXd g(index.size(), index.size());
    Eigen::VectorXd h(index.size());
    for (std::size_t a = 0; a < index.size(); ++a) {
      h(static_cast<Eigen::Index>(a)) = rhs(index[a]);
      for (std::size_t b = 0; b < index.size(); ++b) {
        g(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) = gram(index[a], index[b]);
      }
    }
    const Eigen::VectorXd s_passive = g.ldlt().solve(h);
    Eigen::VectorXd s = Eigen::VectorXd::Zero(n);
    for (std::size_t a = 0; a < index.size(); ++a) s(index[a]) = s_passive(static_cast<Eigen::Index>(a));
    return s;
  };

  while (summary.iterations < max_iterations) {
    const Eigen::VectorXd gradient = rhs - gram * *x;  // negative gradient of 1/2 ||Ax - b||^2
    Eigen::Index best = -1;
    for (Eigen::Index i = 0; i < n; ++i) {
      if (!passive[static_cast<std::size_t>(i)] && gradient(i) > tolerance &&
          (best < 0 || gradient(i) > gradient(best))) {
        best = i;
      }
    }
    if (best < 0) {
      converged = true;
      break;
    }
    passive[static_cast<std::size_t>(best)] = true;
    ++summary.iterations;
    for (;;) {
      const Eigen::VectorXd s = solve_passive();
      double alpha = 1.0;
      bool feasible = true;
      for (Eigen::Index i = 0; i < n; ++i) {
        if (passive[static_cast<std::size_t>(i)] && s(i) <= 0.0) {
          feasible = false;
          alpha = std::min(alpha, (*x)(i) / ((*x)(i) - s(i)));
        }
      }
      if (feasible) {
        *x = s;
        break;
      }
      // Step towards s until the first passive entry hits zero, then release it.
      *x += alpha * (s - *x);
      for (Eigen::Index i = 0; i < n; ++i) {
        if (passive[static_cast<std::size_t>(i)] && (*x)(i) <= tolerance) {
          passive[static_cast<std::size_t>(i)] = false;
          (*x)(i) = 0.0;
        }
      }
    }
  }
  for (Eigen::Index i = 0; i < n; ++i) summary.active_count += (*x)(i) > 0.0 ? 1 : 0;
  if (converged) {
    summary.End(solvers::core::Termination::kSuccess, "");
  } else {
    summary.End(solvers::core::Termination::kNoConvergence,
                "iteration limit (" + std::to_string(max_iterations) + ") reached before the optimality conditions held");
  }
  timer.Finish(&summary);
  return summary;
}

NnlsSummary SolveNnls(const Eigen::MatrixXd& a, const Eigen::VectorXd& b, Eigen::VectorXd* x,
                      const NnlsOptions& options) {
  if (a.rows() != b.size()) {
    NnlsSummary summary;
    summary.End(solvers::core::Termination::kInvalidInput, "A has " + std::to_string(a.rows()) + " rows, b " +
                                                         std::to_string(b.size()) + " entries");
    return summary;
  }
  return SolveNnlsNormal(a.transpose() * a, a.transpose() * b, x, options);
}

}  // namespace photorig::solvers::lighting
