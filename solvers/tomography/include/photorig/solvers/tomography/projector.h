#pragma once
// The system matrix W (rays x voxels) of a scan, applied forwards (W x, a
// projection) and backwards (W^T y, a back projection). Stored as an Eigen
// sparse matrix, with its transpose for a parallel back projection, when both
// fit in the memory budget; otherwise every product traces its rays again
// (matrix-free). Both give the same products through the same interface.

#include "photorig/solvers/core/progress.h"
#include "photorig/solvers/core/summary.h"
#include "photorig/solvers/tomography/geometry.h"
#include "photorig/solvers/tomography/ray_trace.h"
#include "photorig/solvers/tomography/volume_grid.h"

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace photorig::solvers::tomography {

enum class Storage {
  kAuto,       // sparse when W and W^T fit in memory_budget_bytes, matrix-free otherwise
  kSparse,     // sparse, or kFailure when it does not fit
  kMatrixFree  // trace the rays in every product
};

struct ProjectorOptions {
  Interpolation interpolation = Interpolation::kSiddon;
  Storage storage = Storage::kAuto;
  // What the stored W and W^T may take together. Default 4 GiB: a 64^3 volume
  // from 90 views of 64^2 pixels takes about 0.4 GB; 128^3 from 180 views of
  // 128^2 about 7 GB, so it runs matrix-free under the default.
  std::size_t memory_budget_bytes = std::size_t{4} << 30;
  solvers::core::ProgressCallback progress;  // stage "projector": views traced while building W
  // W's columns: the z-slices [first_slice, first_slice + slices) of the
  // grid; slices 0 (default): every slice from first_slice on. A process of a
  // slab decomposition (solvers/tomography_mpi) holds its slab's columns, so
  // that the products of every slab's W add up to the whole grid's
  // (TraceRayInSlices).
  int first_slice = 0;
  int slices = 0;

  bool IsValid(std::string* why) const;
};

using SparseMatrix = Eigen::SparseMatrix<float, Eigen::RowMajor, std::int32_t>;

// What the simultaneous iterations (SIRT, CGLS) need of W: its two products
// and sums over its rays and voxels. A Projector holds every row; a
// distributed form (solvers/tomography_mpi) holds a block of views and a slab
// of the volume per process, so that its ray-space vectors are that block's
// rows and its volumes that slab's voxels, and it sums products, ray sums and
// voxel sums over the processes.
class SystemMatrix {
 public:
  virtual ~SystemMatrix() = default;
  virtual std::int64_t rays() const = 0;    // rows held here (ray-space vectors have this size)
  virtual std::int64_t voxels() const = 0;  // columns held here (volumes have this size)
  virtual int views() const = 0;            // views of the whole scan
  virtual void Forward(const Eigen::VectorXf& x, Eigen::VectorXf* y) const = 0;  // y = W x, rows held here
  virtual void Back(const Eigen::VectorXf& y, Eigen::VectorXf* x) const = 0;     // x = W^T y over every row
  // A sum over rays (a squared norm, a count) from this part's share: the whole scan's.
  virtual double SumOverRays(double held_here) const { return held_here; }
  // A sum over voxels (a squared norm, a count) from this part's share: the whole volume's.
  virtual double SumOverVoxels(double held_here) const { return held_here; }
  // *volume holds the voxels held here; on return, the whole volume where it
  // is written (a distributed form: the first process; empty on the others).
  virtual void GatherVolume(Eigen::VectorXf* /*volume*/) const {}
};

class Projector : public SystemMatrix {
 public:
  // Columns: the grid's z-slices [first_slice, first_slice + slices); slices 0: to the last.
  Projector(const VolumeGrid& grid, const Geometry& geometry, Interpolation interpolation, int first_slice = 0,
            int slices = 0);

  const VolumeGrid& grid() const { return grid_; }
  const Geometry& geometry() const { return geometry_; }
  Interpolation interpolation() const { return interpolation_; }
  std::int64_t rays() const override { return geometry_.rays(); }
  std::int64_t voxels() const override { return static_cast<std::int64_t>(grid_.nx) * grid_.ny * slices_; }
  int first_slice() const { return first_slice_; }
  int slices() const { return slices_; }
  int views() const override { return geometry_.views(); }
  bool is_sparse() const { return w_ != nullptr; }
  std::int64_t nonzeros() const;  // stored entries of W (0 when matrix-free)
  std::size_t stored_bytes() const;

  void Forward(const Eigen::VectorXf& x, Eigen::VectorXf* y) const override;  // y = W x
  void Back(const Eigen::VectorXf& y, Eigen::VectorXf* x) const override;     // x = W^T y
  // Row `ray` of W, for row-action methods.
  void Row(std::int64_t ray, std::vector<RayWeight>* weights) const;
  // Calls visit(ray, voxels, weights_mm, count) for every ray of `view` in
  // order, for methods that work a view at a time: the stored rows when
  // sparse (no copy), traced into scratch arrays otherwise.
  template <typename Visit>
  void VisitViewRows(int view, Visit&& visit) const;

  // Stores W and W^T (called by MakeProjector when they fit).
  void StoreSparse(const solvers::core::ProgressCallback& progress);

 private:
  VolumeGrid grid_;
  Geometry geometry_;
  Interpolation interpolation_;
  int first_slice_, slices_;
  std::unique_ptr<SparseMatrix> w_, wt_;

  void Trace(int view, int row, int col, std::vector<RayWeight>* weights) const;
};

template <typename Visit>
void Projector::VisitViewRows(int view, Visit&& visit) const {
  const std::int64_t per_view = geometry_.pixels_per_view();
  const std::int64_t first = view * per_view;
  if (w_) {
    const std::int32_t* outer = w_->outerIndexPtr();
    for (std::int64_t ray = first; ray < first + per_view; ++ray)
      visit(ray, w_->innerIndexPtr() + outer[ray], w_->valuePtr() + outer[ray], outer[ray + 1] - outer[ray]);
    return;
  }
  std::vector<RayWeight> weights;
  std::vector<std::int32_t> voxels;
  std::vector<float> values;
  for (std::int64_t ray = first; ray < first + per_view; ++ray) {
    Row(ray, &weights);
    voxels.resize(weights.size());
    values.resize(weights.size());
    for (std::size_t k = 0; k < weights.size(); ++k) {
      voxels[k] = weights[k].voxel;
      values[k] = weights[k].weight_mm;
    }
    visit(ray, voxels.data(), values.data(), static_cast<std::int32_t>(weights.size()));
  }
}

struct ProjectorSummary : solvers::core::Summary {
  bool sparse = false;
  std::int64_t nonzeros = 0;                // stored entries of W (sparse only)
  std::size_t estimated_sparse_bytes = 0;   // W and W^T, from a sample of rays
  std::size_t stored_bytes = 0;
};

// Builds the projector of `grid` seen by `geometry`. Ends kInvalidOptions or
// kInvalidInput with the reason, or kFailure when kSparse was asked for and
// W does not fit the budget.
ProjectorSummary MakeProjector(const VolumeGrid& grid, const Geometry& geometry, const ProjectorOptions& options,
                               std::unique_ptr<Projector>* projector);

}  // namespace photorig::solvers::tomography
