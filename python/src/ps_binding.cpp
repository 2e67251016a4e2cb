// photorig.solve_ps: `photorig solve ps --run` in-process, through the same
// pipeline (ps_pipeline.h's LoadRunStack and SolveToMaps).

#include "arrays.h"
#include "bindings.h"
#include "choices.h"
#include "photorig/daemon/pipelines/ps_pipeline.h"
#include "progress.h"
#include "run.h"

#include <pybind11/stl.h>  // std::optional and std::array options

namespace photorig::python {
namespace {

py::dict SolvePs(const py::object& run, const std::string& method, const std::string& derivative,
                 const std::string& integrator, double shadow_threshold_sigma, double max_condition_number,
                 bool assume_distant, double max_distant_bias_deg, bool fill_unresolved,
                 const std::optional<std::string>& mask, const std::optional<std::string>& rig,
                 const std::string& demosaic, const std::optional<std::string>& color_model,
                 bool accept_failed_capture, py::object progress) {
  const std::string run_directory = RunDirectory(run);
  config::PhotometricStereoRequest request;
  request.method = ParseChoice(solvers::ps::kMethodNames, method, "method");
  request.derivative = ParseChoice(solvers::ps::kBlinnPhongDerivativeNames, derivative, "derivative");
  if (!config::ParseIntegratorChoice(integrator, &request.integrator))
    throw py::value_error("integrator must be one of poisson, frankot-chellappa or none, not \"" + integrator + "\"");
  request.shadow_threshold_sigma = shadow_threshold_sigma;
  request.max_condition_number = max_condition_number;
  request.assume_distant = assume_distant;
  request.max_distant_bias_deg = max_distant_bias_deg;
  request.fill_unresolved = fill_unresolved;
  if (std::string why; !request.IsValid(&why)) throw py::value_error(why);
  daemon::ColorStackOptions color;
  color.demosaic = ParseChoice(solvers::color::kDemosaicMethodNames, demosaic, "demosaic");
  color.color_model_path = color_model.value_or("");
  ProgressBridge bridge(std::move(progress));
  request.progress = bridge.Callback();

  daemon::PhotometricStereoMaps maps;
  daemon::PhotometricStereoResult result;
  {
    py::gil_scoped_release unlocked;
    daemon::PhotometricStereoInput input = daemon::LoadRunStack(
        run_directory, color, FailedCapturePolicy(accept_failed_capture));
    if (rig) daemon::ApplyRigCalibration(*rig, &input);
    if (mask) daemon::SetObjectMaskFromFile(*mask, &input);
    result = daemon::SolveToMaps(input, request, &maps);
  }
  bridge.RethrowIfFailed();
  py::dict out;
  out["summary"] = ToPython(daemon::ToJson(result));
  if (!result.usable()) return out;
  const solvers::ps::NormalMap& map = maps.map;
  out["normals"] = ToArray(map.normals);
  out["albedo"] = ToArray(maps.albedo_rgb.empty() ? map.albedo : maps.albedo_rgb);
  out["confidence"] = ToArray(map.confidence);
  out["flags"] = ToArray(map.flags);
  out["model"] = ToArray(map.model);
  out["specular"] = ToArray(map.specular);
  out["usable_lights"] = ToArray(map.usable_lights);
  if (!maps.depth.empty()) out["depth"] = ToArray(maps.depth);
  if (!maps.angular_error_deg.empty()) out["angular_error_deg"] = ToArray(maps.angular_error_deg);
  return out;
}

}  // namespace

void BindPs(py::module_& m) {
  const config::PhotometricStereoRequest defaults;
  m.def("solve_ps", &SolvePs, py::arg("run"), py::kw_only(),
        py::arg("method") = solvers::ps::MethodName(defaults.method),
        py::arg("derivative") = solvers::core::NameOf(solvers::ps::kBlinnPhongDerivativeNames, defaults.derivative),
        py::arg("integrator") = config::IntegratorChoiceName(defaults.integrator),
        py::arg("shadow_threshold_sigma") = defaults.shadow_threshold_sigma,
        py::arg("max_condition_number") = defaults.max_condition_number,
        py::arg("assume_distant") = defaults.assume_distant,
        py::arg("max_distant_bias_deg") = defaults.max_distant_bias_deg,
        py::arg("fill_unresolved") = defaults.fill_unresolved, py::arg("mask") = py::none(),
        py::arg("rig") = py::none(), py::arg("demosaic") = "bilinear", py::arg("color_model") = py::none(),
        py::arg("accept_failed_capture") = false, py::arg("progress") = py::none(),
        "Photometric stereo on a run (a Run or its directory), as `photorig solve ps --run`: a dict of arrays "
        "(normals, albedo, confidence, flags, model, specular, usable_lights, depth, angular_error_deg) and "
        "summary, report.json's fields. Options are the recipe's photometric_stereo keys; rig: a rig file whose LEDs "
        "and camera replace the run's (`--rig`, a calibration made after the capture).");
}

}  // namespace photorig::python
