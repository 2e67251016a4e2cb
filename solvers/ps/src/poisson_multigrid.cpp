#include "poisson_multigrid.h"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace photorig::solvers::ps::internal {
namespace {

// Jacobi's damping: 4/5 damps the high half of the 5-point Laplacian's
// spectrum best. Two sweeps before the coarse correction and two after.
constexpr double kJacobiDamping = 0.8;
constexpr int kSweeps = 2;
// The doubled coarse correction (see the header).
constexpr double kOverCorrection = 2.0;
// The preconditioner's pull of each pixel towards 0, so that its levels are
// nonsingular; far below any pair's weight of 1, and each region's mean is
// removed from what it returns anyway.
constexpr double kShift = 1e-9;
// Grids smaller than this run their loops on one thread: a parallel region
// costs more than the pass.
constexpr int kParallelCells = 1 << 16;

}  // namespace

// One level's grid, padded by a ring of empty cells so that every stencil
// reads its four neighbours without a test: cell (r, c) is at
// (r + 1) * stride + c + 1. Weights and degrees are small integers, exact in float.
struct PoissonMultigrid::Level {
  int rows = 0, cols = 0, stride = 0;
  std::vector<float> right, down;  // weight to the cell at c + 1, at r + 1
  std::vector<float> degree;       // sum of the cell's weights
  std::vector<float> pixels;       // mask pixels merged into the cell (0: empty)
  std::vector<float> inverse_diagonal;  // 1 / (degree + kShift pixels), 0 for an empty cell
  std::vector<double> x, b, r;
  std::size_t size() const { return static_cast<std::size_t>(rows + 2) * stride; }
  int At(int r, int c) const { return (r + 1) * stride + c + 1; }
  bool parallel() const { return rows * cols >= kParallelCells; }
};

struct PoissonMultigrid::Coarsest {
  std::vector<int> unknown;  // cell -> unknown, -1 for an empty cell
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> factor;
  Eigen::VectorXd b;
};

PoissonMultigrid::PoissonMultigrid(const cv::Mat& mask) {
  Level fine;
  fine.rows = mask.rows, fine.cols = mask.cols, fine.stride = mask.cols + 2;
  fine.right.assign(fine.size(), 0.0f), fine.down.assign(fine.size(), 0.0f), fine.pixels.assign(fine.size(), 0.0f);
  for (int r = 0; r < mask.rows; ++r)
    for (int c = 0; c < mask.cols; ++c) {
      if (!mask.at<std::uint8_t>(r, c)) continue;
      const int i = fine.At(r, c);
      fine.pixels[i] = 1.0f;
      fine.right[i] = c + 1 < mask.cols && mask.at<std::uint8_t>(r, c + 1) ? 1.0f : 0.0f;
      fine.down[i] = r + 1 < mask.rows && mask.at<std::uint8_t>(r + 1, c) ? 1.0f : 0.0f;
    }
  levels_.push_back(std::move(fine));
  auto unknowns = [](const Level& level) {
    return std::count_if(level.pixels.begin(), level.pixels.end(), [](float p) { return p > 0.0f; });
  };
  while (unknowns(levels_.back()) > kCoarsestUnknowns) {
    const Level& f = levels_.back();
    Level coarse;
    coarse.rows = (f.rows + 1) / 2, coarse.cols = (f.cols + 1) / 2, coarse.stride = coarse.cols + 2;
    coarse.right.assign(coarse.size(), 0.0f), coarse.down.assign(coarse.size(), 0.0f);
    coarse.pixels.assign(coarse.size(), 0.0f);
    for (int r = 0; r < f.rows; ++r)
      for (int c = 0; c < f.cols; ++c) {
        const int i = f.At(r, c), parent = coarse.At(r / 2, c / 2);
        coarse.pixels[parent] += f.pixels[i];
        // Pairs inside a 2 x 2 block vanish from P^T L P; those leaving it join two coarse cells.
        if (c % 2 == 1) coarse.right[parent] += f.right[i];
        if (r % 2 == 1) coarse.down[parent] += f.down[i];
      }
    levels_.push_back(std::move(coarse));
  }
  for (Level& level : levels_) {
    level.degree.assign(level.size(), 0.0f), level.inverse_diagonal.assign(level.size(), 0.0f);
    for (int r = 0; r < level.rows; ++r)
      for (int c = 0; c < level.cols; ++c) {
        const int i = level.At(r, c);
        level.degree[i] = level.right[i] + level.right[i - 1] + level.down[i] + level.down[i - level.stride];
        if (level.pixels[i] > 0.0f)
          level.inverse_diagonal[i] = static_cast<float>(1.0 / (level.degree[i] + kShift * level.pixels[i]));
      }
    level.x.assign(level.size(), 0.0), level.b.assign(level.size(), 0.0), level.r.assign(level.size(), 0.0);
  }
  const Level& last = levels_.back();
  coarsest_ = std::make_unique<Coarsest>();
  coarsest_->unknown.assign(last.size(), -1);
  int n = 0;
  for (std::size_t i = 0; i < last.size(); ++i)
    if (last.pixels[i] > 0.0f) coarsest_->unknown[i] = n++;
  std::vector<Eigen::Triplet<double>> triplets;
  for (std::size_t i = 0; i < last.size(); ++i) {
    const int a = coarsest_->unknown[i];
    if (a < 0) continue;
    triplets.emplace_back(a, a, last.degree[i] + kShift * last.pixels[i]);
    if (last.right[i] > 0.0f) triplets.emplace_back(coarsest_->unknown[i + 1], a, -last.right[i]);
    if (last.down[i] > 0.0f) triplets.emplace_back(coarsest_->unknown[i + last.stride], a, -last.down[i]);
  }
  Eigen::SparseMatrix<double> matrix(n, n);
  matrix.setFromTriplets(triplets.begin(), triplets.end());  // lower triangle: the partner's index is larger
  coarsest_->factor.compute(matrix);
  coarsest_->b.resize(n);

  cv::Mat labels;
  regions_ = cv::connectedComponents(mask, labels, 4, CV_32S);
  region_.assign(levels_[0].size(), -1);
  region_count_.assign(regions_, 0.0);
  for (int r = 0; r < mask.rows; ++r)
    for (int c = 0; c < mask.cols; ++c)
      if (mask.at<std::uint8_t>(r, c)) {
        const int label = labels.at<int>(r, c);
        region_[levels_[0].At(r, c)] = label;
        region_count_[label] += 1.0;
      }
}

