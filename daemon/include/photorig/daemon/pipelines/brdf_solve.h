#pragma once
// A gonioreflectometer run -> its BRDF: the frames measured into calibrated
// samples (brdf_measurement.h), every candidate model fitted and the one the
// data support chosen (solvers/brdf), written as results/brdf/report.json and
// samples.csv. The recipe's `brdf:` solve stage and `photorig solve brdf`
// both run this.

#include "photorig/config/solve_requests.h"
#include "photorig/daemon/pipelines/brdf_measurement.h"
#include "photorig/solvers/brdf/fit.h"

#include <nlohmann/json.hpp>

#include <optional>
#include <string>

namespace photorig::daemon {

struct BrdfSolveResult {
  BrdfMeasurement measurement;
  std::optional<solvers::brdf::SelectionSummary> selection;  // absent when there was nothing to fit
  nlohmann::json report;  // report.json: the measurement, every model's fit and the choice
  std::string warning;    // a clipped specular peak; empty otherwise
  std::string results;    // the folder written; empty when nothing was
  std::optional<CaptureVerdict> capture;  // the run's (also report.json "capture")
  double total_ms = 0.0;

  // A chosen model from a usable measurement.
  bool usable() const { return selection && selection->IsSolutionUsable(); }
  // Why not usable; empty when it is.
  std::string failure() const;
  // The measurement refused the run's data (a missing step, a monochrome-only
  // option): a configuration fault, not a failed solve.
  bool refused_input() const;
};

// Reads the run at `run_dir` and, when there are samples, writes the report
// and samples into `out_dir` whole (results_folder.h). Throws what the run
// store throws for an unreadable manifest or frame, FailedCaptureError for a
// capture that did not complete unless `failed` accepts it (the report then
// says so), and ResultsWriteError when the results cannot be written.
BrdfSolveResult SolveBrdfAndWrite(const std::string& run_dir, const config::BrdfRequest& request, const std::string& out_dir,
                                  FailedCapture failed = FailedCapture::kRefuse);

// The measurement's part of the report: frames, calibration, noise, clipped poses.
nlohmann::json MeasurementJson(const BrdfMeasurement& measurement);

}  // namespace photorig::daemon
