#pragma once
// Building blocks of the SIMD kernels: multi-versioning, the log and exp of
// core/lane_math.h for loops that run one pixel per SIMD lane, and the queue
// that hands pixels to lanes.

#include "photorig/solvers/core/lane_math.h"

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
