#include "photorig/solvers/tomography_mpi/distributed_projector.h"

#include <algorithm>

namespace photorig::tomography::mpi {

Session::Session(int* argc, char*** argv) {
  int provided = 0;
  MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

Session::~Session() { MPI_Finalize(); }

ViewBlock ViewsOfRank(int views, int rank, int ranks) {
  const int base = views / ranks, extra = views % ranks;
  return {rank * base + std::min(rank, extra), base + (rank < extra ? 1 : 0)};
}

DistributedProjector::DistributedProjector(std::unique_ptr<Projector> views_here, int total_views, MPI_Comm comm)
    : local_(std::move(views_here)), total_views_(total_views), comm_(comm) {}

void DistributedProjector::Forward(const Eigen::VectorXf& x, Eigen::VectorXf* y) const { local_->Forward(x, y); }

void DistributedProjector::Back(const Eigen::VectorXf& y, Eigen::VectorXf* x) const {
  local_->Back(y, x);
  MPI_Allreduce(MPI_IN_PLACE, x->data(), static_cast<int>(x->size()), MPI_FLOAT, MPI_SUM, comm_);
}

double DistributedProjector::SumOverRays(double held_here) const {
  double sum = 0.0;
  MPI_Allreduce(&held_here, &sum, 1, MPI_DOUBLE, MPI_SUM, comm_);
  return sum;
}

ProjectorSummary MakeDistributedProjector(const VolumeGrid& grid, const Geometry& geometry,
                                          const ProjectorOptions& options, MPI_Comm comm,
                                          std::unique_ptr<SystemMatrix>* matrix, std::int64_t* first_ray) {
  int rank = 0, ranks = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &ranks);
  ProjectorSummary summary;
  if (geometry.views() < ranks) {
    summary.End(solvers::Termination::kInvalidInput, std::to_string(geometry.views()) + " views cannot be shared by " +
                                                         std::to_string(ranks) + " processes");
    return summary;
  }
  const ViewBlock block = ViewsOfRank(geometry.views(), rank, ranks);
  Geometry mine = geometry;
  mine.angles_rad.assign(geometry.angles_rad.begin() + block.first, geometry.angles_rad.begin() + block.first + block.count);
  std::unique_ptr<Projector> local;
  summary = MakeProjector(grid, mine, options, &local);
  if (!summary.IsSolutionUsable()) return summary;
  *first_ray = geometry.RayIndex(block.first, 0, 0);
  *matrix = std::make_unique<DistributedProjector>(std::move(local), geometry.views(), comm);
  return summary;
}

}  // namespace photorig::tomography::mpi
