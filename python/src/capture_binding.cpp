// photorig.run_recipe: `photorig run` in-process (service/run.h's ExecuteRun),
// on a simulated or a real rig.

#include "arrays.h"
#include "bindings.h"
#include "photorig/daemon/service/run.h"
#include "progress.h"

#include <pybind11/stl.h>  // std::optional options

namespace photorig::python {

void BindCapture(py::module_& m) {
  m.def(
      "run_recipe",
      [](const std::string& recipe, const std::optional<std::string>& out, const std::optional<std::string>& rig,
         bool solve, py::object progress) {
        ProgressBridge bridge(std::move(progress));
        daemon::RunRequest request;
        request.recipe_path = recipe;
        request.rig_path = rig.value_or("");
        request.output_directory = out.value_or("");
        request.solve = solve;
        request.solve_progress = bridge.Callback();
        // Frames report as a stage of their own, "capture", through the same callback.
        if (request.solve_progress)
          request.on_frame = [report = request.solve_progress](const config::CaptureStep&, const daemon::FrameRecord&,
                                                               int frames, int total) {
            report({"capture", frames, total, {}});
          };
        daemon::RunOutcome outcome;
        {
          py::gil_scoped_release unlocked;
          outcome = daemon::ExecuteRun(request);
        }
        bridge.RethrowIfFailed();
        nlohmann::json stages = nlohmann::json::array();
        for (const daemon::SolveStageReport& stage : outcome.solve_stages) stages.push_back(stage.ToJson());
        py::dict result;
        result["directory"] = outcome.directory;
        result["capture"] = ToPython(daemon::ToJson(outcome.capture));
        result["solve_stages"] = ToPython(stages);
        return result;
      },
      py::arg("recipe"), py::kw_only(), py::arg("out") = py::none(), py::arg("rig") = py::none(),
      py::arg("solve") = true, py::arg("progress") = py::none(),
      "Captures a recipe on its rig (or `rig`) into `out` and runs its solve stages, as `photorig run`: "
      "directory, capture (status, frames_written, ...) and solve_stages. `progress(stage, done, total)` "
      "hears each frame as stage \"capture\", then the solvers' stages.");
}

}  // namespace photorig::python
