#include "photorig/solvers/color/calibration.h"

#include "photorig/solvers/color/colorimetry.h"

#include <Eigen/QR>
#include <Eigen/SVD>
#include <ceres/ceres.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>

namespace photorig::solvers::color {
namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

Eigen::MatrixXd FeatureMatrix(const ModelSpec& spec, const std::vector<Eigen::Vector3d>& rgb, double scale) {
  Eigen::MatrixXd f(static_cast<Eigen::Index>(rgb.size()), spec.TermCount());
  for (std::size_t i = 0; i < rgb.size(); ++i) f.row(static_cast<Eigen::Index>(i)) = ModelFeatures(spec, scale * rgb[i]);
  return f;
}

double ConditionNumber(Eigen::MatrixXd f) {
  for (Eigen::Index c = 0; c < f.cols(); ++c) {
    const double norm = f.col(c).norm();
    if (norm > 0.0) f.col(c) /= norm;
  }
  const Eigen::VectorXd s = Eigen::JacobiSVD<Eigen::MatrixXd>(f).singularValues();
  return s(s.size() - 1) > 0.0 ? s(0) / s(s.size() - 1) : std::numeric_limits<double>::infinity();
}

// One patch's CIEDE2000 as a function of all coefficients (column-major, terms x 3).
struct Ciede2000Residual {
  Eigen::VectorXd features;
  Eigen::Vector3d reference_lab;
  Eigen::Vector3d white_xyz;

  bool operator()(double const* const* parameters, double* residual) const {
    const Eigen::Index terms = features.size();
    const Eigen::Map<const Eigen::MatrixXd> c(parameters[0], terms, 3);
    const Eigen::Vector3d xyz = c.transpose() * features;
    residual[0] = Ciede2000(XyzToLab(xyz, white_xyz), reference_lab);
    return true;
  }
};

double Mean(const std::vector<double>& v) {
  double sum = 0.0;
  int n = 0;
  for (const double x : v)
    if (std::isfinite(x)) sum += x, ++n;
  return n ? sum / n : std::numeric_limits<double>::quiet_NaN();
}

std::vector<double> Finite(const std::vector<double>& v) {
  std::vector<double> out;
  std::copy_if(v.begin(), v.end(), std::back_inserter(out), [](double x) { return std::isfinite(x); });
  return out;
}

// Smallest principal standard deviation of the (r, g) chromaticities.
double ChromaticitySpread(const std::vector<Eigen::Vector3d>& rgb) {
  Eigen::MatrixXd rg(static_cast<Eigen::Index>(rgb.size()), 2);
  for (std::size_t i = 0; i < rgb.size(); ++i) {
    const double sum = std::max(rgb[i].sum(), 1e-12);
    rg.row(static_cast<Eigen::Index>(i)) << rgb[i].x() / sum, rgb[i].y() / sum;
  }
  const Eigen::MatrixXd centred = rg.rowwise() - rg.colwise().mean();
  const Eigen::VectorXd s = Eigen::JacobiSVD<Eigen::MatrixXd>(centred).singularValues();
  return s(1) / std::sqrt(static_cast<double>(rgb.size()));
}

template <typename T>
std::vector<T> Subset(const std::vector<T>& all, const std::vector<int>& indices) {
  std::vector<T> out;
  for (const int i : indices) out.push_back(all[static_cast<std::size_t>(i)]);
  return out;
}

}  // namespace

bool CalibrationOptions::IsValid(std::string* why) const {
  if (candidates.empty()) return core::Refuse(why, "no candidate models");
  if (white_patch < 0) return core::Refuse(why, "white_patch must be >= 0");
  if (!(max_condition_number > 1.0)) return core::Refuse(why, "max_condition_number must be > 1");
  if (!(min_chromaticity_spread >= 0.0)) return core::Refuse(why, "min_chromaticity_spread must be >= 0");
  if (!(selection_tolerance >= 0.0)) return core::Refuse(why, "selection_tolerance must be >= 0");
  if (max_refinement_iterations < 1) return core::Refuse(why, "max_refinement_iterations must be >= 1");
  return true;
}

