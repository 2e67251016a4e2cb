#pragma once
// Fits every candidate model to a chart measurement, scores each by
// leave-one-out CIEDE2000 (fit on all patches but one, predict that one), and
// chooses the simplest model whose held-out error is within a tolerance of the
// best. With 24 patches, training error always falls with model order while the
// held-out error rises once a model starts to fit the noise.

#include "photorig/solvers/color/chart.h"
#include "photorig/solvers/color/model.h"

#include "photorig/solvers/core/progress.h"
#include "photorig/solvers/core/summary.h"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace photorig::solvers::color {

struct CalibrationOptions {
  std::vector<ModelSpec> candidates = ModelSpec::All();
  FitLoss loss = FitLoss::kXyzLeastSquares;  // kCiede2000 refines the least-squares fit with Ceres
  bool normalise_exposure = true;            // scale RGB so the white patch's green equals its reference Y
  int white_patch = 18;                      // fallback: the brightest usable neutral (patches 19-24)
  double max_condition_number = 1e7;         // of the column-normalised feature matrix
  // Smallest principal standard deviation of the usable patches' (r, g)
  // chromaticities: below it the system is near-singular (e.g. only greys).
  double min_chromaticity_spread = 0.01;
  double selection_tolerance = 0.02;         // CIEDE2000: prefer fewer terms within this of the best
  int max_refinement_iterations = 100;       // Ceres, for kCiede2000
  // Fits done (stage "colour fits"): per candidate, one on every usable patch
  // and one per left-out patch; seconds in all with kCiede2000. Empty: none.
  solvers::core::ProgressCallback progress;

  bool IsValid(std::string* why) const;
};

struct CalibrationInput {
  std::vector<Eigen::Vector3d> camera_rgb;     // per patch, dark subtracted
  std::vector<bool> usable;                    // false: left out (flagged measurement)
  std::vector<Eigen::Vector3d> reference_xyz;  // per patch, white Y = 1
  Eigen::Vector3d white_xyz = Eigen::Vector3d::Ones();
  Illuminant illuminant = Illuminant::kD65;
};

struct ModelEvaluation {
  ModelSpec spec;
  bool usable = false;       // false: too few patches or ill-conditioned; see note
  std::string note;
  ColorModel model;          // fitted to every usable patch
  double condition_number = 0.0;
  std::vector<double> training_de;  // per patch; NaN where not usable
  std::vector<double> held_out_de;  // leave-one-out; NaN where not usable
  double training_mean = 0.0, held_out_mean = 0.0, held_out_median = 0.0, held_out_max = 0.0;
  double fit_ms = 0.0, loo_ms = 0.0;
};

// kSuccess: a model was chosen (chosen_model() is valid); otherwise message says why not.
struct CalibrationSummary : solvers::core::Summary {
  std::vector<ModelEvaluation> models;
  int chosen = -1;  // index into models
  int patches_used = 0;
  int exposure_patch = -1;
  const ColorModel& chosen_model() const { return models.at(static_cast<std::size_t>(chosen)).model; }
};

CalibrationSummary Calibrate(const CalibrationInput& input, const CalibrationOptions& options);

// Fits one model to the given patches (all usable); no validation, no LOO.
ColorModel FitModel(const ModelSpec& spec, const std::vector<Eigen::Vector3d>& camera_rgb,
                    const std::vector<Eigen::Vector3d>& reference_xyz, const Eigen::Vector3d& white_xyz,
                    double input_scale, FitLoss loss, int max_refinement_iterations = 100);

// The whole chart path: locate, measure (flagged patches left out), reference
// XYZ of the BabelColor chart under `illuminant`, calibrate.
struct ChartCalibration {
  LocateResult located;
  std::vector<PatchMeasurement> patches;
  ChartReference reference;
  CalibrationSummary summary;
};
ChartCalibration CalibrateChartImage(const cv::Mat& image_bgr, const cv::Mat& dark_bgr, Illuminant illuminant,
                                     const LocateOptions& locate, const MeasureOptions& measure,
                                     const CalibrationOptions& options);

// Wavelengths the reference XYZ are summed over: the reflectance table's 380-730 nm at 5 nm.
std::vector<double> ReferenceGrid();

}  // namespace photorig::solvers::color
