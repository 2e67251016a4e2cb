// photorig brdf fit FILE [--loss weighted|log] [--steps N] [--out DIR]
// photorig brdf eval FILE --wi THETA PHI --wo THETA PHI
// photorig brdf convert IN OUT [--model NAME] [--ndf-roughness A]
//   (--json as every command: docs/cli.md)
//
// Measured-BRDF files: MERL .binary and EPFL RGL .bsdf tables, and the
// samples.csv of `photorig solve brdf`. A table is read through one
// evaluation (solvers/brdf/measured.h) whatever its format; `fit` turns it into
// samples on a half/difference grid and hands them to the same model
// selection, and the same report, as a gonioreflectometer run's samples.
// `convert` also tabulates a fitted model (a fit's report.json, or one
// model's JSON) for renderers that read tables.

#include "../command.h"
#include "../command_output.h"
#include "photorig/daemon/pipelines/internal/brdf_report.h"
#include "photorig/solvers/brdf/measured.h"
#include "photorig/solvers/brdf/merl.h"
#include "photorig/solvers/brdf/rgl.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>

namespace photorig::app {
namespace {

namespace brdf = photorig::solvers::brdf;
namespace fs = std::filesystem;

constexpr double kDeg = M_PI / 180.0;

struct Options {
  std::string file, out;
  std::optional<brdf::FitLoss> loss;  // default: log for a table, weighted for samples
  int steps = 16;
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
  std::vector<brdf::BrdfSample> samples;
  if (IsCsv(o.file)) {
    const solvers::core::Summary read = brdf::ReadSamplesCsv(o.file, &samples);
    if (!read.IsSolutionUsable()) return finish(kExitUsage, read.message);
    doc["format"] = "samples";
  } else {
    brdf::MeasuredBrdf table;
    const solvers::core::Summary read = brdf::ReadMeasured(o.file, &table);
    if (!read.IsSolutionUsable()) return finish(kExitUsage, read.message);
    doc["format"] = brdf::TableFormatName(*brdf::TableFormatOf(o.file));
    samples = brdf::SampleMeasured(table, {o.steps, o.steps, o.steps});
  }
  // A table carries no deviations: the log loss unless told otherwise; samples
  // with deviations are weighted by them.
  const brdf::FitLoss loss = o.loss.value_or(IsCsv(o.file) ? brdf::FitLoss::kWeighted : brdf::FitLoss::kLog);
  doc["loss"] = brdf::FitLossName(loss);
  doc["samples"] = samples.size();
  if (samples.empty()) return finish(kExitFailed, o.file + ": no measured value to fit");
  brdf::SelectionOptions selection;
  selection.fit.loss = loss;
  const brdf::SelectionSummary s = brdf::SelectModel(samples, selection);
  doc.update(daemon::SelectionJson(s));
  FILE* text = stdout;  // under --json main points it at stderr
  std::fprintf(text, "%zu samples from %s (%s loss), closest theta_h %.2f deg\n", samples.size(), o.file.c_str(),
               brdf::FitLossName(loss), s.min_theta_h_deg);
  daemon::PrintSelection(text, s);
  if (!o.out.empty()) {
    fs::create_directories(o.out);
    std::ofstream(fs::path(o.out) / "report.json") << doc.dump(2) << "\n";
    const solvers::core::Summary written = brdf::WriteSamplesCsv((fs::path(o.out) / "samples.csv").string(), samples);
    if (!written.IsSolutionUsable()) return finish(kExitFailed, written.message);
    doc["results"] = o.out;
    std::fprintf(text, "results: %s/\n", o.out.c_str());
  }
  return finish(s.IsSolutionUsable() ? kExitOk : kExitFailed, s.IsSolutionUsable() ? "" : s.message);
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

CommandRunner SetupFit(CLI::App& app) {
  auto options = std::make_shared<Options>();
  CLI::App* fit = Group(app)->add_subcommand("fit", "fit BRDF models to a MERL or RGL table, or to samples.csv, and choose one");
  fit->add_option("file", options->file, "a .binary, .bsdf or samples .csv file")->required();
  fit->add_option_function<std::string>(
         "--loss", [options](const std::string& name) { options->loss = solvers::core::ParseName(brdf::kFitLossNames, name); },
         "weighted | log (default: log for a table, weighted for samples)")
      ->check(CLI::IsMember(solvers::core::NameMap(brdf::kFitLossNames)));
  fit->add_option("--steps", options->steps, "a table's samples per half/difference angle (default 16: 16^3 configurations)")
      ->check(CLI::Range(1, 200));
  fit->add_option("--out", options->out, "write report.json and the samples fitted here");
  return {fit, [options] { return Fit(*options); }};
}

CommandRunner SetupEval(CLI::App& app) {
  auto options = std::make_shared<Options>();
  CLI::App* eval = Group(app)->add_subcommand("eval", "a table's f_r at one configuration");
  eval->add_option("file", options->file, "a .binary or .bsdf file")->required();
  eval->add_option("--wi", options->wi_deg, "towards the light: theta phi in degrees")->expected(2)->required();
  eval->add_option("--wo", options->wo_deg, "towards the camera: theta phi in degrees")->expected(2)->required();
  return {eval, [options] { return Eval(*options); }};
}

CommandRunner SetupConvert(CLI::App& app) {
  auto options = std::make_shared<Options>();
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
  return {convert, [options] { return Convert(*options); }};
}

const bool registered_fit = RegisterCommand(SetupFit);
const bool registered_eval = RegisterCommand(SetupEval);
const bool registered_convert = RegisterCommand(SetupConvert);

}  // namespace
}  // namespace photorig::app