ColorModel FitModel(const ModelSpec& spec, const std::vector<Eigen::Vector3d>& camera_rgb,
                    const std::vector<Eigen::Vector3d>& reference_xyz, const Eigen::Vector3d& white_xyz,
                    double input_scale, FitLoss loss, int max_refinement_iterations) {
  ColorModel model;
  model.spec = spec;
  model.loss = loss;
  model.input_scale = input_scale;
  model.white_xyz = white_xyz;
  const Eigen::MatrixXd f = FeatureMatrix(spec, camera_rgb, input_scale);
  Eigen::MatrixXd target(f.rows(), 3);
  for (Eigen::Index i = 0; i < f.rows(); ++i) target.row(i) = reference_xyz[static_cast<std::size_t>(i)].transpose();
  // A X = b, solved per XYZ channel by column-pivoting QR (stable when nearly rank deficient).
  model.coefficients = f.colPivHouseholderQr().solve(target);
  if (loss == FitLoss::kCiede2000) {
    ceres::Problem problem;
    const int parameter_count = static_cast<int>(model.coefficients.size());
    for (Eigen::Index i = 0; i < f.rows(); ++i) {
      auto* cost = new ceres::DynamicNumericDiffCostFunction<Ciede2000Residual, ceres::CENTRAL>(new Ciede2000Residual{
          f.row(i).transpose(), XyzToLab(reference_xyz[static_cast<std::size_t>(i)], white_xyz), white_xyz});
      cost->AddParameterBlock(parameter_count);
      cost->SetNumResiduals(1);
      problem.AddResidualBlock(cost, nullptr, model.coefficients.data());
    }
    ceres::Solver::Options solver_options;
    solver_options.linear_solver_type = ceres::DENSE_QR;
    solver_options.max_num_iterations = max_refinement_iterations;
    solver_options.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options, &problem, &summary);
  }
  return model;
}

namespace {

// Exposure normalisation on the white patch, or the brightest usable neutral:
// *scale takes the camera's Y there to the reference's (summary->exposure_patch
// says which). Ends *summary and returns false where none is usable.
bool NormaliseExposure(const CalibrationInput& input, int white_patch, const std::vector<int>& used, double* scale,
                       CalibrationSummary* summary) {
  const std::size_t n = input.camera_rgb.size();
  std::vector<int> whites = {white_patch};
  if (n == 24)
    for (int p = 18; p < 24; ++p) whites.push_back(p);
  for (const int w : whites) {
    if (w < static_cast<int>(n) && std::find(used.begin(), used.end(), w) != used.end() &&
        input.camera_rgb[static_cast<std::size_t>(w)].y() > 0.0) {
      summary->exposure_patch = w;
      break;
    }
  }
  if (summary->exposure_patch < 0) {
    summary->End(solvers::core::Termination::kFailure, "no usable white or grey patch to normalise the exposure on");
    return false;
  }
  const auto w = static_cast<std::size_t>(summary->exposure_patch);
  *scale = input.reference_xyz[w].y() / input.camera_rgb[w].y();
  return true;
}

}  // namespace

