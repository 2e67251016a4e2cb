#include "photorig/solvers/camera/calibration.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <optional>
#include <sstream>

namespace photorig::solvers::camera {
namespace {

constexpr double kPi = 3.14159265358979323846;

std::string ImageName(const std::vector<std::string>& names, std::size_t count, std::size_t index) {
  return names.size() == count ? names[index] : "image " + std::to_string(index);
}

std::string JoinNames(const std::vector<std::string>& names) {
  std::string joined;
  for (const std::string& name : names) joined += (joined.empty() ? "" : ", ") + name;
  return joined;
}

// The corner detector works on 8-bit grey: a 16-bit frame is stretched over
// its own range so a dim 12-bit board keeps its contrast.
cv::Mat EightBitGrey(const cv::Mat& image) {
  cv::Mat grey = image;
  if (image.channels() == 3) cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  if (grey.depth() == CV_8U) return grey;
  cv::Mat eight;
  cv::normalize(grey, eight, 0, 255, cv::NORM_MINMAX, CV_8U);
  return eight;
}

std::string CheckImages(const CheckerboardCalibrationOptions& options, const std::vector<cv::Mat>& images) {
  if (images.empty()) return "no images";
  if (options.plane_image >= static_cast<int>(images.size()))
    return "the plane image is number " + std::to_string(options.plane_image) + " of " + std::to_string(images.size()) +
           " images (counting from 0)";
  for (std::size_t i = 0; i < images.size(); ++i) {
    const cv::Mat& image = images[i];
    if (image.empty()) return "image " + std::to_string(i) + " is empty";
    if (image.size() != images[0].size()) return "the images differ in size";
    if ((image.channels() != 1 && image.channels() != 3) || (image.depth() != CV_8U && image.depth() != CV_16U))
      return "image " + std::to_string(i) + " is neither 8- nor 16-bit grey or colour";
  }
  return {};
}

// calibrateCamera's flags for a model: the coefficients beyond it held at 0.
int FixedCoefficients(DistortionModel model) {
  switch (model) {
    case DistortionModel::kNone:
      return cv::CALIB_FIX_K1 | cv::CALIB_FIX_K2 | cv::CALIB_FIX_K3 | cv::CALIB_ZERO_TANGENT_DIST;
    case DistortionModel::kRadial1:
      return cv::CALIB_FIX_K2 | cv::CALIB_FIX_K3 | cv::CALIB_ZERO_TANGENT_DIST;
    case DistortionModel::kRadial2:
      return cv::CALIB_FIX_K3 | cv::CALIB_ZERO_TANGENT_DIST;
    case DistortionModel::kRadial2Tangential:
      return cv::CALIB_FIX_K3;
    case DistortionModel::kRadial3Tangential:
      return 0;
  }
  return 0;
}

// How many of the coefficients a model fits.
int CoefficientCount(DistortionModel model) {
  switch (model) {
    case DistortionModel::kNone: return 0;
    case DistortionModel::kRadial1: return 1;
    case DistortionModel::kRadial2: return 2;
    case DistortionModel::kRadial2Tangential: return 4;
    case DistortionModel::kRadial3Tangential: return 5;
  }
  return 0;
}

// calibrateCamera's answer for one model.
struct LensFit {
  DistortionCandidate candidate;
  cv::Mat k, distortion, std_intrinsics, per_view_rms;
  std::vector<cv::Mat> rotations, translations;
};

LensFit FitLens(const std::vector<std::vector<cv::Point3f>>& boards,
                const std::vector<std::vector<cv::Point2f>>& corners, cv::Size size, DistortionModel model) {
  LensFit fit;
  cv::Mat std_extrinsics;
  fit.candidate.model = model;
  fit.candidate.rms_px = cv::calibrateCamera(boards, corners, size, fit.k, fit.distortion, fit.rotations,
                                             fit.translations, fit.std_intrinsics, std_extrinsics, fit.per_view_rms,
                                             FixedCoefficients(model),
                                             cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-12));
  // calibrateCamera's RMS is over the corners' 2-D offsets: the sum of
  // squares is rms^2 per corner, over two residuals each.
  std::size_t points = 0;
  for (const auto& view : corners) points += view.size();
  const double residuals = 2.0 * static_cast<double>(points);
  const double parameters = 4.0 + CoefficientCount(model) + 6.0 * static_cast<double>(corners.size());
  const double rss = fit.candidate.rms_px * fit.candidate.rms_px * static_cast<double>(points);
  fit.candidate.bic = residuals * std::log(std::max(rss, 1e-300) / residuals) + parameters * std::log(residuals);
  return fit;
}

// The simplest model the corners support: every candidate fitted, the one
// of lowest BIC kept. Its coefficients are judged together, by what they
// predict: k2 alone is often poorly determined (it trades off against k1)
// while the two together bend the corners as the lens does. `reason` says
// why, with the others' margins.
LensFit ChooseLens(const std::vector<std::vector<cv::Point3f>>& boards,
                   const std::vector<std::vector<cv::Point2f>>& corners, cv::Size size,
                   const CheckerboardCalibrationOptions& options, std::vector<DistortionCandidate>* candidates,
                   std::string* reason) {
  std::vector<DistortionModel> models;
  if (options.distortion) {
    models = {*options.distortion};
  } else {
    for (const auto& named : kDistortionModelNames) models.push_back(named.value);
  }
  // One after another on the calling thread: calibrateCamera inside another
  // thread's parallel region ran its own loops differently, and the same
  // photographs gave BICs a last bit apart from run to run (two at a time
  // took 0.46x the time; a calibration is done once).
  std::optional<LensFit> best;
  for (const DistortionModel model : models) {
    LensFit fit = FitLens(boards, corners, size, model);
    candidates->push_back(fit.candidate);
    if (!best || fit.candidate.bic < best->candidate.bic) best = std::move(fit);
  }
  std::ostringstream why;
  why.precision(3);
  why << core::NameOf(kDistortionModelNames, best->candidate.model);
  if (options.distortion) {
    why << ": as the options fix it";
  } else {
    why << ": the lowest BIC";
    for (const DistortionCandidate& other : *candidates)
      if (other.model != best->candidate.model)
        why << "; " << core::NameOf(kDistortionModelNames, other.model) << " higher by " << other.bic - best->candidate.bic;
  }
  *reason = why.str();
  return std::move(*best);
}

// The largest distance of a corner found from the principal point over the
// farthest image corner's.
double CornerReach(const std::vector<std::vector<cv::Point2f>>& corners, const PinholeLens& lens, cv::Size size) {
  const double w = size.width - 1.0, h = size.height - 1.0;
  const double dx = std::max(lens.cx_px, w - lens.cx_px), dy = std::max(lens.cy_px, h - lens.cy_px);
  const double farthest = std::hypot(dx, dy);
  double reach = 0.0;
  for (const auto& view : corners)
    for (const cv::Point2f& p : view) reach = std::max(reach, std::hypot(p.x - lens.cx_px, p.y - lens.cy_px));
  return reach / farthest;
}

}  // namespace

