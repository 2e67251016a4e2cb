#pragma once
// The short summaries of solver results that several commands print, and
// their JSON form (docs/cli.md).

#include "photorig/daemon/pipelines/light_calibration.h"
#include "photorig/daemon/pipelines/ps_pipeline.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <optional>

namespace photorig::app {
void PrintPhotometricStereoSummary(const daemon::PhotometricStereoResult& result);

// `--accept-failed-capture`, which every `solve <family> --run` takes: solve a
// run whose capture failed or was aborted instead of refusing it.
void AddAcceptFailedCaptureFlag(CLI::App* solve, bool* accept);
// `--integrator poisson | frankot-chellappa | none` into request->integrator.
void AddIntegratorOption(CLI::App* solve, config::PhotometricStereoRequest* request);
inline daemon::FailedCapture FailedCapturePolicy(bool accept) {
  return accept ? daemon::FailedCapture::kAccept : daemon::FailedCapture::kRefuse;
}

// The image stack that solve ps and solve svbrdf read: a run (`--run DIR`,
// with --accept-failed-capture) or a DiLiGenT-layout folder (`--dataset DIR`).
struct StackSource {
  std::string run_dir, dataset_dir;
  bool accept_failed_capture = false;

  bool given() const { return !run_dir.empty() || !dataset_dir.empty(); }
  bool from_run() const { return !run_dir.empty(); }
  // `out` when given, else the source's results/<family>.
  std::string ResultsDirectory(const std::string& out, const std::string& family) const;
  daemon::PhotometricStereoInput Load(const daemon::ColorStackOptions& color) const;
};
// --run and --dataset, which exclude each other, and --accept-failed-capture.
void AddStackSourceOptions(CLI::App* solve, StackSource* source);
// A warning, with the capture's verdict and reasons, when a result comes from
// a capture that did not complete (its report's "capture" says so too).
void WarnOfFailedCapture(const std::optional<daemon::CaptureVerdict>& capture);
}
