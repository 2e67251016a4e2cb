// photorig.solve_svbrdf: `photorig solve svbrdf --run` in-process, through the
// same pipeline (svbrdf_pipeline.h's SolveSvbrdfAndWrite), which writes its
// results folder as the CLI does; the maps come back as it wrote them.

#include "arrays.h"
#include "bindings.h"
#include "choices.h"
#include "photorig/daemon/pipelines/svbrdf_pipeline.h"
#include "progress.h"
#include "run.h"

#include <pybind11/stl.h>  // std::optional options

namespace photorig::python {
namespace {

namespace refl = solvers::reflectance;

// The request the CLI builds from its flags, refused with the solvers' own
// messages where the CLI's flags would refuse it.
config::SvbrdfRequest SvbrdfRequestOf(const std::string& method, int max_materials, int held_out,
                                      bool refine_normals, bool export_gltf) {
  config::SvbrdfRequest request;
  request.ps.method = ParseChoice(solvers::ps::kMethodNames, method, "method");
  request.max_materials = max_materials;
  request.held_out_lights = held_out;
  request.refine_normals = refine_normals;
  request.export_gltf = export_gltf;
  if (std::string why; !request.IsValid(&why)) throw py::value_error(why);
  return request;
}

py::dict SolveSvbrdf(const py::object& run, const std::string& method, int max_materials, int held_out,
                     bool refine_normals, bool export_gltf, const std::optional<std::string>& mask,
                     const std::optional<std::string>& out, const std::string& demosaic, bool accept_failed_capture,
                     py::object progress) {
  const std::string run_directory = RunDirectory(run);
  config::SvbrdfRequest request = SvbrdfRequestOf(method, max_materials, held_out, refine_normals, export_gltf);
  daemon::ColorStackOptions color;
  color.demosaic = ParseChoice(solvers::color::kDemosaicMethodNames, demosaic, "demosaic");
  const std::string destination = ResultsFolder(run_directory, out, "svbrdf");
  ProgressBridge bridge(std::move(progress));
  request.progress = bridge.Callback();

  daemon::SvbrdfResult result;
  refl::ReflectanceMaps maps;
  {
    py::gil_scoped_release unlocked;
    daemon::PhotometricStereoInput input =
        daemon::LoadRunStack(run_directory, color, FailedCapturePolicy(accept_failed_capture));
    if (mask) daemon::SetObjectMaskFromFile(*mask, &input);
    result = daemon::SolveSvbrdfAndWrite(input, request, destination);
    // Read back as `photorig relight` reads them: the arrays are the files.
    if (result.usable()) maps = daemon::ReadSvbrdfResult(destination);
  }
  bridge.RethrowIfFailed();
  py::dict solved;
  solved["summary"] = ToPython(daemon::ToJson(result));
  solved["directory"] = destination;
  if (!result.usable()) return solved;
  solved["albedo"] = ToArray(maps.albedo);
  solved["material"] = ToArray(maps.material);
  solved["flags"] = ToArray(maps.flags);
  solved["normals"] = ToArray(maps.normals);
  return solved;
}

}  // namespace

void BindSvbrdf(py::module_& m) {
  const config::SvbrdfRequest defaults;
  m.def("solve_svbrdf", &SolveSvbrdf, py::arg("run"), py::kw_only(),
        py::arg("method") = solvers::ps::MethodName(defaults.ps.method),
        py::arg("max_materials") = defaults.max_materials, py::arg("held_out") = defaults.held_out_lights,
        py::arg("refine_normals") = defaults.refine_normals, py::arg("export_gltf") = defaults.export_gltf,
        py::arg("mask") = py::none(), py::arg("out") = py::none(), py::arg("demosaic") = "bilinear",
        py::arg("accept_failed_capture") = false, py::arg("progress") = py::none(),
        "Spatially varying reflectance of a run (a Run or its directory), as `photorig solve svbrdf --run`: "
        "writes the same results folder (out, default RUN/results/svbrdf) and returns a dict of arrays (albedo, "
        "material, flags, normals), summary, report.json's fields, and directory, the folder written. Options are "
        "the CLI's: method (photometric stereo's, for the normals), max_materials, held_out (-1 skips the check), "
        "refine_normals, export_gltf (`--no-gltf`), demosaic.");
}

}  // namespace photorig::python
