#pragma once
// The masked Poisson equations of normal integration, L z = A^T d (L the
// graph Laplacian of the mask's 4-neighbour pairs), for masks too large to
// factor: a sparse Cholesky factor of L grows faster than the mask (6-9 s
// for a 1 MP disc), where conjugate gradients preconditioned by a multigrid
// V-cycle cost a few passes over the grid per iteration and take about ten.
//
// The V-cycle is aggregation multigrid on the pixel grid: each coarser level
// merges 2 x 2 cells, its operator is the Galerkin product P^T L P with P
// piecewise constant (again a weighted graph Laplacian: the weight between
// two cells is the number of fine pairs that join them), smoothing is
// damped Jacobi, and the coarsest level (at most kCoarsestUnknowns cells) is
// factored. The correction is doubled: a piecewise-constant interpolant of a
// smooth error has twice that error's energy on a grid (per coarse edge, two
// fine pairs each see the whole jump of 2h times the slope), so the Galerkin
// correction comes out half as large as the error it corrects (Braess's
// over-correction). Pre- and post-smoothing match, so the V-cycle is a
// symmetric preconditioner, as conjugate gradients need.
//
// L is singular: every 4-connected region of the mask has a free constant.
// The right-hand side sums to zero over each region (each pair adds +d and
// -d), and the iteration removes each region's mean from its residuals and
// its solution, so the constant stays fixed at a zero mean.

#include <opencv2/core.hpp>

#include <memory>
#include <vector>

namespace photorig::solvers::ps::internal {

class PoissonMultigrid {
 public:
  // Coarsening stops at this many cells or fewer, which are factored once
  // (a few milliseconds) and solved directly in every V-cycle (well under
  // one pass over a fine level of a million pixels).
  static constexpr int kCoarsestUnknowns = 4096;

  // mask: CV_8U; the unknowns are its nonzero pixels.
  explicit PoissonMultigrid(const cv::Mat& mask);
  ~PoissonMultigrid();

  struct Result {
    bool converged = false;
    int iterations = 0;
    double relative_residual = 0.0;  // |L z - b| / |b| after the last iteration
  };
  // rhs: CV_64F of the mask's size, b per pixel (0 off the mask). *z:
  // CV_64F, each region's mean 0, 0 off the mask. Stops when the residual
  // falls to relative_tolerance |b| or after max_iterations.
  Result Solve(const cv::Mat& rhs, double relative_tolerance, int max_iterations, cv::Mat* z);

 private:
  struct Level;
  struct Coarsest;

  // y = L x on level k (with the preconditioner's diagonal if shifted).
  void Apply(int k, const double* x, double* y, bool shifted) const;
  // One V-cycle on level k: levels_[k].x from levels_[k].b.
  void Cycle(int k);
  // Removes each region's mean from v (a level-0 grid).
  void Project(double* v) const;
  // Per-row partial sums, added in row order: the same answer on any number of threads.
  double Dot(const double* a, const double* b) const;

  std::vector<Level> levels_;
  std::unique_ptr<Coarsest> coarsest_;
  // The iteration's vectors on level 0's grid, kept between solves: a solve
  // on the same pixels then touches no fresh memory.
  std::vector<double> b_, x_, r_, p_, q_;
  std::vector<int> region_;  // level-0 cell -> its 4-connected region (-1 off the mask)
  std::vector<double> region_count_;
  int regions_ = 0;
};

}  // namespace photorig::solvers::ps::internal
