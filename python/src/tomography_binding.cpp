// photorig.solve_tomography: `photorig solve tomography` in-process, through
// the same pipeline (tomography_pipeline.h's LoadTomographyInput and SolveTomography).

#include "arrays.h"
#include "bindings.h"
#include "choices.h"
#include "photorig/daemon/pipelines/tomography_pipeline.h"
#include "progress.h"
#include "run.h"

#include <pybind11/stl.h>  // std::optional and std::array options

#include <algorithm>
#include <array>

namespace photorig::python {
namespace {

namespace tomo = solvers::tomography;

py::dict SolveTomographyOf(const std::string& source, const config::TomographyRequest& request,
                           bool accept_failed_capture, ProgressBridge* bridge) {
  daemon::TomographyResult result;
  {
    py::gil_scoped_release unlocked;
    const daemon::TomographyInput input = daemon::LoadTomographyInput(
        source, FailedCapturePolicy(accept_failed_capture));
    result = daemon::SolveTomography(input, request);
  }
  bridge->RethrowIfFailed();
  py::dict out;
  out["summary"] = ToPython(result.ToJson());
  if (result.sigma.size() == 0) return out;
  // sigma is in VolumeGrid::Index order, x fastest: (nz, ny, nx) in C order.
  const tomo::VolumeGrid& grid = result.grid;
  py::array_t<float> volume({grid.nz, grid.ny, grid.nx});
  std::copy(result.sigma.data(), result.sigma.data() + result.sigma.size(), volume.mutable_data());
  out["volume"] = volume;
  return out;
}

}  // namespace

void BindTomography(py::module_& m) {
  const config::TomographyRequest defaults;
  m.def(
      "solve_tomography",
      [](py::object run, const std::string& method, bool total_variation, const std::string& projector,
         int max_iterations, double discrepancy_factor, std::array<int, 3> volume, double voxel_mm,
         std::optional<double> cor_offset_mm, bool ring_filter, bool held_out, bool accept_failed_capture,
         py::object progress) {
        config::TomographyRequest request;
        request.method = ParseChoice(tomo::kMethodNames, method, "method");
        request.total_variation = total_variation;
        request.projector = ParseChoice(tomo::kInterpolationNames, projector, "projector");
        request.max_iterations = max_iterations;
        request.discrepancy_factor = discrepancy_factor;
        request.volume = volume;
        request.voxel_mm = voxel_mm;
        request.cor_offset_mm = cor_offset_mm;
        request.ring_filter = ring_filter;
        request.held_out = held_out;
        if (std::string why; !request.IsValid(&why)) throw py::value_error(why);
        ProgressBridge bridge(std::move(progress));
        request.progress = bridge.Callback();
        return SolveTomographyOf(RunDirectory(run), request, accept_failed_capture, &bridge);
      },
      py::arg("run"), py::kw_only(), py::arg("method") = tomo::MethodName(defaults.method),
      py::arg("total_variation") = defaults.total_variation,
      py::arg("projector") = tomo::InterpolationName(defaults.projector),
      py::arg("max_iterations") = defaults.max_iterations, py::arg("discrepancy_factor") = defaults.discrepancy_factor,
      py::arg("volume") = defaults.volume, py::arg("voxel_mm") = defaults.voxel_mm,
      py::arg("cor_offset_mm") = py::none(), py::arg("ring_filter") = defaults.ring_filter,
      py::arg("held_out") = defaults.held_out, py::arg("accept_failed_capture") = false,
      py::arg("progress") = py::none(),
      "Tomography on a turntable run or a projection folder, as `photorig solve tomography`: volume "
      "(nz, ny, nx) float32 attenuation in 1/mm, and summary, report.json's fields. Options are the recipe's "
      "tomography keys.");
}

}  // namespace photorig::python
