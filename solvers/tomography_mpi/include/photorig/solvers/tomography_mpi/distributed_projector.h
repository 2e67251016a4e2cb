#pragma once
// W split over MPI processes by views. Each process holds a contiguous block
// of the scan's views (its rows of W, stored sparse or traced as a Projector
// of those views decides) and a whole copy of the volume:
//   forward  W x:   each process projects its own views; no communication;
//   back     W^T y: each process back-projects its views into a whole
//                   volume, and MPI_Allreduce sums the volumes;
//   ray sums (residual norms, counts, the noise level): MPI_Allreduce of one double.
// Reconstruct (SIRT, CGLS) runs unchanged on every process on top of this:
// every process makes the same updates from the same sums, so the volumes
// stay identical, and equal the single-process solve up to the order in
// which floats are added. ART visits rays one at a time and is refused.

#include "photorig/solvers/tomography/projector.h"

#include <mpi.h>

#include <cstdint>
#include <memory>

namespace photorig::tomography::mpi {

// MPI_Init_thread (funneled: OpenMP threads compute, the main thread
// communicates) and MPI_Finalize around a scope.
class Session {
 public:
  Session(int* argc, char*** argv);
  ~Session();
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;
  int rank() const { return rank_; }
  int size() const { return size_; }

 private:
  int rank_ = 0, size_ = 1;
};

// The views [first, first + count) process `rank` of `ranks` holds: the scan
// cut into blocks whose sizes differ by at most one.
struct ViewBlock {
  int first = 0;
  int count = 0;
};
ViewBlock ViewsOfRank(int views, int rank, int ranks);

class DistributedProjector : public SystemMatrix {
 public:
  // `views_here`: this process's Projector over its block of `geometry`'s views.
  DistributedProjector(std::unique_ptr<Projector> views_here, int total_views, MPI_Comm comm);

  std::int64_t rays() const override { return local_->rays(); }
  std::int64_t voxels() const override { return local_->voxels(); }
  int views() const override { return total_views_; }
  void Forward(const Eigen::VectorXf& x, Eigen::VectorXf* y) const override;
  void Back(const Eigen::VectorXf& y, Eigen::VectorXf* x) const override;
  double SumOverRays(double held_here) const override;

  const Projector& local() const { return *local_; }

 private:
  std::unique_ptr<Projector> local_;
  int total_views_;
  MPI_Comm comm_;
};

// Every process calls it with the whole scan's geometry and the same
// options; each builds its block. *first_ray is the scan's ray index of the
// block's first row (Geometry::RayIndex of its first view). The summary
// counts this process's block; MakeProjector's terminations.
ProjectorSummary MakeDistributedProjector(const VolumeGrid& grid, const Geometry& geometry,
                                          const ProjectorOptions& options, MPI_Comm comm,
                                          std::unique_ptr<SystemMatrix>* matrix, std::int64_t* first_ray);

}  // namespace photorig::tomography::mpi
