#include "photorig/solvers/tomography/projector.h"

#include <algorithm>
#include <numeric>

#include <omp.h>

namespace photorig::solvers::tomography {

bool ProjectorOptions::IsValid(std::string* why) const {
  if (memory_budget_bytes == 0 && storage == Storage::kSparse) {
    if (why) *why = "a sparse W needs memory_budget_bytes > 0";
    return false;
  }
  if (first_slice < 0 || slices < 0) {
    if (why) *why = "first_slice and slices must be >= 0";
    return false;
  }
  return true;
}

Projector::Projector(const VolumeGrid& grid, const Geometry& geometry, Interpolation interpolation, int first_slice,
                     int slices)
    : grid_(grid),
      geometry_(geometry),
      interpolation_(interpolation),
      first_slice_(first_slice),
      slices_(slices > 0 ? slices : grid.nz - first_slice) {}

std::int64_t Projector::nonzeros() const { return w_ ? w_->nonZeros() : 0; }

std::size_t Projector::stored_bytes() const {
  if (!w_) return 0;
  auto bytes = [](const SparseMatrix& m) {
    return static_cast<std::size_t>(m.nonZeros()) * (sizeof(float) + sizeof(std::int32_t)) +
           static_cast<std::size_t>(m.outerSize() + 1) * sizeof(std::int32_t);
  };
  return bytes(*w_) + bytes(*wt_);
}

void Projector::Row(std::int64_t ray, std::vector<RayWeight>* weights) const {
  if (w_) {
    weights->clear();
    for (SparseMatrix::InnerIterator it(*w_, ray); it; ++it) weights->push_back({it.index(), it.value()});
    return;
  }
  const int cols = geometry_.detector_cols, rows = geometry_.detector_rows;
  const int view = static_cast<int>(ray / (static_cast<std::int64_t>(rows) * cols));
  const int row = static_cast<int>(ray / cols % rows), col = static_cast<int>(ray % cols);
  Trace(view, row, col, weights);
}

void Projector::Trace(int view, int row, int col, std::vector<RayWeight>* weights) const {
  Eigen::Vector3d origin, direction;
  geometry_.Ray(view, row, col, &origin, &direction);
  if (slices_ == grid_.nz)
    TraceRay(grid_, origin, direction, interpolation_, weights);
  else
    TraceRayInSlices(grid_, first_slice_, slices_, origin, direction, interpolation_, weights);
}

namespace {

// Below this many entries a product is faster on one thread than the cost of waking the others.
constexpr std::int64_t kParallelWork = 200000;

// y = M x for a row-major sparse M, rows shared between threads.
void Multiply(const SparseMatrix& m, const Eigen::VectorXf& x, Eigen::VectorXf* y) {
  y->resize(m.rows());
  const std::int32_t* outer = m.outerIndexPtr();
  const std::int32_t* inner = m.innerIndexPtr();
  const float* value = m.valuePtr();
  const float* xs = x.data();
  float* ys = y->data();
  const std::int64_t rows = m.rows();
#pragma omp parallel for schedule(static) if (m.nonZeros() > kParallelWork)
  for (std::int64_t r = 0; r < rows; ++r) {
    float sum = 0.0f;
    for (std::int32_t k = outer[r]; k < outer[r + 1]; ++k) sum += value[k] * xs[inner[k]];
    ys[r] = sum;
  }
}

}  // namespace

void Projector::Forward(const Eigen::VectorXf& x, Eigen::VectorXf* y) const {
  if (w_) return Multiply(*w_, x, y);
  y->resize(rays());
  const std::int64_t n = rays();
#pragma omp parallel if (n > 2000)
  {
    std::vector<RayWeight> weights;
#pragma omp for schedule(dynamic, 256)
    for (std::int64_t ray = 0; ray < n; ++ray) {
      Row(ray, &weights);
      float sum = 0.0f;
      for (const RayWeight& w : weights) sum += w.weight_mm * x[w.voxel];
      (*y)[ray] = sum;
    }
  }
}

void Projector::Back(const Eigen::VectorXf& y, Eigen::VectorXf* x) const {
  if (wt_) return Multiply(*wt_, y, x);
  x->setZero(voxels());
  const std::int64_t n = rays();
  float* xs = x->data();
#pragma omp parallel if (n > 2000)
  {
    std::vector<RayWeight> weights;
#pragma omp for schedule(dynamic, 256)
    for (std::int64_t ray = 0; ray < n; ++ray) {
      const float value = y[ray];
      if (value == 0.0f) continue;
      Row(ray, &weights);
      for (const RayWeight& w : weights) {
#pragma omp atomic
        xs[w.voxel] += w.weight_mm * value;
      }
    }
  }
}

void Projector::StoreSparse(const solvers::core::ProgressCallback& progress) {
  const int views = geometry_.views();
  const std::int64_t per_view = geometry_.pixels_per_view();
  // Each view's rows are traced on their own, then laid end to end.
  std::vector<std::vector<std::int32_t>> counts(views), inner(views);
  std::vector<std::vector<float>> values(views);
  solvers::core::ProgressThrottle throttle(progress, "projector", views);
  int done = 0;
#pragma omp parallel
  {
    std::vector<RayWeight> weights;
#pragma omp for schedule(dynamic, 1)
    for (int view = 0; view < views; ++view) {
      counts[view].reserve(per_view);
      for (int row = 0; row < geometry_.detector_rows; ++row)
        for (int col = 0; col < geometry_.detector_cols; ++col) {
          Trace(view, row, col, &weights);
          counts[view].push_back(static_cast<std::int32_t>(weights.size()));
          for (const RayWeight& w : weights) {
            inner[view].push_back(w.voxel);
            values[view].push_back(w.weight_mm);
          }
        }
      // Reported from the calling thread only, as the progress contract asks.
#pragma omp atomic
      ++done;
      if (omp_get_thread_num() == 0) throttle.Update(done);
    }
  }
  std::int64_t nnz = 0;
  for (const auto& v : inner) nnz += static_cast<std::int64_t>(v.size());
  auto w = std::make_unique<SparseMatrix>(rays(), voxels());
  w->resizeNonZeros(nnz);
  std::int32_t* outer = w->outerIndexPtr();
  std::int64_t ray = 0, at = 0;
  outer[0] = 0;
  for (int view = 0; view < views; ++view) {
    for (std::int32_t c : counts[view]) {
      outer[ray + 1] = outer[ray] + c;
      ++ray;
    }
    std::copy(inner[view].begin(), inner[view].end(), w->innerIndexPtr() + at);
    std::copy(values[view].begin(), values[view].end(), w->valuePtr() + at);
    at += static_cast<std::int64_t>(inner[view].size());
    std::vector<std::int32_t>().swap(inner[view]);
    std::vector<float>().swap(values[view]);
  }
  // Siddon rows come in path order, not column order.
  for (std::int64_t r = 0; r < w->rows(); ++r) {
    std::vector<std::pair<std::int32_t, float>> row;
    for (std::int32_t k = outer[r]; k < outer[r + 1]; ++k) row.emplace_back(w->innerIndexPtr()[k], w->valuePtr()[k]);
    if (std::is_sorted(row.begin(), row.end())) continue;
    std::sort(row.begin(), row.end());
    for (std::size_t i = 0; i < row.size(); ++i) {
      w->innerIndexPtr()[outer[r] + i] = row[i].first;
      w->valuePtr()[outer[r] + i] = row[i].second;
    }
  }
  wt_ = std::make_unique<SparseMatrix>(w->transpose());
  w_ = std::move(w);
  throttle.Finish();
}

ProjectorSummary MakeProjector(const VolumeGrid& grid, const Geometry& geometry, const ProjectorOptions& options,
                               std::unique_ptr<Projector>* projector) {
  solvers::core::SolveTimer timer;
  ProjectorSummary summary;
  using solvers::core::Termination;
  std::string why;
  if (!options.IsValid(&why)) return timer.End(&summary, Termination::kInvalidOptions, why);
  if (!grid.IsValid(&why) || !geometry.IsValid(&why)) return timer.End(&summary, Termination::kInvalidInput, why);
  if (options.first_slice + std::max(options.slices, 1) > grid.nz)
    return timer.End(&summary, Termination::kInvalidOptions,
                     "slices from " + std::to_string(options.first_slice) + " (" + std::to_string(options.slices) +
                         " of them) run past the grid's " + std::to_string(grid.nz));
  auto result = std::make_unique<Projector>(grid, geometry, options.interpolation, options.first_slice, options.slices);
  // Entries per ray from a sample of about 2000 rays spread over the scan.
  const std::int64_t rays = geometry.rays();
  const std::int64_t stride = std::max<std::int64_t>(1, rays / 2000);
  std::vector<RayWeight> weights;
  std::int64_t sampled = 0, sampled_entries = 0;
  for (std::int64_t ray = stride / 2; ray < rays; ray += stride, ++sampled) {
    result->Row(ray, &weights);
    sampled_entries += static_cast<std::int64_t>(weights.size());
  }
  const double entries = static_cast<double>(sampled_entries) / std::max<std::int64_t>(1, sampled) * rays;
  summary.estimated_sparse_bytes = static_cast<std::size_t>(
      2 * entries * (sizeof(float) + sizeof(std::int32_t)) + (rays + result->voxels() + 2) * sizeof(std::int32_t));
  // Eigen's 32-bit indices also bound the entries.
  const bool fits = summary.estimated_sparse_bytes <= options.memory_budget_bytes && entries < 2.0e9;
  timer.SetupDone(&summary);
  if (options.storage == Storage::kSparse && !fits)
    return timer.End(&summary, Termination::kFailure,
                     "W and W^T need about " + std::to_string(summary.estimated_sparse_bytes >> 20) +
                         " MiB, over memory_budget_bytes; raise the budget or use the matrix-free storage");
  if (options.storage == Storage::kSparse || (options.storage == Storage::kAuto && fits))
    result->StoreSparse(options.progress);
  summary.sparse = result->is_sparse();
  summary.nonzeros = result->nonzeros();
  summary.stored_bytes = result->stored_bytes();
  summary.termination = Termination::kSuccess;
  *projector = std::move(result);
  timer.Finish(&summary);
  return summary;
}

}  // namespace photorig::solvers::tomography
