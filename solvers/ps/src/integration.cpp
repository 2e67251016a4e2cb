#include "photorig/solvers/ps/integration.h"

#include "poisson_multigrid.h"

#include <Eigen/Core>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <limits>
#include <vector>

namespace photorig::solvers::ps {

struct IntegrationWorkspace::Factorisation {
  cv::Mat mask;  // the pixels factored for
  // Up to PoissonMultigrid::kCoarsestUnknowns pixels, the normal matrix is
  // factored (index: CV_32S, each pixel's unknown, -1 off the mask); above,
  // a multigrid-preconditioned iteration solves it on the pixel grid.
  cv::Mat index;
  int unknowns = 0;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
  std::unique_ptr<internal::PoissonMultigrid> multigrid;
  bool factored = false;
  int reuses = 0;
};

IntegrationWorkspace::IntegrationWorkspace() : factorisation_(std::make_unique<Factorisation>()) {}
IntegrationWorkspace::~IntegrationWorkspace() = default;
IntegrationWorkspace::IntegrationWorkspace(IntegrationWorkspace&&) noexcept = default;
IntegrationWorkspace& IntegrationWorkspace::operator=(IntegrationWorkspace&&) noexcept = default;
int IntegrationWorkspace::reuses() const { return factorisation_->reuses; }
IntegrationWorkspace::Factorisation& FactorisationOf(IntegrationWorkspace& workspace) { return *workspace.factorisation_; }

namespace {

struct Gradients {
  cv::Mat dzdx, dzdy;  // CV_64F, per pixel, depth units per pixel
  cv::Mat mask;        // CV_8U, pixels with a usable gradient
  std::size_t dropped = 0;
};

// The gradient field of every masked pixel with a finite normal: `slope`
// turns a normal into the integrand's change per column step and per step of
// +y (one row up), or refuses one too close to grazing.
template <typename Slope>
Gradients ComputeGradients(const cv::Mat& normals, const cv::Mat& mask, Slope slope) {
  Gradients g;
  g.dzdx = cv::Mat::zeros(normals.size(), CV_64F);
  g.dzdy = cv::Mat::zeros(normals.size(), CV_64F);
  g.mask = cv::Mat::zeros(normals.size(), CV_8U);
  for (int r = 0; r < normals.rows; ++r)
    for (int c = 0; c < normals.cols; ++c) {
      if (!mask.empty() && mask.at<std::uint8_t>(r, c) == 0) continue;
      const cv::Vec3f n = normals.at<cv::Vec3f>(r, c);
      if (!std::isfinite(n[0]) || !std::isfinite(n[1]) || !std::isfinite(n[2])) continue;
      if (!slope(r, c, n, &g.dzdx.at<double>(r, c), &g.dzdy.at<double>(r, c))) {
        ++g.dropped;
        continue;
      }
      g.mask.at<std::uint8_t>(r, c) = 255;
    }
  return g;
}

Gradients OrthographicGradients(const IntegrationOptions& options, const cv::Mat& normals, const cv::Mat& mask) {
  return ComputeGradients(normals, mask, [&options](int, int, const cv::Vec3f& n, double* dx, double* dy) {
    if (n[2] < options.min_normal_z) return false;
    *dx = -n[0] / n[2] * options.pixel_pitch;
    *dy = -n[1] / n[2] * options.pixel_pitch;
    return true;
  });
}

// Under a pinhole camera the point of pixel (r, c) is C + s (a, b, -1), s its
// distance along the axis and (a, b) the pixel's ray, so a normal n gives
//   d(ln s)/dc = (n_x a_c + n_y b_c) / (n_z - n_x a - n_y b)
// (likewise per row): the log of the distance is integrable like a height,
// and the unknown constant becomes a scale (Durou et al., "Integrating the
// normal field of a surface in the presence of discontinuities").
Gradients PerspectiveGradients(const IntegrationOptions& options, const camera::PixelRays& rays, const cv::Mat& normals,
                               const cv::Mat& mask) {
  const int rows = normals.rows, cols = normals.cols;
  auto ray = [&rays](int r, int c) -> Eigen::Vector2d { return -rays.Slope(r, c); };  // (a, b)
  return ComputeGradients(normals, mask, [&](int r, int c, const cv::Vec3f& n, double* dx, double* dy) {
    const Eigen::Vector2d ab = ray(r, c);
    const double facing = n[2] - n[0] * ab.x() - n[1] * ab.y();  // n . (-a, -b, 1): towards the camera
    if (facing < options.min_normal_z * std::sqrt(1.0 + ab.squaredNorm())) return false;
    // The ray's change per column and per row, from the neighbours (exact
    // for an undistorted lens, whose rays are linear in the pixel).
    const int c0 = std::max(c - 1, 0), c1 = std::min(c + 1, cols - 1);
    const int r0 = std::max(r - 1, 0), r1 = std::min(r + 1, rows - 1);
    const Eigen::Vector2d per_column = (ray(r, c1) - ray(r, c0)) / std::max(c1 - c0, 1);
    const Eigen::Vector2d per_row = (ray(r1, c) - ray(r0, c)) / std::max(r1 - r0, 1);
    *dx = (n[0] * per_column.x() + n[1] * per_column.y()) / facing;
    // dzdy is per step of +y, one row up: minus the per-row change.
    *dy = -(n[0] * per_row.x() + n[1] * per_row.y()) / facing;
    return true;
  });
}

// Calls visit(a, b, d) for each pair of 4-neighbours in g's mask, a the
// pixel and b its right or lower neighbour, with d the depth difference
// z_b - z_a the gradient asks for (trapezoidal: the mean of the two pixels'
// slopes). One equation each.
template <typename Visit>
void ForEachPair(const Gradients& g, Visit visit) {
  const cv::Mat& mask = g.mask;
  for (int r = 0; r < mask.rows; ++r)
    for (int c = 0; c < mask.cols; ++c) {
      if (!mask.at<std::uint8_t>(r, c)) continue;
      if (c + 1 < mask.cols && mask.at<std::uint8_t>(r, c + 1))
        visit(cv::Point(c, r), cv::Point(c + 1, r), 0.5 * (g.dzdx.at<double>(r, c) + g.dzdx.at<double>(r, c + 1)));
      // One row down is one step of -y.
      if (r + 1 < mask.rows && mask.at<std::uint8_t>(r + 1, c))
        visit(cv::Point(c, r), cv::Point(c, r + 1), -0.5 * (g.dzdy.at<double>(r, c) + g.dzdy.at<double>(r + 1, c)));
    }
}

// Residual of the integrated depth against the gradient on every neighbour pair inside the mask.
double ResidualRms(const Gradients& g, const cv::Mat& depth) {
  double sum = 0.0;
  std::size_t count = 0;
  ForEachPair(g, [&](cv::Point a, cv::Point b, double d) {
    const double e = (depth.at<float>(b) - depth.at<float>(a)) - d;
    sum += e * e, ++count;
  });
  return count ? std::sqrt(sum / count) : 0.0;
}

// Subtracts each connected region's mean depth.
void CentreRegions(const cv::Mat& mask, cv::Mat* depth) {
  cv::Mat labels;
  const int regions = cv::connectedComponents(mask, labels, 4, CV_32S);
  std::vector<double> sum(regions, 0.0);
  std::vector<std::size_t> count(regions, 0);
  for (int r = 0; r < mask.rows; ++r)
    for (int c = 0; c < mask.cols; ++c)
      if (mask.at<std::uint8_t>(r, c)) sum[labels.at<int>(r, c)] += depth->at<float>(r, c), ++count[labels.at<int>(r, c)];
  for (int r = 0; r < mask.rows; ++r)
    for (int c = 0; c < mask.cols; ++c) {
      if (mask.at<std::uint8_t>(r, c))
        depth->at<float>(r, c) -= static_cast<float>(sum[labels.at<int>(r, c)] / count[labels.at<int>(r, c)]);
      else
        depth->at<float>(r, c) = std::numeric_limits<float>::quiet_NaN();
    }
}

void FrankotChellappa(const Gradients& g, cv::Mat* depth) {
  const int rows = g.dzdx.rows, cols = g.dzdx.cols;
  // Image rows run down: the row-direction derivative is -dz/dy.
  cv::Mat p = g.dzdx, q = -g.dzdy;
  cv::Mat planes_p[] = {p.clone(), cv::Mat::zeros(p.size(), CV_64F)};
  cv::Mat planes_q[] = {q.clone(), cv::Mat::zeros(q.size(), CV_64F)};
  cv::Mat fp, fq;
  cv::merge(planes_p, 2, fp);
  cv::merge(planes_q, 2, fq);
  cv::dft(fp, fp);
  cv::dft(fq, fq);
  cv::Mat fz(rows, cols, CV_64FC2);
  for (int r = 0; r < rows; ++r) {
    const double v = 2.0 * M_PI * (r <= rows / 2 ? r : r - rows) / rows;
    for (int c = 0; c < cols; ++c) {
      const double u = 2.0 * M_PI * (c <= cols / 2 ? c : c - cols) / cols;
      const double denominator = u * u + v * v;
      if (denominator == 0.0) {
        fz.at<cv::Vec2d>(r, c) = cv::Vec2d(0, 0);
        continue;
      }
      // Z = (-j u P - j v Q) / (u^2 + v^2)
      const cv::Vec2d P = fp.at<cv::Vec2d>(r, c), Q = fq.at<cv::Vec2d>(r, c);
      const double real = (u * P[1] + v * Q[1]) / denominator;
      const double imag = (-u * P[0] - v * Q[0]) / denominator;
      fz.at<cv::Vec2d>(r, c) = cv::Vec2d(real, imag);
    }
  }
  cv::Mat z;
  cv::dft(fz, z, cv::DFT_INVERSE | cv::DFT_SCALE | cv::DFT_REAL_OUTPUT);
  z.convertTo(*depth, CV_32F);
}

// The normal matrix A^T A of the pairs' equations for `mask`: per pair +1 on
// both diagonals and -1 off them (the 5-point Laplacian of the mask,
// assembled directly rather than as a sparse product), factored, or its
// multigrid levels built.
bool Factor(const cv::Mat& mask, IntegrationWorkspace::Factorisation* f, std::string* message) {
  const int rows = mask.rows, cols = mask.cols;
  f->mask = mask.clone();
  f->unknowns = cv::countNonZero(mask);
  if (f->unknowns > internal::PoissonMultigrid::kCoarsestUnknowns) {
    f->index.release();
    f->multigrid = std::make_unique<internal::PoissonMultigrid>(mask);
    f->factored = true;
    return true;
  }
  f->multigrid.reset();
  f->index.create(rows, cols, CV_32S);
  f->index.setTo(-1);
  int unknown = 0;
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c)
      if (mask.at<std::uint8_t>(r, c)) f->index.at<int>(r, c) = unknown++;
  std::vector<Eigen::Triplet<double>> triplets;
  // A tiny pull towards 0 fixes each region's free constant; CentreRegions then removes its effect.
  for (int i = 0; i < f->unknowns; ++i) triplets.emplace_back(i, i, 1e-9);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const int a = f->index.at<int>(r, c);
      if (a < 0) continue;
      for (const int b : {c + 1 < cols ? f->index.at<int>(r, c + 1) : -1, r + 1 < rows ? f->index.at<int>(r + 1, c) : -1}) {
        if (b < 0) continue;
        triplets.emplace_back(a, a, 1.0);  // the lower triangle: index b > a
        triplets.emplace_back(b, b, 1.0);
        triplets.emplace_back(b, a, -1.0);
      }
    }
  Eigen::SparseMatrix<double> normal(f->unknowns, f->unknowns);
  normal.setFromTriplets(triplets.begin(), triplets.end());
  f->solver.compute(normal);
  f->factored = f->solver.info() == Eigen::Success;
  if (!f->factored) *message = "sparse factorisation failed";
  return f->factored;
}

