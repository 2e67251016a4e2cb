// photorig brdf fit FILE [--loss weighted|log] [--samples N] [--out DIR [--keep-table]]
// photorig brdf eval FILE --wi THETA PHI --wo THETA PHI
// photorig brdf convert IN OUT [--model NAME] [--ndf-roughness A]
//   (--json as every command: docs/cli.md)
//
// Measured-BRDF files: MERL .binary and EPFL RGL .bsdf tables, and the
// samples.csv of `photorig solve brdf`. A table is read through one
// evaluation (solvers/brdf/measured.h) whatever its format; `fit` draws cells
// from it where it has energy and structure (solvers/brdf/table_fit.h), hands
// them to the same model selection, and the same report, as a
// gonioreflectometer run's samples, and reports each model's error over all
// cells.
// `convert` also tabulates a fitted model (a fit's report.json, or one
// model's JSON) for renderers that read tables.

#include "../command.h"
#include "../command_output.h"
#include "photorig/daemon/pipelines/internal/brdf_report.h"
#include "photorig/solvers/brdf/measured.h"
#include "photorig/solvers/brdf/merl.h"
#include "photorig/solvers/brdf/rgl.h"
#include "photorig/solvers/brdf/table_fit.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

namespace photorig::app {
namespace {

namespace brdf = photorig::solvers::brdf;
namespace fs = std::filesystem;

constexpr double kDeg = M_PI / 180.0;

struct Options {
  std::string file, out;
  std::optional<brdf::FitLoss> loss;  // default: log for a table, weighted for samples
  std::size_t samples = brdf::TableFitOptions().samples;
  bool keep_table = false;
  std::vector<double> wi_deg, wo_deg;
  std::string convert_to;
  std::string model;  // convert from a report: which candidate (default: the chosen one)
  double ndf_roughness = 0.5;
};

nlohmann::json Vec(const Eigen::Vector3d& v) { return {v[0], v[1], v[2]}; }

bool IsCsv(const std::string& path) { return fs::path(path).extension() == ".csv"; }

int Fit(const Options& o) {
  nlohmann::json doc = {{"file", o.file}};
  auto finish = [&](ExitCode code, const std::string& error) {
    ResultFields() = doc;
    return error.empty() ? static_cast<int>(code) : Fail(code, error);
  };
  const bool csv = IsCsv(o.file);
  if (o.keep_table && (csv || o.out.empty())) return finish(kExitUsage, "--keep-table needs a table and --out");
  // A table carries no deviations: the log loss; samples with deviations are weighted by them.
  const brdf::FitLoss loss = o.loss.value_or(csv ? brdf::FitLoss::kWeighted : brdf::FitLoss::kLog);
  if (!csv && loss != brdf::FitLoss::kLog) return finish(kExitUsage, "a table carries no deviations: fit it with --loss log");
  doc["loss"] = brdf::FitLossName(loss);
  std::vector<brdf::BrdfSample> samples;
  std::optional<brdf::TableFitSummary> table_fit;
  FILE* text = stdout;  // under --json main points it at stderr
  if (csv) {
    const solvers::core::Summary read = brdf::ReadSamplesCsv(o.file, &samples);
    if (!read.IsSolutionUsable()) return finish(kExitUsage, read.message);
    doc["format"] = "samples";
    doc["samples"] = samples.size();
    if (samples.empty()) return finish(kExitFailed, o.file + ": no measured value to fit");
  } else {
    brdf::MeasuredBrdf table;
    const solvers::core::Summary read = brdf::ReadMeasured(o.file, &table);
    if (!read.IsSolutionUsable()) return finish(kExitUsage, read.message);
    doc["format"] = brdf::TableFormatName(*brdf::TableFormatOf(o.file));
    brdf::TableFitOptions options;
    options.samples = o.samples;
    table_fit = brdf::FitTable(table, options);
    doc["samples"] = table_fit->samples;
    if (table_fit->termination == solvers::core::Termination::kInvalidInput)
      return finish(kExitFailed, o.file + ": " + table_fit->message);
  }
  brdf::SelectionSummary s;
  if (table_fit) {
    s = table_fit->selection;
  } else {
    brdf::SelectionOptions selection;
    selection.fit.loss = loss;
    s = brdf::SelectModel(samples, selection);
  }
  doc.update(daemon::SelectionJson(s));
  if (table_fit) {
    daemon::AddTableFitJson(*table_fit, &doc);
    std::fprintf(text, "%zu cells of %zu drawn from %s (%s loss), closest theta_h %.3f deg\n", table_fit->samples,
                 table_fit->cells, o.file.c_str(), brdf::FitLossName(loss), s.min_theta_h_deg);
  } else {
    std::fprintf(text, "%zu samples from %s (%s loss), closest theta_h %.2f deg\n", samples.size(), o.file.c_str(),
                 brdf::FitLossName(loss), s.min_theta_h_deg);
  }
  daemon::PrintSelection(text, s);
  if (table_fit) {
    std::fprintf(text, "over all %zu cells (log RMS, reported / all cells, cosine-weighted RMS of f_r in 1/sr):\n",
                 table_fit->cells);
    for (std::size_t c = 0; c < s.candidates.size(); ++c)
      std::fprintf(text, "  %-15s %8.4f  %6.3f  %8.4f\n", brdf::ModelName(s.candidates[c].params.model),
                   table_fit->all_cells[c].log_rms, table_fit->reported_over_all_cells[c],
                   table_fit->all_cells[c].neutral_rms);
    if (!table_fit->warning.empty()) std::fprintf(text, "warning: %s\n", table_fit->warning.c_str());
  }
  if (!o.out.empty()) {
    fs::create_directories(o.out);
    if (o.keep_table) {
      // The measured table itself is the material; the fits stay in the report.
      const fs::path kept = fs::path(o.out) / ("material" + fs::path(o.file).extension().string());
      std::error_code error;
      fs::copy_file(o.file, kept, fs::copy_options::overwrite_existing, error);
      if (error) return finish(kExitFailed, "cannot copy the table to " + kept.string() + ": " + error.message());
      doc["material"] = {{"kind", "table"}, {"file", kept.filename().string()}};
      std::fprintf(text, "material: the measured table (%s)\n", kept.string().c_str());
    } else if (s.chosen) {
      doc["material"] = {{"kind", "model"}, {"model", brdf::ModelName(*s.chosen)}};
    }
    std::ofstream(fs::path(o.out) / "report.json") << doc.dump(2) << "\n";
    if (csv) {
      const solvers::core::Summary written = brdf::WriteSamplesCsv((fs::path(o.out) / "samples.csv").string(), samples);
      if (!written.IsSolutionUsable()) return finish(kExitFailed, written.message);
    }
    doc["results"] = o.out;
    std::fprintf(text, "results: %s/\n", o.out.c_str());
  }
  // With the table kept, the material does not depend on a model being chosen.
  const bool ok = s.IsSolutionUsable() || o.keep_table;
  return finish(ok ? kExitOk : kExitFailed, ok ? "" : s.message);
}

Eigen::Vector3d Direction(const std::vector<double>& theta_phi_deg) {
  const double t = theta_phi_deg[0] * kDeg, p = theta_phi_deg[1] * kDeg;
  return {std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t)};
}

int Eval(const Options& o) {
  nlohmann::json doc = {{"file", o.file}, {"wi_deg", o.wi_deg}, {"wo_deg", o.wo_deg}};
  auto finish = [&](ExitCode code, const std::string& error) {
    ResultFields() = doc;
    return error.empty() ? static_cast<int>(code) : Fail(code, error);
  };
  brdf::MeasuredBrdf table;
  const solvers::core::Summary read = brdf::ReadMeasured(o.file, &table);
  if (!read.IsSolutionUsable()) return finish(kExitUsage, read.message);
  doc["format"] = brdf::TableFormatName(*brdf::TableFormatOf(o.file));
  const std::optional<Eigen::Vector3d> f = table(Direction(o.wi_deg), Direction(o.wo_deg));
  if (!f) return finish(kExitFailed, "no value there: below the horizon or not measured");
  doc["f_r"] = Vec(*f);
  std::printf("f_r = %.6g %.6g %.6g 1/sr\n", (*f)[0], (*f)[1], (*f)[2]);
  return finish(kExitOk, "");
}

int Convert(const Options& o) {
  nlohmann::json doc = {{"file", o.file}, {"out", o.convert_to}};
  auto finish = [&](ExitCode code, const std::string& error) {
    ResultFields() = doc;
    return error.empty() ? static_cast<int>(code) : Fail(code, error);
  };
  const std::optional<brdf::TableFormat> to = brdf::TableFormatOf(o.convert_to);
  if (!to) return finish(kExitUsage, "'" + o.convert_to + "': the output must end in .binary (MERL) or .bsdf (RGL)");
  brdf::MeasuredBrdf table;
  if (fs::path(o.file).extension() == ".json") {
    // A fitted model: its f_r wherever both directions are above the horizon.
    std::ifstream in(o.file);
    if (!in) return finish(kExitUsage, "'" + o.file + "': cannot open the file");
    const nlohmann::json spec = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
    if (spec.is_discarded()) return finish(kExitUsage, "'" + o.file + "': not valid JSON");
    brdf::ModelParams params;
    if (std::string why; !daemon::ModelFromJson(spec, o.model, &params, &why)) return finish(kExitUsage, "'" + o.file + "': " + why);
    doc["model"] = brdf::ModelName(params.model);
    table = [params](const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) -> std::optional<Eigen::Vector3d> {
      if (wi.z() <= 0.0 || wo.z() <= 0.0) return std::nullopt;
      return brdf::Evaluate(params, wi, wo);
    };
  } else {
    if (!o.model.empty()) return finish(kExitUsage, "--model names a candidate of a fit report (.json)");
    const solvers::core::Summary read = brdf::ReadMeasured(o.file, &table);
    if (!read.IsSolutionUsable()) return finish(kExitUsage, read.message);
  }
  solvers::core::Summary written;
  if (*to == brdf::TableFormat::kMerl) {
    written = brdf::WriteMerl(o.convert_to, brdf::MerlTable::FromFunction(
                                                [&](const brdf::DirectionPair& d) { return table(d.wi, d.wo); }));
  } else {
    brdf::RglTabulation tab;
    tab.ndf_roughness = o.ndf_roughness;
    tab.description = "converted by photorig from " + fs::path(o.file).filename().string();
    brdf::TensorFile file;
    // An unmeasured configuration has no value in the RGB table: zero there.
    written = brdf::TabulateRgl(
        [&](const brdf::DirectionPair& d) { return table(d.wi, d.wo).value_or(Eigen::Vector3d::Zero()); }, tab,
        &file);
    if (written.IsSolutionUsable()) written = brdf::WriteTensorFile(o.convert_to, file);
  }
  if (!written.IsSolutionUsable()) return finish(written.termination == solvers::core::Termination::kInvalidOptions ? kExitUsage : kExitFailed, written.message);
  std::printf("wrote %s\n", o.convert_to.c_str());
  return finish(kExitOk, "");
}

CLI::App* Group(CLI::App& app) { return SubcommandGroup(app, "brdf", "measured-BRDF files: fit, evaluate, convert"); }

CLI::App* SetupFit(CLI::App& app, Options* options) {
  CLI::App* fit = Group(app)->add_subcommand("fit", "fit BRDF models to a MERL or RGL table, or to samples.csv, and choose one");
  fit->add_option("file", options->file, "a .binary, .bsdf or samples .csv file")->required();
  fit->add_option_function<std::string>(
         "--loss", [options](const std::string& name) { options->loss = solvers::core::ParseName(brdf::kFitLossNames, name); },
         "weighted | log (default: log for a table, weighted for samples)")
      ->check(CLI::IsMember(solvers::core::NameMap(brdf::kFitLossNames)));
  fit->add_option("--samples", options->samples,
                  "a table's cells the fits see, drawn where it has energy and structure (default 20000)")
      ->check(CLI::Range(100, 1000000));
  fit->add_option("--out", options->out, "write report.json (and, for samples.csv, the samples fitted)");
  fit->add_flag("--keep-table", options->keep_table,
                "with --out: keep the measured table as the material (material.binary|.bsdf), the fits reported beside it");
  return fit;
}

CLI::App* SetupEval(CLI::App& app, Options* options) {
  CLI::App* eval = Group(app)->add_subcommand("eval", "a table's f_r at one configuration");
  eval->add_option("file", options->file, "a .binary or .bsdf file")->required();
  eval->add_option("--wi", options->wi_deg, "towards the light: theta phi in degrees")->expected(2)->required();
  eval->add_option("--wo", options->wo_deg, "towards the camera: theta phi in degrees")->expected(2)->required();
  return eval;
}

CLI::App* SetupConvert(CLI::App& app, Options* options) {
  CLI::App* convert = Group(app)->add_subcommand(
      "convert", "a table from one format to the other (.binary <-> .bsdf), or a fitted model to a table");
  convert->add_option("in", options->file, "a .binary or .bsdf file, a fit's report.json or one model's .json")
      ->required();
  convert->add_option("--model", options->model,
                      "from a report: the candidate to tabulate (default: the chosen one), e.g. ggx");
  convert->add_option("out", options->convert_to, "the file to write: .binary or .bsdf")->required();
  convert->add_option("--ndf-roughness", options->ndf_roughness,
                      "to .bsdf: the GGX roughness of the parameterising NDF (default 0.5)")
      ->check(CLI::Range(1e-3, 1.0));
  return convert;
}

const bool registered_fit = RegisterCommand<Options, SetupFit, Fit>();
const bool registered_eval = RegisterCommand<Options, SetupEval, Eval>();
const bool registered_convert = RegisterCommand<Options, SetupConvert, Convert>();

}  // namespace
}  // namespace photorig::app
