#pragma once
// What the Lambertian lane fitters (trimmed_lambertian_fit, irls_lambertian_fit)
// share: the lights as plain arrays for their kernels, and each lane's
// weighted 3 x 3 normal equations.

#include "lane_math.h"

#include <Eigen/Core>

#include <vector>

namespace photorig::solvers::ps::internal {

// w_k as three doubles per light, for kernels that use no Eigen.
inline std::vector<double> DirectionArray(const std::vector<Eigen::Vector3d>& light_directions) {
  std::vector<double> directions;
  directions.reserve(3 * light_directions.size());
  for (const Eigen::Vector3d& w : light_directions) directions.insert(directions.end(), {w.x(), w.y(), w.z()});
  return directions;
}

// Weighted normal equations of each lane: sum c w w^T (xx, xy, xz, yy, yz,
// zz) and sum c b w.
struct alignas(64) LaneNormalEquations {
  double matrix[6][kLanes];
  double rhs[3][kLanes];
};

// Adds sample (w, b) with weight c to lane j; inlined into the lane loops,
// which keep a local LaneNormalEquations in registers.
PHOTORIG_LANE_INLINE void AddSample(LaneNormalEquations& sums, int j, double c, double b, double wx, double wy,
                                    double wz) {
  sums.matrix[0][j] += c * wx * wx, sums.matrix[1][j] += c * wx * wy, sums.matrix[2][j] += c * wx * wz;
  sums.matrix[3][j] += c * wy * wy, sums.matrix[4][j] += c * wy * wz, sums.matrix[5][j] += c * wz * wz;
  sums.rhs[0][j] += c * b * wx, sums.rhs[1][j] += c * b * wy, sums.rhs[2][j] += c * b * wz;
}

}  // namespace photorig::solvers::ps::internal
