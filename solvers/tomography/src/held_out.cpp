#include "photorig/solvers/tomography/held_out.h"

#include "photorig/solvers/tomography/projector.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <numeric>

namespace photorig::solvers::tomography {

bool HeldOutOptions::IsValid(std::string* why) const { return reconstruct.IsValid(why); }

void SelectViews(const Geometry& geometry, const Absorbance& measurements, const std::vector<int>& views,
                 Geometry* selected_geometry, Absorbance* selected) {
  *selected_geometry = geometry;
  selected_geometry->angles_rad.clear();
  const std::int64_t per_view = geometry.pixels_per_view();
  const auto n = static_cast<std::int64_t>(views.size());
  *selected = Absorbance();
  selected->b.resize(n * per_view);
  const bool has_valid = !measurements.valid.empty(), has_variance = measurements.variance.size() > 0;
  if (has_valid) selected->valid.resize(static_cast<std::size_t>(n * per_view));
  if (has_variance) selected->variance.resize(n * per_view);
  for (std::int64_t k = 0; k < n; ++k) {
    const int view = views[static_cast<std::size_t>(k)];
    selected_geometry->angles_rad.push_back(geometry.angles_rad[static_cast<std::size_t>(view)]);
    const std::int64_t from = view * per_view, to = k * per_view;
    selected->b.segment(to, per_view) = measurements.b.segment(from, per_view);
    if (has_valid)
      std::copy_n(measurements.valid.begin() + from, per_view, selected->valid.begin() + to);
    if (has_variance) selected->variance.segment(to, per_view) = measurements.variance.segment(from, per_view);
  }
}

HeldOutSummary HeldOutResidual(const VolumeGrid& grid, const Geometry& geometry, const Absorbance& measurements,
                               const HeldOutOptions& options) {
  solvers::core::SolveTimer timer;
  HeldOutSummary summary;
  if (solvers::core::EndIfInvalid(options, &summary)) return summary;
  std::string why;
  if (!geometry.IsValid(&why)) return timer.End(&summary, solvers::core::Termination::kInvalidInput, why);
  if (measurements.b.size() != geometry.rays())
    return timer.End(&summary, solvers::core::Termination::kInvalidInput, "the measurements do not match the scan's rays");

  // Distinct angles in order (repeats of one angle stay on one side: a repeat
  // held out would only measure the noise).
  std::vector<int> order(static_cast<std::size_t>(geometry.views()));
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return geometry.angles_rad[a] < geometry.angles_rad[b]; });
  std::vector<int> fit, held;
  int distinct = -1;
  double last = 0.0;
  for (int view : order) {
    const double angle = geometry.angles_rad[static_cast<std::size_t>(view)];
    if (distinct < 0 || angle - last > 1e-9) ++distinct;
    last = angle;
    (distinct % 2 == 0 ? fit : held).push_back(view);
  }
  if (held.empty())
    return timer.End(&summary, solvers::core::Termination::kFailure, "fewer than two distinct view angles: none to hold out");
  summary.fit_views = static_cast<int>(fit.size());
  summary.held_out_views = static_cast<int>(held.size());
  Geometry fit_geometry, held_geometry;
  Absorbance fit_b, held_b;
  SelectViews(geometry, measurements, fit, &fit_geometry, &fit_b);
  SelectViews(geometry, measurements, held, &held_geometry, &held_b);

  ProjectorOptions projector_options;
  projector_options.interpolation = options.interpolation;
  std::unique_ptr<Projector> fit_w, held_w;
  for (auto [g, w] : {std::pair{&fit_geometry, &fit_w}, std::pair{&held_geometry, &held_w}})
    if (const ProjectorSummary made = MakeProjector(grid, *g, projector_options, w); !made.IsSolutionUsable())
      return timer.End(&summary, made.termination, "projector: " + made.message);
  timer.SetupDone(&summary);

  double b2 = 0.0, variance = 0.0;
  for (std::int64_t ray = 0; ray < held_geometry.rays(); ++ray) {
    if (!held_b.valid.empty() && held_b.valid[static_cast<std::size_t>(ray)] == 0) continue;
    b2 += static_cast<double>(held_b.b[ray]) * held_b.b[ray];
    if (held_b.variance.size() > 0) variance += held_b.variance[ray];
    ++summary.held_out_rays;
  }
  if (!(b2 > 0.0))
    return timer.End(&summary, solvers::core::Termination::kFailure, "the held-out views carry no signal");
  Eigen::VectorXf predicted;
  auto relative_residual = [&](const Eigen::VectorXf& sigma) {
    held_w->Forward(sigma, &predicted);
    double residual2 = 0.0;
    for (std::int64_t ray = 0; ray < held_geometry.rays(); ++ray)
      if (held_b.valid.empty() || held_b.valid[static_cast<std::size_t>(ray)] != 0)
        residual2 += (predicted[ray] - held_b.b[ray]) * (predicted[ray] - held_b.b[ray]);
    return std::sqrt(residual2 / b2);
  };
  ReconstructOptions reconstruct = options.reconstruct;
  if (options.track_iterations)
    reconstruct.on_iteration = [&, outer = options.reconstruct.on_iteration](int iteration, const Eigen::VectorXf& x) {
      summary.residual_history.push_back(relative_residual(x));
      if (summary.best_iteration == 0 || summary.residual_history.back() < summary.residual_history[summary.best_iteration - 1])
        summary.best_iteration = iteration;
      if (outer) outer(iteration, x);
    };

  Eigen::VectorXf sigma;
  summary.reconstruction = Reconstruct(*fit_w, fit_b, reconstruct, &sigma);
  if (!summary.reconstruction.IsSolutionUsable())
    return timer.End(&summary, solvers::core::Termination::kFailure,
                     "the even views' reconstruction: " + summary.reconstruction.message);
  summary.relative_residual = relative_residual(sigma);
  timer.Finish(&summary);
  summary.noise_floor = std::sqrt(variance / b2);
  summary.termination = summary.reconstruction.termination == solvers::core::Termination::kSuccess
                            ? solvers::core::Termination::kSuccess
                            : solvers::core::Termination::kNoConvergence;
  if (summary.termination != solvers::core::Termination::kSuccess)
    summary.message = "the even views' reconstruction: " + summary.reconstruction.message;
  return summary;
}

}  // namespace photorig::solvers::tomography