CalibrationSummary Calibrate(const CalibrationInput& input, const CalibrationOptions& options) {
  solvers::core::SolveTimer timer;
  CalibrationSummary summary;
  if (solvers::core::EndIfInvalid(options, &summary)) return summary;
  const std::size_t n = input.camera_rgb.size();
  if (input.usable.size() != n || input.reference_xyz.size() != n) {
    summary.End(solvers::core::Termination::kInvalidInput, "camera_rgb, usable and reference_xyz must have one entry per patch");
    return summary;
  }
  std::vector<int> used;
  for (std::size_t i = 0; i < n; ++i)
    if (input.usable[i] && input.camera_rgb[i].allFinite() && input.reference_xyz[i].allFinite())
      used.push_back(static_cast<int>(i));
  summary.patches_used = static_cast<int>(used.size());
  if (used.size() < 4) {
    summary.End(solvers::core::Termination::kFailure,
                "only " + std::to_string(used.size()) + " usable patches; at least 4 are needed");
    return summary;
  }

  // A white patch the chart does not have is a mistake, not a patch to fall back from.
  if (options.normalise_exposure && options.white_patch >= static_cast<int>(n)) {
    summary.End(solvers::core::Termination::kInvalidOptions, "white_patch " + std::to_string(options.white_patch) +
                                                                 " is not one of the chart's " + std::to_string(n) +
                                                                 " patches (0-" + std::to_string(n - 1) + ")");
    return summary;
  }
  double scale = 1.0;
  if (options.normalise_exposure && !NormaliseExposure(input, options.white_patch, used, &scale, &summary))
    return summary;

  const std::vector<Eigen::Vector3d> rgb = Subset(input.camera_rgb, used);
  const std::vector<Eigen::Vector3d> xyz = Subset(input.reference_xyz, used);
  const double spread = ChromaticitySpread(rgb);
  if (spread < options.min_chromaticity_spread) {
    std::ostringstream message;
    message << "near-singular system: the usable patches span too little colour (chromaticity spread " << spread
            << " < " << options.min_chromaticity_spread << "); a chart of greys cannot calibrate colour";
    summary.End(solvers::core::Termination::kFailure, message.str());
    return summary;
  }
  timer.SetupDone(&summary);
  std::vector<Eigen::Vector3d> lab;
  for (const auto& v : xyz) lab.push_back(XyzToLab(v, input.white_xyz));
  const double nan = std::numeric_limits<double>::quiet_NaN();

  const std::int64_t fits_per_model = static_cast<std::int64_t>(used.size()) + 1;
  solvers::core::ProgressThrottle progress(options.progress, "colour fits",
                                     fits_per_model * static_cast<std::int64_t>(options.candidates.size()));
  std::int64_t fits_done = 0;  // a skipped model's fits count as done
  for (const ModelSpec& spec : options.candidates) {
    const std::int64_t first_fit = fits_done;
    fits_done += fits_per_model;
    ModelEvaluation eval;
    eval.spec = spec;
    eval.training_de.assign(n, nan);
    eval.held_out_de.assign(n, nan);
    const int terms = spec.TermCount();
    if (static_cast<int>(used.size()) - 1 <= terms) {
      eval.note = "needs more than " + std::to_string(terms + 1) + " usable patches, has " + std::to_string(used.size());
      summary.models.push_back(std::move(eval));
      continue;
    }
    eval.condition_number = ConditionNumber(FeatureMatrix(spec, rgb, scale));
    if (!(eval.condition_number <= options.max_condition_number)) {
      std::ostringstream note;
      note << "ill-conditioned (condition number " << eval.condition_number
           << "): the patches do not span enough colours for " << spec.Name();
      eval.note = note.str();
      summary.models.push_back(std::move(eval));
      continue;
    }
    auto t0 = Clock::now();
    eval.model = FitModel(spec, rgb, xyz, input.white_xyz, scale, options.loss, options.max_refinement_iterations);
    eval.model.illuminant = input.illuminant;
    eval.fit_ms = MsSince(t0);
    for (std::size_t k = 0; k < used.size(); ++k)
      eval.training_de[static_cast<std::size_t>(used[k])] =
          Ciede2000(XyzToLab(eval.model.ToXyz(rgb[k]), input.white_xyz), lab[k]);
    t0 = Clock::now();
    for (std::size_t k = 0; k < used.size(); ++k) {
      std::vector<Eigen::Vector3d> rgb_train, xyz_train;
      for (std::size_t j = 0; j < used.size(); ++j)
        if (j != k) rgb_train.push_back(rgb[j]), xyz_train.push_back(xyz[j]);
      const ColorModel held_out =
          FitModel(spec, rgb_train, xyz_train, input.white_xyz, scale, options.loss, options.max_refinement_iterations);
      eval.held_out_de[static_cast<std::size_t>(used[k])] =
          Ciede2000(XyzToLab(held_out.ToXyz(rgb[k]), input.white_xyz), lab[k]);
      progress.Update(first_fit + 2 + static_cast<std::int64_t>(k));  // the fit on all patches, then k + 1 left out
    }
    eval.loo_ms = MsSince(t0);
    eval.training_mean = Mean(eval.training_de);
    std::vector<double> held = Finite(eval.held_out_de);
    eval.held_out_mean = Mean(held);
    std::sort(held.begin(), held.end());
    eval.held_out_median =
        held.size() % 2 ? held[held.size() / 2] : 0.5 * (held[held.size() / 2 - 1] + held[held.size() / 2]);
    eval.held_out_max = held.back();
    eval.usable = std::isfinite(eval.held_out_mean) && eval.model.coefficients.allFinite();
    if (!eval.usable) eval.note = "fit produced non-finite values";
    summary.models.push_back(std::move(eval));
  }
  progress.Finish();

  // The simplest model whose held-out error is within the tolerance of the best.
  double best = std::numeric_limits<double>::infinity();
  for (const auto& m : summary.models)
    if (m.usable) best = std::min(best, m.held_out_mean);
  for (std::size_t i = 0; i < summary.models.size(); ++i) {
    const auto& m = summary.models[i];
    if (!m.usable || m.held_out_mean > best + options.selection_tolerance) continue;
    if (summary.chosen < 0 || m.spec.TermCount() < summary.models[static_cast<std::size_t>(summary.chosen)].spec.TermCount())
      summary.chosen = static_cast<int>(i);
  }
  timer.Finish(&summary);
  if (summary.chosen < 0) {
    std::string reasons = "no candidate model is usable:";
    for (const auto& m : summary.models) reasons += " " + m.spec.Name() + ": " + m.note + ";";
    summary.End(solvers::core::Termination::kFailure, reasons);
    return summary;
  }
  const auto& chosen = summary.models[static_cast<std::size_t>(summary.chosen)];
  std::ostringstream message;
  message.precision(3);
  message << "chose " << chosen.spec.Name() << ": leave-one-out mean CIEDE2000 " << chosen.held_out_mean
          << " (training " << chosen.training_mean << ") over " << used.size() << " patches";
  summary.End(solvers::core::Termination::kSuccess, message.str());
  return summary;
}

