#pragma once
// Checks on a photometric-stereo solve's summary that every kind of solve shares.

#include "photorig/solvers/ps/summary.h"

#include <gtest/gtest.h>

namespace photorig::solvers::ps::testing {

// The solve's steps (tiles, steps 5-6, step 7) are non-negative parts of its
// solve_ms, beside other_ms spent elsewhere in it (near lights' depth_ms).
inline void ExpectStepsWithinSolve(const SolverSummary& summary, double other_ms = 0.0) {
  EXPECT_GT(summary.tiles_ms, 0.0);
  EXPECT_GE(summary.shared_lobe_ms, 0.0);
  EXPECT_GE(summary.low_frequency_ms, 0.0);
  EXPECT_LE(summary.tiles_ms + summary.shared_lobe_ms + summary.low_frequency_ms + other_ms, summary.solve_ms + 1e-9);
}

}  // namespace photorig::solvers::ps::testing
