// photorig solve --from RESULT --out DIR [--run DIR]
// RESULT: a report.json, the results folder holding it, or a NeXus file's
// NXprocess as FILE::/entry/NAME (silx's notation).

#include "../command.h"
#include "../command_output.h"
#include "photorig/config/yaml_node.h"
#include "photorig/daemon/io/nexus.h"
#include "photorig/daemon/pipelines/brdf_solve.h"
#include "photorig/daemon/pipelines/provenance.h"
#include "photorig/daemon/pipelines/ps_pipeline.h"
#include "photorig/daemon/pipelines/tomography_pipeline.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace photorig::app {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct Options {
  std::string from, run_dir, out;
};

json ParseJson(const std::string& text, const std::string& source) {
  const json doc = json::parse(text, nullptr, false);
  if (doc.is_discarded()) throw std::invalid_argument(source + " is not JSON");
  return doc;
}

// The provenance a report.json or a NeXus NXprocess records.
daemon::Provenance LoadProvenance(const std::string& from) {
  if (const auto at = from.find("::"); at != std::string::npos) {
    const std::string file = from.substr(0, at), group = from.substr(at + 2);
    const auto text = [&](const std::string& field) {
      std::string value, error;
      if (!daemon::ReadNexusText(file, group + "/" + field, &value, &error))
        throw std::invalid_argument(error + " (is " + group + " an NXprocess photorig wrote?)");
      return value;
    };
    const json doc = {{"program", text("program")},
                      {"version", text("version")},
                      {"date", text("date")},
                      {"options", ParseJson(text("options/data"), from + "/options")},
                      {"inputs", ParseJson(text("input_checksums/data"), from + "/input_checksums")}};
    return daemon::ProvenanceFromJson(doc, from);
  }
  const fs::path report = fs::is_directory(from) ? fs::path(from) / "report.json" : fs::path(from);
  std::ifstream in(report);
  if (!in) throw std::invalid_argument("cannot read " + report.string() + ": give a report.json, its folder or FILE::/entry/NAME");
  const json doc = ParseJson({std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()}, report.string());
  return daemon::ProvenanceFromJson(doc.value("provenance", json()), report.string());
}

// Empty when `run` holds the manifest and frames the provenance records; else why not.
std::string CheckInputs(const daemon::Provenance& provenance, const std::string& run) {
  const json now = daemon::RunInputs(run);
  for (const char* key : {"manifest_fnv1a64", "frames", "frames_crc32_fnv1a64"})
    if (now.value(key, json()) != provenance.inputs.value(key, json()))
      return run + " is not the run the result was solved from: its " + key + " is " + now.value(key, json()).dump() +
             ", the result records " + provenance.inputs.value(key, json()).dump() +
             "; give --run with the run it was solved from";
  return "";
}

// Solves again into `out`; returns whether the result is usable, its report in *fields.
bool SolveAgain(const daemon::Provenance& provenance, const std::string& run, const std::string& out, json* fields) {
  const json& loading = provenance.options["loading"];
  const config::YamlNode request =
      config::YamlNode::LoadString(provenance.options["request"].dump(), "the recorded request");
  const daemon::FailedCapture failed =
      loading.value("accept_failed_capture", false) ? daemon::FailedCapture::kAccept : daemon::FailedCapture::kRefuse;
  const std::string stage = provenance.stage();
  if (stage == "photometric_stereo") {
    daemon::ColorStackOptions color;
    const std::string demosaic = loading.value("demosaic", "bilinear");
    const auto method = solvers::core::ParseName(solvers::color::kDemosaicMethodNames, demosaic);
    if (!method) throw std::invalid_argument("the recorded demosaic '" + demosaic + "' is none this photorig knows");
    color.demosaic = *method;
    color.color_model_path = loading.value("color_model", "");
    daemon::PhotometricStereoInput input = daemon::LoadRunStack(run, color, failed);
    if (loading.contains("mask")) daemon::SetObjectMaskFromFile(loading["mask"].get<std::string>(), &input);
    const daemon::PhotometricStereoResult result =
        daemon::SolveAndWrite(input, config::ParsePhotometricStereoRequest(request), out);
    *fields = daemon::ToJson(result);
    return result.usable();
  }
  if (stage == "brdf") {
    const daemon::BrdfSolveResult result = daemon::SolveBrdfAndWrite(run, config::ParseBrdfRequest(request), out, failed);
    *fields = result.report;
    return result.usable();
  }
  if (stage == "tomography") {
    const daemon::TomographyInput input = daemon::LoadTomographyRun(run, failed);
    const daemon::TomographyResult result = daemon::SolveTomography(input, config::ParseTomographyRequest(request));
    daemon::WriteTomographyResults(input, result, out);
    *fields = result.ToJson();
    return result.trusted();
  }
  throw std::invalid_argument("a " + stage + " solve is not repeated by solve --from (photometric_stereo, brdf and "
                              "tomography are)");
}

int Execute(const Options& options) {
  if (options.from.empty()) return Fail(kExitUsage, "give a solver (photorig solve --help) or --from RESULT");
  if (options.out.empty()) return Fail(kExitUsage, "give --out DIR: the folder for the repeated solve's results");
  const daemon::Provenance provenance = LoadProvenance(options.from);
  const std::string run = options.run_dir.empty() ? provenance.inputs.value("run", "") : options.run_dir;
  if (run.empty())
    return Fail(kExitUsage, options.from + " was solved from a folder that is no run (" +
                                provenance.inputs.dump() + "): solve --from repeats solves of runs");
  if (const std::string why = CheckInputs(provenance, run); !why.empty()) return Fail(kExitUsage, why);
  std::printf("solving %s again as %s %s did on %s: %s\n", provenance.stage().c_str(), provenance.program.c_str(),
              provenance.version.c_str(), provenance.date.c_str(), provenance.options["request"].dump().c_str());
  json fields;
  const bool usable = SolveAgain(provenance, run, options.out, &fields);
  std::printf("results: %s/\n", options.out.c_str());
  ResultFields() = {{"from", options.from},
                    {"stage", provenance.stage()},
                    {"run_directory", run},
                    {"results_directory", options.out},
                    {"report", fields}};
  if (!usable) return Fail(kExitFailed, "the repeated solve has no usable result; its report is in " + options.out);
  return kExitOk;
}

CLI::App* Setup(CLI::App& app, Options* options) {
  CLI::App* solve = SolveGroup(app);
  // `solve --from` runs without a solver's subcommand: the result names it.
  solve->require_subcommand(0, 1);
  solve->add_option("--from", options->from,
                    "repeat the solve that made RESULT (a report.json, its folder, or FILE.nxs::/entry/NAME)");
  solve->add_option("--run", options->run_dir, "with --from: the run, when it has moved (default: where it was)")
      ->check(CLI::ExistingDirectory);
  solve->add_option("--out", options->out, "with --from: the folder for the results");
  return solve;
}

const bool registered = RegisterCommand<Options, Setup, Execute>();

}  // namespace
}  // namespace photorig::app