// The iteration stops where the residual of the normal equations is this
// fraction of their right-hand side: the depth then differs from the
// factored solution by under 1e-6 of its range (test_integration), far
// below what float depth maps hold. Multigrid takes about ten iterations to
// get there on any size; a hundred means the preconditioner failed.
constexpr double kPoissonRelativeResidual = 1e-10;
constexpr int kPoissonMaxIterations = 100;

bool Poisson(const Gradients& g, cv::Mat* depth, std::string* message, IntegrationWorkspace::Factorisation* f,
             int* iterations) {
  const bool same_pixels = f->factored && f->mask.size() == g.mask.size() && cv::countNonZero(f->mask != g.mask) == 0;
  if (same_pixels)
    ++f->reuses;
  else if (!Factor(g.mask, f, message))
    return false;
  depth->create(g.mask.size(), CV_32F);
  if (f->multigrid) {
    // A^T d on the pixel grid: each pair's d to +b and -a.
    cv::Mat rhs = cv::Mat::zeros(g.mask.size(), CV_64F), z;
    ForEachPair(g, [&rhs](cv::Point a, cv::Point b, double d) { rhs.at<double>(b) += d, rhs.at<double>(a) -= d; });
    const internal::PoissonMultigrid::Result solved =
        f->multigrid->Solve(rhs, kPoissonRelativeResidual, kPoissonMaxIterations, &z);
    *iterations = solved.iterations;
    if (!solved.converged) {
      *message = "the Poisson equations did not converge in " + std::to_string(solved.iterations) +
                 " iterations (relative residual " + std::to_string(solved.relative_residual) +
                 "); integrate with --integrator frankot-chellappa, or in blocks (block_px > 1)";
      return false;
    }
    z.convertTo(*depth, CV_32F);
    return true;
  }
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(f->unknowns);
  ForEachPair(g, [&](cv::Point a, cv::Point b, double d) {
    rhs[f->index.at<int>(b)] += d, rhs[f->index.at<int>(a)] -= d;
  });
  const Eigen::VectorXd z = f->solver.solve(rhs);
  depth->setTo(0.0f);
  for (int r = 0; r < depth->rows; ++r)
    for (int c = 0; c < depth->cols; ++c)
      if (const int i = f->index.at<int>(r, c); i >= 0) depth->at<float>(r, c) = static_cast<float>(z[i]);
  return true;
}

