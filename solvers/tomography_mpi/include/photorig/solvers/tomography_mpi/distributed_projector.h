#pragma once
// W split over MPI processes by views and by slabs of the volume. The
// processes form a grid of view_groups x slabs (process p: view group
// p / slabs, slab p % slabs). Each holds a contiguous block of the scan's
// views and a contiguous slab of z-slices of the volume: the block of W
// where its views' rows meet its slab's columns (stored sparse or traced, as
// a Projector of those views and slices decides), its views' rays and its
// slab's voxels.
//   forward  W x:   each process projects its slab along its views' rays: partial
//                   ray sums, added by MPI_Allreduce over the processes of its
//                   view group (the other slabs of the same views);
//   back     W^T y: each process back-projects its views into its slab,
//                   added by MPI_Allreduce over the processes of its slab (the
//                   other view groups);
//   sums over rays (residual norms, counts, the noise level): MPI_Allreduce
//                   over the processes of one slab; sums over voxels (CGLS's
//                   |W^T r|^2, reached voxels): over those of one view group.
// Views alone (slabs = 1) replicate the volume on every process; slabs alone
// (one view group) replicate the rays. Reconstruct (SIRT, CGLS) runs
// unchanged on every process on top of this: every process makes the same
// updates from the same sums, so the copies of each slab stay identical, and
// equal the single-process solve up to the order in which floats are added.
// ART visits rays one at a time and is refused.

#include "photorig/solvers/tomography/projector.h"

#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

namespace photorig::solvers::tomography_mpi {

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

// The items [first, first + count) part `rank` of `ranks` holds: `items`
// (views, slices) cut into contiguous blocks whose sizes differ by at most one.
struct Block {
  int first = 0;
  int count = 0;
};
Block BlockOfRank(int items, int rank, int ranks);

struct Decomposition {
  int view_groups = 1;
  int slabs = 1;
};

struct DecompositionOptions {
  // Slabs of the volume along z (the rotation axis); the processes are split
  // into processes / slabs groups of views. 0 (default): the fewest slabs, a
  // divisor of the processes, for which one process's volume vectors fit
  // volume_budget_bytes: views alone when the whole volume fits, and as many
  // slabs as can be when even that does not fit.
  int slabs = 0;
  // What the volume vectors of one process may take (SIRT and CGLS hold four:
  // the volume, a back projection, the column sums and their inverse or
  // CGLS's two directions). Default 4 GiB: up to 645^3 voxels stays split by
  // views alone (no partial ray sums to exchange); 1024^3 (16 GiB) needs 4
  // slabs or more.
  std::size_t volume_budget_bytes = std::size_t{4} << 30;

  bool IsValid(std::string* why) const;
};

// How `processes` processes share a scan of `views` views of `grid`: `options`
// resolved, and checked (the slabs divide the processes, processes = view
// groups x slabs; no more slabs than slices, no more view groups than views).
// False with the reason otherwise.
bool ChooseDecomposition(const tomography::VolumeGrid& grid, int views, int processes,
                         const DecompositionOptions& options, Decomposition* chosen, std::string* why);

class DistributedProjector : public tomography::SystemMatrix {
 public:
  // `here`: this process's Projector over its block of the scan's views and
  // its slab of the grid. `comm`: every process of the decomposition.
  DistributedProjector(std::unique_ptr<tomography::Projector> here, int total_views,
                       const Decomposition& decomposition, MPI_Comm comm);
  ~DistributedProjector() override;
  DistributedProjector(const DistributedProjector&) = delete;
  DistributedProjector& operator=(const DistributedProjector&) = delete;

  std::int64_t rays() const override { return local_->rays(); }
  std::int64_t voxels() const override { return local_->voxels(); }
  int views() const override { return total_views_; }
  void Forward(const Eigen::VectorXf& x, Eigen::VectorXf* y) const override;
  void Back(const Eigen::VectorXf& y, Eigen::VectorXf* x) const override;
  double SumOverRays(double held_here) const override;
  double SumOverVoxels(double held_here) const override;
  // The slabs to the first process (of the first view group), in z order.
  void GatherVolume(Eigen::VectorXf* volume) const override;

  const tomography::Projector& local() const { return *local_; }
  const Decomposition& decomposition() const { return decomposition_; }

 private:
  std::unique_ptr<tomography::Projector> local_;
  int total_views_;
  Decomposition decomposition_;
  bool first_view_group_ = true;
  // The processes holding the same views (every slab of them), and those
  // holding the same slab (every view group).
  MPI_Comm same_views_ = MPI_COMM_NULL, same_slab_ = MPI_COMM_NULL;
};

// Every process calls it with the whole scan's geometry and grid and the
// same options; each builds its block of views and slab of slices. *first_ray
// is the scan's ray index of the block's first row (Geometry::RayIndex of
// its first view). The summary counts this process's block; MakeProjector's
// terminations, and kInvalidOptions for a decomposition ChooseDecomposition
// refuses.
tomography::ProjectorSummary MakeDistributedProjector(const tomography::VolumeGrid& grid,
                                                      const tomography::Geometry& geometry,
                                                      const tomography::ProjectorOptions& options,
                                                      const DecompositionOptions& decomposition, MPI_Comm comm,
                                                      std::unique_ptr<tomography::SystemMatrix>* matrix,
                                                      std::int64_t* first_ray);

}  // namespace photorig::solvers::tomography_mpi