bool CheckerboardCalibrationOptions::IsValid(std::string* why) const {
  // Fewer than 3 inner corners a side leave the detector nothing to order.
  if (inner_corners_cols < 3 || inner_corners_rows < 3)
    return core::Refuse(why, "the board needs at least 3 x 3 inner corners");
  if (!(square_mm > 0.0) || !std::isfinite(square_mm)) return core::Refuse(why, "square_mm must be positive");
  if (plane_image < 0) return core::Refuse(why, "plane_image must be an image index (>= 0)");
  if (min_images < 3) return core::Refuse(why, "min_images must be at least 3 (two poses do not fix the intrinsics)");
  if (!(max_rms_px > 0.0)) return core::Refuse(why, "max_rms_px must be positive");
  if (!(max_tilt_deg > 0.0 && max_tilt_deg < 90.0)) return core::Refuse(why, "max_tilt_deg must lie in (0, 90)");
  if (!(min_corner_reach >= 0.0 && min_corner_reach <= 1.0)) return core::Refuse(why, "min_corner_reach must lie in [0, 1]");
  if (subpixel_half_window_px < 1) return core::Refuse(why, "subpixel_half_window_px must be at least 1");
  return true;
}

CheckerboardCalibrationSummary CalibrateFromCheckerboards(const CheckerboardCalibrationOptions& options,
                                                          const std::vector<cv::Mat>& images,
                                                          const std::vector<std::string>& names) {
  core::SolveTimer timer;
  CheckerboardCalibrationSummary summary;
  if (core::EndIfInvalid(options, &summary)) return summary;
  if (core::EndIfBadInput(CheckImages(options, images), &summary)) return summary;
  summary.width_px = images[0].cols;
  summary.height_px = images[0].rows;
  timer.SetupDone(&summary);

  const cv::Size pattern(options.inner_corners_cols, options.inner_corners_rows);
  std::vector<cv::Point3f> board;  // the corners on the board, row by row
  for (int r = 0; r < pattern.height; ++r)
    for (int c = 0; c < pattern.width; ++c)
      board.emplace_back(static_cast<float>(c * options.square_mm), static_cast<float>(r * options.square_mm), 0.0f);

  std::vector<std::vector<cv::Point2f>> corners;
  std::vector<std::size_t> used_index;
  core::ProgressThrottle corner_progress(options.progress, "corners", static_cast<std::int64_t>(images.size()));
  for (std::size_t i = 0; i < images.size(); ++i) {
    const cv::Mat grey = EightBitGrey(images[i]);
    std::vector<cv::Point2f> found;
    if (cv::findChessboardCorners(grey, pattern, found, cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE)) {
      const int half = options.subpixel_half_window_px;
      cv::cornerSubPix(grey, found, cv::Size(half, half), cv::Size(-1, -1),
                       cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-3));
      corners.push_back(std::move(found));
      used_index.push_back(i);
      summary.used.push_back(ImageName(names, images.size(), i));
    } else {
      summary.rejected.push_back(ImageName(names, images.size(), i));
    }
    corner_progress.Update(static_cast<std::int64_t>(i) + 1);
  }
  corner_progress.Finish();

  const std::string plane_name = ImageName(names, images.size(), static_cast<std::size_t>(options.plane_image));
  const auto plane = std::find(used_index.begin(), used_index.end(), static_cast<std::size_t>(options.plane_image));
  if (plane == used_index.end())
    return timer.End(&summary, core::Termination::kFailure,
                     "no board found in the plane image " + plane_name + ", which gives the camera's height");
  if (static_cast<int>(corners.size()) < options.min_images)
    return timer.End(&summary, core::Termination::kFailure,
                     "a board was found in " + std::to_string(corners.size()) + " images, at least " +
                         std::to_string(options.min_images) + " are needed; none in: " + JoinNames(summary.rejected));

  const std::vector<std::vector<cv::Point3f>> boards(corners.size(), board);
  core::ProgressThrottle fit_progress(options.progress, "fit", 1);
  LensFit fit = ChooseLens(boards, corners, images[0].size(), options, &summary.candidates, &summary.distortion_reason);
  fit_progress.Finish();
  summary.distortion_model = fit.candidate.model;
  summary.rms_px = fit.candidate.rms_px;
  const cv::Mat& k = fit.k;
  const cv::Mat& distortion = fit.distortion;
  const cv::Mat& std_intrinsics = fit.std_intrinsics;
  const std::vector<cv::Mat>& rotations = fit.rotations;
  const std::vector<cv::Mat>& translations = fit.translations;

  PinholeLens& lens = summary.lens;
  lens.fx_px = k.at<double>(0, 0);
  lens.fy_px = k.at<double>(1, 1);
  lens.cx_px = k.at<double>(0, 2);
  lens.cy_px = k.at<double>(1, 2);
  // stdDeviationsIntrinsics: fx, fy, cx, cy, then the coefficients in distCoeffs' order.
  summary.fx_std_px = std_intrinsics.at<double>(0);
  summary.fy_std_px = std_intrinsics.at<double>(1);
  summary.cx_std_px = std_intrinsics.at<double>(2);
  summary.cy_std_px = std_intrinsics.at<double>(3);
  for (int i = 0; i < 5; ++i) {
    lens.distortion[static_cast<std::size_t>(i)] = distortion.at<double>(i);
    summary.distortion_std[static_cast<std::size_t>(i)] = std_intrinsics.at<double>(4 + i);
  }
  for (int i = 0; i < fit.per_view_rms.rows; ++i) summary.image_rms_px.push_back(fit.per_view_rms.at<double>(i));
  summary.corner_reach = CornerReach(corners, lens, images[0].size());

  // The plane image's board: its normal n in the camera's frame against the
  // optical axis gives the tilt, and the plane n.x = n.t its distance from
  // the camera centre.
  const std::size_t plane_view = static_cast<std::size_t>(plane - used_index.begin());
  cv::Matx33d rotation;
  cv::Rodrigues(rotations[plane_view], rotation);
  const cv::Vec3d normal(rotation(0, 2), rotation(1, 2), rotation(2, 2));
  const cv::Vec3d t(translations[plane_view]);
  summary.tilt_deg = std::acos(std::min(1.0, std::abs(normal[2]))) * 180.0 / kPi;
  lens.distance_mm = std::abs(normal.dot(t));

  std::ostringstream figures;
  figures.precision(3);
  if (!(summary.rms_px <= options.max_rms_px)) {
    figures << "RMS reprojection error " << summary.rms_px << " px is above " << options.max_rms_px
            << " px: check the board's flatness, its size and the images' focus";
    return timer.End(&summary, core::Termination::kFailure, figures.str());
  }
  if (!(summary.tilt_deg <= options.max_tilt_deg)) {
    figures << "the camera is tilted " << summary.tilt_deg << " deg from the normal of the board in " << plane_name
            << " (limit " << options.max_tilt_deg
            << " deg): the model needs a camera looking straight down on a board lying flat on the sample plane";
    return timer.End(&summary, core::Termination::kFailure, figures.str());
  }
  if (!(summary.corner_reach >= options.min_corner_reach)) {
    figures << "the corners found reach " << 100.0 * summary.corner_reach
            << " % of the way from the principal point to the image's corners (at least "
            << 100.0 * options.min_corner_reach
            << " % needed): the distortion beyond them would be extrapolated; add photographs with the board near "
               "the image's corners and edges";
    return timer.End(&summary, core::Termination::kFailure, figures.str());
  }
  std::string why;
  if (!lens.IsValid(&why)) return timer.End(&summary, core::Termination::kFailure, "the fitted lens is unusable: " + why);
  summary.termination = core::Termination::kSuccess;
  if (!summary.rejected.empty()) summary.message = "no board found in: " + JoinNames(summary.rejected);
  timer.Finish(&summary);
  return summary;
}

}  // namespace photorig::solvers::camera
