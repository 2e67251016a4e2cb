#include "photorig/solvers/tomography_mpi/distributed_projector.h"

#include <algorithm>
#include <vector>

namespace photorig::solvers::tomography_mpi {

Session::Session(int* argc, char*** argv) {
  int provided = 0;
  MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

Session::~Session() { MPI_Finalize(); }

Block BlockOfRank(int items, int rank, int ranks) {
  const int base = items / ranks, extra = items % ranks;
  return {rank * base + std::min(rank, extra), base + (rank < extra ? 1 : 0)};
}

bool DecompositionOptions::IsValid(std::string* why) const {
  if (slabs < 0) return core::Refuse(why, "slabs must be >= 0 (0: chosen from volume_budget_bytes)");
  if (volume_budget_bytes == 0) return core::Refuse(why, "volume_budget_bytes must be > 0");
  return true;
}

namespace {

// Reconstruct's volume vectors (see DecompositionOptions::volume_budget_bytes).
constexpr int kVolumeVectors = 4;

std::size_t VolumeBytes(const tomography::VolumeGrid& grid, int slices) {
  return static_cast<std::size_t>(kVolumeVectors) * sizeof(float) * static_cast<std::size_t>(grid.nx) *
         static_cast<std::size_t>(grid.ny) * static_cast<std::size_t>(slices);
}

// MPI counts are ints: vectors beyond 2^31 entries go in pieces.
template <typename Reduce>
void InPieces(std::int64_t n, Reduce reduce) {
  constexpr std::int64_t kPiece = std::int64_t{1} << 30;
  for (std::int64_t at = 0; at < n; at += kPiece) reduce(at, static_cast<int>(std::min(kPiece, n - at)));
}

void SumInPlace(Eigen::VectorXf* v, MPI_Comm comm) {
  InPieces(v->size(), [&](std::int64_t at, int count) {
    MPI_Allreduce(MPI_IN_PLACE, v->data() + at, count, MPI_FLOAT, MPI_SUM, comm);
  });
}

int Size(MPI_Comm comm) {
  int size = 1;
  MPI_Comm_size(comm, &size);
  return size;
}

}  // namespace

bool ChooseDecomposition(const tomography::VolumeGrid& grid, int views, int processes,
                         const DecompositionOptions& options, Decomposition* chosen, std::string* why) {
  if (!options.IsValid(why)) return false;
  int slabs = options.slabs;
  if (slabs == 0) {
    // The fewest slabs that fit; failing that, the most there can be.
    for (int s = 1; s <= std::min(processes, grid.nz); ++s) {
      if (processes % s != 0 || processes / s > views) continue;
      slabs = s;
      if (VolumeBytes(grid, (grid.nz + s - 1) / s) <= options.volume_budget_bytes) break;
    }
    if (slabs == 0) return core::Refuse(why, std::to_string(processes) + " processes cannot share " + std::to_string(views) +
                                             " views and " + std::to_string(grid.nz) + " slices");
  }
  if (processes % slabs != 0)
    return core::Refuse(why, std::to_string(processes) + " processes cannot form " + std::to_string(slabs) +
                             " slabs: the processes are view groups x slabs, so the slabs must divide them");
  if (slabs > grid.nz)
    return core::Refuse(why, std::to_string(slabs) + " slabs of a volume of " + std::to_string(grid.nz) +
                             " slices: at most one slab a slice");
  if (processes / slabs > views)
    return core::Refuse(why, std::to_string(processes / slabs) + " view groups (" + std::to_string(processes) + " processes / " +
                             std::to_string(slabs) + " slabs) cannot share " + std::to_string(views) + " views");
  *chosen = {processes / slabs, slabs};
  return true;
}

DistributedProjector::DistributedProjector(std::unique_ptr<tomography::Projector> here, int total_views,
                                           const Decomposition& decomposition, MPI_Comm comm)
    : local_(std::move(here)), total_views_(total_views), decomposition_(decomposition) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  const int view_group = rank / decomposition.slabs, slab = rank % decomposition.slabs;
  first_view_group_ = view_group == 0;
  MPI_Comm_split(comm, view_group, slab, &same_views_);
  MPI_Comm_split(comm, slab, view_group, &same_slab_);
}

DistributedProjector::~DistributedProjector() {
  MPI_Comm_free(&same_views_);
  MPI_Comm_free(&same_slab_);
}

void DistributedProjector::Forward(const Eigen::VectorXf& x, Eigen::VectorXf* y) const {
  local_->Forward(x, y);
  if (decomposition_.slabs > 1) SumInPlace(y, same_views_);
}

void DistributedProjector::Back(const Eigen::VectorXf& y, Eigen::VectorXf* x) const {
  local_->Back(y, x);
  if (decomposition_.view_groups > 1) SumInPlace(x, same_slab_);
}

double DistributedProjector::SumOverRays(double held_here) const {
  double sum = 0.0;
  MPI_Allreduce(&held_here, &sum, 1, MPI_DOUBLE, MPI_SUM, same_slab_);
  return sum;
}

double DistributedProjector::SumOverVoxels(double held_here) const {
  double sum = 0.0;
  MPI_Allreduce(&held_here, &sum, 1, MPI_DOUBLE, MPI_SUM, same_views_);
  return sum;
}

void DistributedProjector::GatherVolume(Eigen::VectorXf* volume) const {
  if (!first_view_group_) {
    *volume = Eigen::VectorXf();
    return;
  }
  const int slabs = Size(same_views_);
  int slab = 0;
  MPI_Comm_rank(same_views_, &slab);
  if (slabs == 1) return;
  // Slabs are contiguous runs of z, the slowest index: they lie end to end.
  const tomography::VolumeGrid& grid = local_->grid();
  const int per_slice = grid.nx * grid.ny;
  std::vector<int> counts(static_cast<std::size_t>(slabs)), offsets(static_cast<std::size_t>(slabs));
  for (int s = 0; s < slabs; ++s) {
    const Block block = BlockOfRank(grid.nz, s, slabs);
    counts[static_cast<std::size_t>(s)] = block.count * per_slice;
    offsets[static_cast<std::size_t>(s)] = block.first * per_slice;
  }
  Eigen::VectorXf whole;
  if (slab == 0) whole.resize(grid.voxels());
  MPI_Gatherv(volume->data(), static_cast<int>(volume->size()), MPI_FLOAT, whole.data(), counts.data(),
              offsets.data(), MPI_FLOAT, 0, same_views_);
  *volume = std::move(whole);
}

tomography::ProjectorSummary MakeDistributedProjector(const tomography::VolumeGrid& grid,
                                                      const tomography::Geometry& geometry,
                                                      const tomography::ProjectorOptions& options,
                                                      const DecompositionOptions& decomposition, MPI_Comm comm,
                                                      std::unique_ptr<tomography::SystemMatrix>* matrix,
                                                      std::int64_t* first_ray) {
  int rank = 0, ranks = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &ranks);
  tomography::ProjectorSummary summary;
  Decomposition chosen;
  if (std::string why; !ChooseDecomposition(grid, geometry.views(), ranks, decomposition, &chosen, &why)) {
    summary.End(solvers::core::Termination::kInvalidOptions, why);
    return summary;
  }
  const Block views = BlockOfRank(geometry.views(), rank / chosen.slabs, chosen.view_groups);
  const Block slices = BlockOfRank(grid.nz, rank % chosen.slabs, chosen.slabs);
  tomography::Geometry mine = geometry;
  mine.angles_rad.assign(geometry.angles_rad.begin() + views.first,
                         geometry.angles_rad.begin() + views.first + views.count);
  tomography::ProjectorOptions slab = options;
  slab.first_slice = slices.first;
  slab.slices = slices.count;
  std::unique_ptr<tomography::Projector> local;
  summary = MakeProjector(grid, mine, slab, &local);
  // A block that does not fit the budget on one process fails them all: the
  // others would wait for it in their first product.
  int built_everywhere = summary.IsSolutionUsable() ? 1 : 0;
  MPI_Allreduce(MPI_IN_PLACE, &built_everywhere, 1, MPI_INT, MPI_MIN, comm);
  if (!summary.IsSolutionUsable()) return summary;
  if (!built_everywhere) {
    summary.End(solvers::core::Termination::kFailure,
                "another process could not build its block of W: it does not fit memory_budget_bytes there");
    return summary;
  }
  *first_ray = geometry.RayIndex(views.first, 0, 0);
  *matrix = std::make_unique<DistributedProjector>(std::move(local), geometry.views(), chosen, comm);
  return summary;
}

}  // namespace photorig::solvers::tomography_mpi