// The gradient field on blocks of block x block pixels: each block's mean
// slope over its usable pixels, per step of one block. A block enters when a
// quarter of its pixels are usable, so the rim's few pixels do not carry it.
Gradients BlockGradients(const Gradients& g, int block) {
  const int rows = (g.mask.rows + block - 1) / block, cols = (g.mask.cols + block - 1) / block;
  Gradients coarse;
  coarse.dzdx = cv::Mat::zeros(rows, cols, CV_64F);
  coarse.dzdy = cv::Mat::zeros(rows, cols, CV_64F);
  coarse.mask = cv::Mat::zeros(rows, cols, CV_8U);
  cv::Mat count = cv::Mat::zeros(rows, cols, CV_32S);
  for (int r = 0; r < g.mask.rows; ++r)
    for (int c = 0; c < g.mask.cols; ++c)
      if (g.mask.at<std::uint8_t>(r, c)) {
        coarse.dzdx.at<double>(r / block, c / block) += g.dzdx.at<double>(r, c);
        coarse.dzdy.at<double>(r / block, c / block) += g.dzdy.at<double>(r, c);
        ++count.at<int>(r / block, c / block);
      }
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const int n = count.at<int>(r, c);
      if (4 * n < block * block) continue;
      coarse.dzdx.at<double>(r, c) *= static_cast<double>(block) / n;
      coarse.dzdy.at<double>(r, c) *= static_cast<double>(block) / n;
      coarse.mask.at<std::uint8_t>(r, c) = 255;
    }
  return coarse;
}