PoissonMultigrid::~PoissonMultigrid() = default;

void PoissonMultigrid::Apply(int k, const double* x, double* y, bool shifted) const {
  const Level& l = levels_[k];
  const int stride = l.stride;
  const float *right = l.right.data(), *down = l.down.data(), *degree = l.degree.data(), *pixels = l.pixels.data();
  const double shift = shifted ? kShift : 0.0;
#pragma omp parallel for schedule(static) if (l.parallel())
  for (int r = 0; r < l.rows; ++r) {
    const int first = l.At(r, 0);
#pragma omp simd
    for (int i = first; i < first + l.cols; ++i)
      y[i] = (degree[i] + shift * pixels[i]) * x[i] - right[i] * x[i + 1] - right[i - 1] * x[i - 1] -
             down[i] * x[i + stride] - down[i - stride] * x[i - stride];
  }
}

void PoissonMultigrid::Cycle(int k) {
  Level& l = levels_[k];
  if (k + 1 == static_cast<int>(levels_.size())) {
    for (std::size_t i = 0; i < l.size(); ++i)
      if (coarsest_->unknown[i] >= 0) coarsest_->b[coarsest_->unknown[i]] = l.b[i];
    const Eigen::VectorXd solution = coarsest_->factor.solve(coarsest_->b);
    for (std::size_t i = 0; i < l.size(); ++i) l.x[i] = coarsest_->unknown[i] >= 0 ? solution[coarsest_->unknown[i]] : 0.0;
    return;
  }
  double *x = l.x.data(), *r = l.r.data();
  const double* b = l.b.data();
  const float* inverse_diagonal = l.inverse_diagonal.data();
  // x += w D^-1 (b - L x), from x = 0; `residual` ends with r = b - L x.
  auto sweep = [&](bool from_zero) {
    if (!from_zero) Apply(k, x, r, true);
#pragma omp parallel for schedule(static) if (l.parallel())
    for (int row = 0; row < l.rows; ++row) {
      const int first = l.At(row, 0);
#pragma omp simd
      for (int i = first; i < first + l.cols; ++i)
        x[i] = (from_zero ? 0.0 : x[i]) + kJacobiDamping * inverse_diagonal[i] * (b[i] - (from_zero ? 0.0 : r[i]));
    }
  };
  for (int s = 0; s < kSweeps; ++s) sweep(s == 0);
  Apply(k, x, r, true);
  Level& coarse = levels_[k + 1];
#pragma omp parallel for schedule(static) if (coarse.parallel())
  for (int row = 0; row < coarse.rows; ++row)
    for (int c = 0; c < coarse.cols; ++c) {
      // The 2 x 2 children's residuals; a child past the fine grid's last row
      // or column is its padding, whose b and r are 0.
      const int i = l.At(2 * row, 2 * c);
      coarse.b[coarse.At(row, c)] =
          (b[i] - r[i]) + (b[i + 1] - r[i + 1]) + (b[i + l.stride] - r[i + l.stride]) + (b[i + l.stride + 1] - r[i + l.stride + 1]);
    }
  Cycle(k + 1);
  const double* correction = coarse.x.data();
  const float* pixels = l.pixels.data();
#pragma omp parallel for schedule(static) if (l.parallel())
  for (int row = 0; row < l.rows; ++row)
    for (int c = 0; c < l.cols; ++c) {
      const int i = l.At(row, c);
      x[i] += pixels[i] > 0.0f ? kOverCorrection * correction[coarse.At(row / 2, c / 2)] : 0.0;
    }
  for (int s = 0; s < kSweeps; ++s) sweep(false);
}

