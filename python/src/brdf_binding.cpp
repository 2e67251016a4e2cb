// photorig.read_merl, write_merl, eval_brdf and fit_brdf: measured-BRDF
// tables and samples through the solver's own readers, writers and fits
// (solvers/brdf/merl.h, measured.h, samples.h, table_fit.h), as `photorig
// brdf eval`, `convert` and `fit` use them; solve_brdf: `photorig solve brdf
// --run` in-process, through the same pipeline (brdf_solve.h).

#include "arrays.h"
#include "bindings.h"
#include "choices.h"
#include "run.h"
#include "photorig/daemon/pipelines/brdf_solve.h"
#include "photorig/daemon/pipelines/internal/brdf_report.h"
#include "photorig/solvers/brdf/measured.h"
#include "photorig/solvers/brdf/merl.h"
#include "photorig/solvers/brdf/samples.h"
#include "photorig/solvers/brdf/table_fit.h"

#include <pybind11/stl.h>  // std::optional options

#include <cmath>
#include <filesystem>
#include <limits>
#include <memory>

namespace photorig::python {
namespace {

namespace brdf = solvers::brdf;
using Table = brdf::MerlTable;

// (3, theta_h, theta_d, phi_d) in 1/sr, NaN where a cell is not measured.
py::array_t<double> ReadMerl(const std::string& path) {
  Table table;
  brdf::MerlReadSummary read;
  {
    py::gil_scoped_release unlocked;
    read = brdf::ReadMerl(path, &table);
  }
  if (!read.IsSolutionUsable()) throw py::value_error(read.message);
  py::array_t<double> values({3, Table::kThetaHBins, Table::kThetaDBins, Table::kPhiDBins});
  double* out = values.mutable_data();
  for (int c = 0; c < 3; ++c)
    for (std::size_t cell = 0; cell < Table::kCells; ++cell) {
      const double stored = table.plane(c)[cell];
      out[c * Table::kCells + cell] = stored < 0.0 ? std::numeric_limits<double>::quiet_NaN() : stored * Table::kChannelScale[c];
    }
  return values;
}

using TableArray = py::array_t<double, py::array::c_style | py::array::forcecast>;

// read_merl's layout as a table (NaN: a cell not measured).
void ToTable(const TableArray& values, Table* table) {
  if (values.ndim() != 4 || values.shape(0) != 3 || values.shape(1) != Table::kThetaHBins ||
      values.shape(2) != Table::kThetaDBins || values.shape(3) != Table::kPhiDBins)
    throw py::value_error("a MERL table is (3, 90, 90, 180): R, G, B over theta_h, theta_d, phi_d");
  const double* in = values.data();
  for (std::size_t cell = 0; cell < Table::kCells; ++cell) {
    const Eigen::Vector3d value(in[cell], in[Table::kCells + cell], in[2 * Table::kCells + cell]);
    if (value.array().isNaN().any()) {
      table->SetCellInvalid(cell);
      continue;
    }
    // The file marks a cell not measured by a negative value: a negative
    // value given here would come back as a hole.
    for (int c = 0; c < 3; ++c)
      if (value[c] < 0.0) {
        const std::size_t per_h = std::size_t{Table::kThetaDBins} * Table::kPhiDBins;
        throw py::value_error("values[" + std::to_string(c) + ", " + std::to_string(cell / per_h) + ", " +
                              std::to_string(cell % per_h / Table::kPhiDBins) + ", " +
                              std::to_string(cell % Table::kPhiDBins) + "] is " + std::to_string(value[c]) +
                              ": a BRDF is not negative (NaN marks a cell not measured)");
      }
    table->SetCell(cell, value);
  }
}

void WriteMerl(const std::string& path, const TableArray& values) {
  // eval_brdf, fit_brdf and `photorig brdf` know a table's format by its name.
  if (brdf::TableFormatOf(path) != brdf::TableFormat::kMerl)
    throw py::value_error("'" + path + "': a MERL table is written as a .binary file");
  Table table;
  ToTable(values, &table);
  py::gil_scoped_release unlocked;
  if (const solvers::core::Summary written = brdf::WriteMerl(path, table); !written.IsSolutionUsable())
    throw py::value_error(written.message);
}

// f_r in 1/sr per channel for each row of wi and wo (unit vectors, (n, 3));
// NaN rows below the horizon or where the table has no value.
py::array_t<double> EvalBrdf(const std::string& path,
                             const py::array_t<double, py::array::c_style | py::array::forcecast>& wi,
                             const py::array_t<double, py::array::c_style | py::array::forcecast>& wo) {
  if (wi.ndim() != 2 || wi.shape(1) != 3 || wo.ndim() != 2 || wo.shape(1) != 3 || wi.shape(0) != wo.shape(0))
    throw py::value_error("wi and wo must be (n, 3) arrays of unit vectors, n alike");
  brdf::MeasuredBrdf table;
  if (const solvers::core::Summary read = brdf::ReadMeasured(path, &table); !read.IsSolutionUsable())
    throw py::value_error(read.message);
  const py::ssize_t n = wi.shape(0);
  py::array_t<double> f({n, py::ssize_t{3}});
  const auto a = wi.unchecked<2>();
  const auto b = wo.unchecked<2>();
  auto out = f.mutable_unchecked<2>();
  for (py::ssize_t i = 0; i < n; ++i) {
    const std::optional<Eigen::Vector3d> value =
        table(Eigen::Vector3d(a(i, 0), a(i, 1), a(i, 2)), Eigen::Vector3d(b(i, 0), b(i, 1), b(i, 2)));
    for (int c = 0; c < 3; ++c) out(i, c) = value ? (*value)[c] : std::numeric_limits<double>::quiet_NaN();
  }
  return f;
}

// A table as `photorig brdf fit` reads it: a .binary or .bsdf path, or read_merl's array.
brdf::MeasuredBrdf MeasuredOf(const py::object& table_or_path, nlohmann::json* doc) {
  if (py::isinstance<py::array>(table_or_path)) {
    auto table = std::make_shared<Table>();
    ToTable(table_or_path.cast<TableArray>(), table.get());
    (*doc)["format"] = brdf::TableFormatName(brdf::TableFormat::kMerl);
    return [table](const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) { return table->Evaluate(wi, wo); };
  }
  const std::string path = py::str(table_or_path);
  brdf::MeasuredBrdf table;
  if (const solvers::core::Summary read = brdf::ReadMeasured(path, &table); !read.IsSolutionUsable())
    throw py::value_error(read.message);
  (*doc)["file"] = path;
  (*doc)["format"] = brdf::TableFormatName(*brdf::TableFormatOf(path));
  return table;
}

// report.json of `photorig brdf fit` (`doc`) as `summary`, with the chosen
// model and its candidate's entry (parameters and their deviations) beside it.
py::dict FittedOf(const brdf::SelectionSummary& selection, const nlohmann::json& doc) {
  py::dict out;
  out["model"] = py::none();
  out["parameters"] = py::none();
  if (selection.chosen) {
    out["model"] = brdf::ModelName(*selection.chosen);
    out["parameters"] = ToPython(doc["candidates"][selection.chosen_index]);
  }
  out["summary"] = ToPython(doc);
  return out;
}

// A gonioreflectometer's samples.csv (`photorig solve brdf`'s), fitted as
// `photorig brdf fit samples.csv` fits it: weighted by the samples' deviations
// unless `loss` says otherwise.
py::dict FitSamples(const std::string& path, const std::optional<std::string>& loss) {
  brdf::SelectionOptions options;
  if (loss) options.fit.loss = ParseChoice(brdf::kFitLossNames, *loss, "loss");
  if (std::string why; !options.IsValid(&why)) throw py::value_error(why);
  std::vector<brdf::BrdfSample> samples;
  if (const solvers::core::Summary read = brdf::ReadSamplesCsv(path, &samples); !read.IsSolutionUsable())
    throw py::value_error(read.message);
  if (samples.empty()) throw py::value_error(path + ": no measured value to fit");
  brdf::SelectionSummary selection;
  {
    py::gil_scoped_release unlocked;
    selection = brdf::SelectModel(samples, options);
  }
  // Refused samples (NaN values, a negative deviation, a zero direction) raise, as a refused table does.
  if (selection.termination == solvers::core::Termination::kInvalidInput) throw py::value_error(path + ": " + selection.message);
  nlohmann::json doc = {{"file", path},
                        {"format", "samples"},
                        {"loss", brdf::FitLossName(options.fit.loss)},
                        {"samples", samples.size()}};
  doc.update(daemon::SelectionJson(selection));
  return FittedOf(selection, doc);
}

// fit_brdf: a table's fit, or FitSamples for a .csv path.
py::dict FitBrdf(const py::object& table_or_path, const std::optional<std::string>& loss, std::size_t samples) {
  if (!py::isinstance<py::array>(table_or_path)) {
    const std::string path = py::str(table_or_path);
    if (std::filesystem::path(path).extension() == ".csv") return FitSamples(path, loss);
  }
  brdf::TableFitOptions options;
  if (loss) options.selection.fit.loss = ParseChoice(brdf::kFitLossNames, *loss, "loss");
  options.samples = samples;
  if (std::string why; !options.IsValid(&why)) throw py::value_error(why);
  nlohmann::json doc;
  const brdf::MeasuredBrdf table = MeasuredOf(table_or_path, &doc);
  doc["loss"] = brdf::FitLossName(options.selection.fit.loss);
  brdf::TableFitSummary fit;
  {
    py::gil_scoped_release unlocked;
    fit = brdf::FitTable(table, options);
  }
  if (fit.termination == solvers::core::Termination::kInvalidInput) throw py::value_error(fit.message);
  doc["samples"] = fit.samples;
  doc.update(daemon::SelectionJson(fit.selection));
  daemon::AddTableFitJson(fit, &doc);
  return FittedOf(fit.selection, doc);
}

// A gonioreflectometer run measured and fitted as `photorig solve brdf` does
// it, its results folder written as the CLI writes it.
py::dict SolveBrdf(const py::object& run, const std::string& loss, const std::string& calibration,
                   const std::optional<std::string>& out, bool accept_failed_capture) {
  const std::string run_directory = RunDirectory(run);
  config::BrdfRequest request;
  request.loss = ParseChoice(brdf::kFitLossNames, loss, "loss");
  request.calibrate_with_target = ParseChoice(config::BrdfRequest::kCalibrationNames, calibration, "calibration");
  const std::string destination = ResultsFolder(run_directory, out, "brdf");
  daemon::BrdfSolveResult result;
  {
    py::gil_scoped_release unlocked;
    result = daemon::SolveBrdfAndWrite(run_directory, request, destination, FailedCapturePolicy(accept_failed_capture));
  }
  if (result.refused_input()) throw py::value_error(result.measurement.message);
  py::dict solved;
  solved["summary"] = ToPython(result.report);
  solved["directory"] = result.results;
  solved["model"] = py::none();
  solved["parameters"] = py::none();
  if (result.selection && result.selection->chosen) {
    solved["model"] = brdf::ModelName(*result.selection->chosen);
    solved["parameters"] = ToPython(result.report["candidates"][result.selection->chosen_index]);
  }
  // The samples as samples.csv holds them: wi, wo (n, 3) and f_r, sigma (n, 3) in 1/sr.
  const std::vector<brdf::BrdfSample>& samples = result.measurement.samples;
  const py::ssize_t n = static_cast<py::ssize_t>(samples.size());
  py::array_t<double> wi({n, py::ssize_t{3}}), wo({n, py::ssize_t{3}}), value({n, py::ssize_t{3}}),
      sigma({n, py::ssize_t{3}});
  for (py::ssize_t i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) {
      wi.mutable_at(i, c) = samples[i].wi[c], wo.mutable_at(i, c) = samples[i].wo[c];
      value.mutable_at(i, c) = samples[i].value[c], sigma.mutable_at(i, c) = samples[i].sigma[c];
    }
  solved["wi"] = wi, solved["wo"] = wo, solved["value"] = value, solved["sigma"] = sigma;
  return solved;
}

}  // namespace

void BindBrdf(py::module_& m) {
  m.def("read_merl", &ReadMerl, py::arg("path"),
        "A MERL .binary as (3, 90, 90, 180) float64 R, G, B in 1/sr over (theta_h, theta_d, phi_d) bins; "
        "NaN where a cell is not measured. ValueError with the reader's message for a bad file.");
  m.def("write_merl", &WriteMerl, py::arg("path"), py::arg("values"),
        "Writes read_merl's layout as a MERL .binary (NaN: a cell not measured).");
  m.def("eval_brdf", &EvalBrdf, py::arg("path"), py::arg("wi"), py::arg("wo"),
        "A MERL .binary's or RGL .bsdf's f_r (1/sr, R, G, B) for each row of wi (towards the light) and wo "
        "(towards the camera), as `photorig brdf eval`: (n, 3), NaN rows where it has no value.");
  m.def("fit_brdf", &FitBrdf, py::arg("table"), py::kw_only(),
        py::arg("loss") = py::none(),
        py::arg("samples") = brdf::TableFitOptions().samples,
        "Fits BRDF models to a measured table (a .binary or .bsdf path, or read_merl's array) or to a "
        "gonioreflectometer's samples.csv and chooses one, as `photorig brdf fit`: model (the chosen one's name, or "
        "None), parameters (its report entry) and summary, report.json's fields. Options are the CLI's (loss: None "
        "for log on a table, which carries no deviations, and weighted on samples; samples: a table's cells the "
        "fits see).");
  const config::BrdfRequest defaults;
  m.def("solve_brdf", &SolveBrdf, py::arg("run"), py::kw_only(), py::arg("loss") = brdf::FitLossName(defaults.loss),
        py::arg("calibration") = solvers::core::NameOf(config::BrdfRequest::kCalibrationNames,
                                                       defaults.calibrate_with_target),
        py::arg("out") = py::none(), py::arg("accept_failed_capture") = false,
        "A gonioreflectometer run (a Run or its directory) measured and fitted as `photorig solve brdf --run`, "
        "which writes results/brdf (or `out`) as the CLI does: model (the chosen one's name, or None), parameters "
        "(its report entry), the samples (wi, wo, value and sigma, (n, 3) each, f_r in 1/sr), directory and "
        "summary, report.json's fields. Options are the CLI's (loss: weighted | log; calibration: reference | "
        "camera). ValueError for options or run data the solve refuses.");
}

}  // namespace photorig::python
