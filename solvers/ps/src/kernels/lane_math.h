#pragma once
// Building blocks of the SIMD kernels: multi-versioning, the log and exp of
// core/lane_math.h for loops that run one pixel per SIMD lane, and the queue
// that hands pixels to lanes.

#include "photorig/solvers/core/lane_math.h"

#include <cmath>

namespace photorig::solvers::ps::internal {

using core::Horner;
using core::kLn2Hi;
using core::kLn2HiF;
using core::kLn2Lo;
using core::kLn2LoF;
using core::LaneExp;
using core::LaneLogAndInverse;

// The hot loops are multi-versioned (PHOTORIG_LANE_MULTIVERSION): the
// library itself stays at the baseline ISA (see CMakeLists.txt).
#define PHOTORIG_PS_MULTIVERSION PHOTORIG_LANE_MULTIVERSION

// Pixels per lane kernel pass: one AVX-512 register of doubles, two of AVX2;
// kFloatLanes for the kernels that run in float.
inline constexpr int kLanes = 8;
inline constexpr int kFloatLanes = 16;

template <typename T>
struct TangentPair {
  T t1[3], t2[3];
};

// A tangent basis for a unit normal, continuous everywhere but on n_z = -1
// (Duff et al. 2017): branch-free, so it also runs in lanes (double or float).
// Returned by value: GCC 12 leaves an `omp simd` loop scalar if it declares
// a local array (the result arrays this once wrote into).
template <typename T>
PHOTORIG_LANE_INLINE TangentPair<T> TangentBasis(T nx, T ny, T nz) {
  const T sign = std::copysign(T(1), nz);
  const T a = T(-1) / (sign + nz);
  const T b = nx * ny * a;
  return {{T(1) + sign * nx * nx * a, sign * b, -sign * nx}, {b, sign + ny * ny * a, -ny}};
}

// Levenberg-Marquardt's proposals across lanes: propose() fills positive[lane]
// (0 where the lane's damped matrix is not positive definite); each stepping
// lane without one raises its damping fourfold and all propose again, until
// every stepping lane has one or its damping reaches 1e12 (then it stops
// stepping and finish(lane): no step is left to try).
template <int kCount, typename Propose, typename Finish>
void ProposeWhilePositiveDefinite(bool* stepping, double* lambda, const double* positive, const Propose& propose,
                                  const Finish& finish) {
  for (bool retry = true; retry;) {
    propose();
    retry = false;
    for (int lane = 0; lane < kCount; ++lane) {
      if (!stepping[lane] || positive[lane] != 0.0) continue;
      lambda[lane] *= 4.0;
      if (lambda[lane] < 1e12) {
        retry = true;
      } else {
        stepping[lane] = false;
        finish(lane);
      }
    }
  }
}

// Problems handed to lanes in order: a lane keeps its problem until it is
// done, then takes the next at once; `busy` counts the lanes with a problem.
class LaneQueue {
 public:
  explicit LaneQueue(int count, int lanes = kLanes) : count_(count), busy_(lanes) {}
  int busy() const { return busy_; }
  // Gives the lane the next problem, load(lane, index) and problem[lane] =
  // index, or idles it, idle(lane) and problem[lane] = -1.
  template <typename Load, typename Idle>
  void Refill(int lane, int* problem, const Load& load, const Idle& idle) {
    if (next_ < count_) {
      problem[lane] = next_;
      load(lane, next_++);
    } else {
      problem[lane] = -1;
      idle(lane);
      --busy_;
    }
  }

 private:
  int count_, next_ = 0, busy_;
};

}  // namespace photorig::solvers::ps::internal
