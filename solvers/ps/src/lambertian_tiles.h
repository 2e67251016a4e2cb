#pragma once
// SolveLambertian with a hook on each tile of pixels, for solvers that refine
// the Lambertian answer: the hook runs on the thread that solved the tile,
// right after the tile is written, while its samples are still in cache, so
// refining a pixel does not fetch its K samples from memory again.

#include "photorig/solvers/ps/lambertian_options.h"
#include "photorig/solvers/ps/stack.h"
#include "photorig/solvers/ps/summary.h"

#include <functional>
#include <memory>
#include <span>

namespace photorig::solvers::ps::internal {

// thread: omp_get_thread_num() of the solving thread (< the solve's thread
// count); the tile is pixels [begin, begin + count) in row-major order.
using TileVisitor = std::function<void(int thread, int begin, int count)>;
// Runs on each solving thread once it has no tiles left, while the others
// may still be solving theirs: the place to finish the thread's own work.
using ThreadDone = std::function<void(int thread)>;

SolverSummary SolveLambertianTiles(const LambertianOptions& options, const PhotometricStack& stack,
                                   NormalMap* result, const TileVisitor& visit, const ThreadDone& done = {});

// One pixel's least squares on its usable samples, as the tile kernel sums
// it (float lanes, the same thresholds and residual precision).
struct PixelResidual {
  double rss = 0.0;                        // sum of squared residuals in solver units, b = (I - D) / s
  int usable = 0;                          // usable samples
  double sum_inverse_scale2 = 0.0;         // sum of 1 / s^2 over the usable samples
  double sum_signal_inverse_scale2 = 0.0;  // sum of (I - D) / s^2 over them
  bool conditioned = false;                // false where the kernel could not vouch for the subset
};

// The tile kernel on chosen runs of pixels, for statistics over many pixels
// (the noise estimate) at the cost of the Lambertian pass rather than of a
// per-pixel fit.
class PixelResiduals {
 public:
  struct Run {
    int begin = 0;  // first pixel, row-major
    int count = 0;  // at most kMaxRun
  };
  static constexpr int kMaxRun = 256;

  // ok() is false where SolveLambertian would refuse the stack: invalid
  // options or images, fewer than 3 lights, coplanar lights.
  PixelResiduals(const LambertianOptions& options, const PhotometricStack& stack);
  ~PixelResiduals();
  bool ok() const { return impl_ != nullptr; }

  // Writes one PixelResidual per pixel of the runs, in order. Thread-safe.
  void Fit(std::span<const Run> runs, PixelResidual* out) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The subset kernel sums the normal equations with AVX-512 intrinsics where
// the CPU has AVX-512F, else with AVX2 intrinsics where it has AVX2 and FMA,
// else with its portable loop (multi-versioned for AVX2 and the baseline).
// Tests choose one to compare them on one machine (a kernel the CPU lacks
// leaves the fastest); not to be switched while a solve runs.
enum class SubsetKernel { kPortable, kAvx2, kAvx512 };
bool SubsetKernelAvailable(SubsetKernel kernel);
void UseSubsetKernel(SubsetKernel kernel);
void UseFastestSubsetKernel();

}  // namespace photorig::solvers::ps::internal
