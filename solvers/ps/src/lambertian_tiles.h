#pragma once
// SolveLambertian with a hook on each tile of pixels, for solvers that refine
// the Lambertian answer: the hook runs on the thread that solved the tile,
// right after the tile is written, while its samples are still in cache, so
// refining a pixel does not fetch its K samples from memory again.

#include "photorig/ps/lambertian.h"

#include <functional>

namespace photorig::ps::internal {

// thread: omp_get_thread_num() of the solving thread (< the solve's thread
// count); the tile is pixels [begin, begin + count) in row-major order.
using TileVisitor = std::function<void(int thread, int begin, int count)>;

SolverSummary SolveLambertianTiles(const LambertianOptions& options, const PhotometricStack& stack,
                                   NormalMap* result, const TileVisitor& visit);

}  // namespace photorig::ps::internal