void PoissonMultigrid::Project(double* v) const {
  std::vector<double> sum(regions_, 0.0);
  const std::size_t size = levels_[0].size();
  for (std::size_t i = 0; i < size; ++i)
    if (region_[i] >= 0) sum[region_[i]] += v[i];
  for (int g = 0; g < regions_; ++g) sum[g] = region_count_[g] > 0.0 ? sum[g] / region_count_[g] : 0.0;
  for (std::size_t i = 0; i < size; ++i) v[i] = region_[i] >= 0 ? v[i] - sum[region_[i]] : 0.0;
}

double PoissonMultigrid::Dot(const double* a, const double* b) const {
  const Level& l = levels_[0];
  std::vector<double> rows(l.rows, 0.0);
#pragma omp parallel for schedule(static) if (l.parallel())
  for (int r = 0; r < l.rows; ++r) {
    const int first = l.At(r, 0);
    double s = 0.0;
#pragma omp simd reduction(+ : s)
    for (int i = first; i < first + l.cols; ++i) s += a[i] * b[i];
    rows[r] = s;
  }
  double total = 0.0;
  for (const double s : rows) total += s;
  return total;
}

PoissonMultigrid::Result PoissonMultigrid::Solve(const cv::Mat& rhs, double relative_tolerance, int max_iterations,
                                                 cv::Mat* z) {
  Level& fine = levels_[0];
  const std::size_t size = fine.size();
  for (std::vector<double>* v : {&b_, &x_, &r_, &p_, &q_}) v->assign(size, 0.0);
  std::vector<double> &b = b_, &x = x_, &r = r_, &p = p_, &q = q_;
  for (int row = 0; row < fine.rows; ++row)
    for (int c = 0; c < fine.cols; ++c) b[fine.At(row, c)] = rhs.at<double>(row, c);
  Project(b.data());
  Result result;
  const double b_norm = std::sqrt(Dot(b.data(), b.data()));
  r = b;
  // z_k = M r_k: one V-cycle, its regions' means removed.
  auto precondition = [&] {
    std::copy(r.begin(), r.end(), fine.b.begin());
    Cycle(0);
    Project(fine.x.data());
  };
  if (b_norm > 0.0) {
    precondition();
    p = fine.x;
    double rz = Dot(r.data(), fine.x.data());
    while (result.iterations < max_iterations) {
      Apply(0, p.data(), q.data(), false);
      const double step = rz / Dot(p.data(), q.data());
#pragma omp parallel for simd schedule(static) if (fine.parallel())
      for (std::size_t i = 0; i < size; ++i) x[i] += step * p[i], r[i] -= step * q[i];
      ++result.iterations;
      result.relative_residual = std::sqrt(Dot(r.data(), r.data())) / b_norm;
      if (!(result.relative_residual > relative_tolerance)) break;
      precondition();
      const double rz_next = Dot(r.data(), fine.x.data());
      const double beta = rz_next / rz;
      rz = rz_next;
#pragma omp parallel for simd schedule(static) if (fine.parallel())
      for (std::size_t i = 0; i < size; ++i) p[i] = fine.x[i] + beta * p[i];
    }
  }
  result.converged = result.relative_residual <= relative_tolerance;
  Project(x.data());
  z->create(fine.rows, fine.cols, CV_64F);
  for (int row = 0; row < fine.rows; ++row)
    for (int c = 0; c < fine.cols; ++c) z->at<double>(row, c) = x[fine.At(row, c)];
  return result;
}

}  // namespace photorig::solvers::ps::internal