// The blocks' depths at every pixel of *mask, bilinear between the centres
// of the solved blocks around it (their weights renormalised); a pixel with
// none around is taken out of *mask.
void InterpolateBlocks(const cv::Mat& coarse, const cv::Mat& coarse_mask, int block, cv::Mat* mask, cv::Mat* depth) {
  depth->create(mask->size(), CV_32F);
  depth->setTo(0.0f);
  for (int r = 0; r < mask->rows; ++r)
    for (int c = 0; c < mask->cols; ++c) {
      if (!mask->at<std::uint8_t>(r, c)) continue;
      const double v = (r + 0.5) / block - 0.5, u = (c + 0.5) / block - 0.5;
      const int r0 = static_cast<int>(std::floor(v)), c0 = static_cast<int>(std::floor(u));
      const double fv = v - r0, fu = u - c0;
      double sum = 0.0, weight = 0.0;
      for (int dr = 0; dr < 2; ++dr)
        for (int dc = 0; dc < 2; ++dc) {
          const int rr = r0 + dr, cc = c0 + dc;
          if (rr < 0 || cc < 0 || rr >= coarse.rows || cc >= coarse.cols || !coarse_mask.at<std::uint8_t>(rr, cc))
            continue;
          // + 1e-12: a solved block of weight 0 still stands in for an unsolved one.
          const double w = (dr ? fv : 1.0 - fv) * (dc ? fu : 1.0 - fu) + 1e-12;
          sum += w * coarse.at<float>(rr, cc);
          weight += w;
        }
      if (weight > 0.0)
        depth->at<float>(r, c) = static_cast<float>(sum / weight);
      else
        mask->at<std::uint8_t>(r, c) = 0;
    }
}

}  // namespace

bool IntegrationOptions::IsValid(std::string* why) const {
  if (!(pixel_pitch > 0.0)) {
    if (why) *why = "pixel_pitch must be > 0";
    return false;
  }
  if (!(min_normal_z > 0.0 && min_normal_z < 1.0)) {
    if (why) *why = "min_normal_z must be in (0, 1)";
    return false;
  }
  if (block_px < 1 || block_px > 64) {
    if (why) *why = "block_px must be within [1, 64]";
    return false;
  }
  return true;
}