std::vector<double> ReferenceGrid() { return WavelengthGrid(380.0, 730.0, 5.0); }

ChartCalibration CalibrateChartImage(const cv::Mat& image_bgr, const cv::Mat& dark_bgr, Illuminant illuminant,
                                     const LocateOptions& locate, const MeasureOptions& measure,
                                     const CalibrationOptions& options) {
  ChartCalibration out;
  out.reference = ColorCheckerReference(illuminant, ReferenceGrid());
  out.located = LocateChart(image_bgr, locate);
  if (!out.located.location) {
    out.summary.End(out.located.termination, "chart not found: " + out.located.message);
    return out;
  }
  const solvers::core::Summary measured = MeasurePatches(image_bgr, dark_bgr, *out.located.location, measure, &out.patches);
  if (!measured.IsSolutionUsable()) {
    out.summary.End(measured.termination, "measuring the chart's patches: " + measured.message);
    return out;
  }
  CalibrationInput input;
  input.reference_xyz = out.reference.xyz;
  input.white_xyz = out.reference.white_xyz;
  input.illuminant = illuminant;
  for (const auto& patch : out.patches) {
    input.camera_rgb.push_back(patch.rgb);
    input.usable.push_back(patch.flag == PatchFlag::kOk);
  }
  out.summary = Calibrate(input, options);
  int flagged = 0;
  for (const auto& patch : out.patches) flagged += patch.flag != PatchFlag::kOk;
  if (flagged) out.summary.message += " (" + std::to_string(flagged) + " patches flagged and left out)";
  return out;
}

}  // namespace photorig::solvers::color