namespace {

std::string CheckInputs(const cv::Mat& normals, const cv::Mat& mask) {
  if (normals.type() != CV_32FC3 || normals.empty()) return "normals must be a non-empty CV_32FC3 image";
  if (!mask.empty() && (mask.type() != CV_8U || mask.size() != normals.size()))
    return "the mask must be an 8-bit image of the normals' size";
  return {};
}

bool Solve(const IntegrationOptions& options, const Gradients& g, cv::Mat* depth, std::string* why,
           IntegrationWorkspace& workspace, int* iterations) {
  if (options.integrator == Integrator::kFrankotChellappa) {
    FrankotChellappa(g, depth);
    return true;
  }
  return Poisson(g, depth, why, &FactorisationOf(workspace), iterations);
}

// Integrates g into *depth (each region's mean 0).
void Integrate(const IntegrationOptions& options, Gradients g, solvers::core::SolveTimer& timer,
               IntegrationSummary* summary, cv::Mat* depth, IntegrationWorkspace* workspace) {
  IntegrationWorkspace local;
  IntegrationWorkspace& kept = workspace ? *workspace : local;
  summary->pixels_dropped = g.dropped;
  if (cv::countNonZero(g.mask) == 0) {
    summary->End(solvers::core::Termination::kFailure, "no pixel has a usable normal to integrate");
    return;
  }
  timer.SetupDone(summary);
  std::string why;
  if (options.block_px == 1) {
    if (!Solve(options, g, depth, &why, kept, &summary->iterations))
      return summary->End(solvers::core::Termination::kFailure, why);
  } else {
    const Gradients coarse = BlockGradients(g, options.block_px);
    cv::Mat coarse_depth;
    if (!Solve(options, coarse, &coarse_depth, &why, kept, &summary->iterations))
      return summary->End(solvers::core::Termination::kFailure, why);
    g.mask = g.mask.clone();
    InterpolateBlocks(coarse_depth, coarse.mask, options.block_px, &g.mask, depth);
  }
  summary->pixels = static_cast<std::size_t>(cv::countNonZero(g.mask));
  CentreRegions(g.mask, depth);
  summary->residual_rms = ResidualRms(g, *depth);
  summary->End(solvers::core::Termination::kSuccess, "");
}

}  // namespace

IntegrationSummary IntegrateNormals(const IntegrationOptions& options, const cv::Mat& normals, const cv::Mat& mask,
                                    cv::Mat* depth, IntegrationWorkspace* workspace) {
  solvers::core::SolveTimer timer;
  IntegrationSummary summary;
  if (solvers::core::EndIfInvalid(options, &summary) ||
      solvers::core::EndIfBadInput(CheckInputs(normals, mask), &summary))
    return summary;
  Integrate(options, OrthographicGradients(options, normals, mask), timer, &summary, depth, workspace);
  timer.Finish(&summary);
  return summary;
}

IntegrationSummary IntegrateNormalsPerspective(const IntegrationOptions& options, const camera::PixelRays& rays,
                                               const cv::Mat& normals, const cv::Mat& mask, cv::Mat* height_mm,
                                               IntegrationWorkspace* workspace) {
  solvers::core::SolveTimer timer;
  IntegrationSummary summary;
  std::string inputs = CheckInputs(normals, mask);
  if (inputs.empty() && !rays.camera().IsPinhole()) inputs = "perspective integration needs a pinhole camera's rays";
  if (inputs.empty() && (rays.camera().width_px != normals.cols || rays.camera().height_px != normals.rows))
    inputs = "the camera's image size differs from the normals'";
  if (solvers::core::EndIfInvalid(options, &summary) || solvers::core::EndIfBadInput(inputs, &summary)) return summary;
  cv::Mat log_distance;
  Integrate(options, PerspectiveGradients(options, rays, normals, mask), timer, &summary, &log_distance, workspace);
  if (summary.IsSolutionUsable()) {
    // Each region's mean log distance is 0: its geometric-mean distance from
    // the camera becomes the camera's distance, the object on the sample plane.
    const double d = rays.camera().pinhole.distance_mm;
    height_mm->create(normals.size(), CV_32F);
    for (int r = 0; r < normals.rows; ++r)
      for (int c = 0; c < normals.cols; ++c)
        height_mm->at<float>(r, c) = static_cast<float>(d - d * std::exp(double(log_distance.at<float>(r, c))));
    summary.residual_rms *= d;  // a change of log distance e moves the surface by about e d
  }
  timer.Finish(&summary);
  return summary;
}

}  // namespace photorig::solvers::ps
