#include "photorig/solvers/color/chart.h"

#include "photorig/solvers/color/colorimetry.h"
#include "photorig/solvers/core/names.h"

#include <opencv2/imgproc.hpp>
#if PHOTORIG_HAVE_MCC
#include <opencv2/mcc.hpp>
#endif

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <sstream>
#include <utility>

namespace photorig::solvers::color {
namespace {

using solvers::core::Termination;

cv::Matx33d GridToImage(const std::array<cv::Point2f, 4>& corners) {
  const cv::Point2f grid[4] = {{0.f, 0.f}, {6.f, 0.f}, {6.f, 4.f}, {0.f, 4.f}};
  return cv::Matx33d(cv::getPerspectiveTransform(grid, corners.data()));
}

cv::Point2f Map(const cv::Matx33d& h, double x, double y) {
  const cv::Vec3d p = h * cv::Vec3d(x, y, 1.0);
  return {static_cast<float>(p[0] / p[2]), static_cast<float>(p[1] / p[2])};
}

#if PHOTORIG_HAVE_MCC
double Distance(const cv::Point2f& a, const cv::Point2f& b) { return std::hypot(a.x - b.x, a.y - b.y); }

// 8-bit view for the detector: scaled to the bright end, gamma for contrast.
cv::Mat DetectorView(const cv::Mat& image) {
  cv::Mat values;
  image.convertTo(values, CV_32F);
  double max_value = 0.0;
  cv::minMaxLoc(values.reshape(1), nullptr, &max_value);
  if (max_value <= 0.0) max_value = 1.0;
  values /= max_value;
  cv::pow(cv::max(values, 0.0), 1.0 / 2.2, values);
  cv::Mat view;
  values.convertTo(view, CV_8U, 255.0);
  return view;
}

// The detector's box may start at any corner and run either way round; put the
// long edge first and the grey ramp (patches 19-24, white to black) on the bottom row.
std::array<cv::Point2f, 4> OrientCorners(std::array<cv::Point2f, 4> corners, const cv::Mat& image) {
  if (Distance(corners[0], corners[1]) < Distance(corners[1], corners[2]))
    std::rotate(corners.begin(), corners.begin() + 1, corners.end());
  cv::Mat gray;
  cv::Mat bgr;
  image.convertTo(bgr, CV_32F);
  cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  auto ramp_score = [&](const std::array<cv::Point2f, 4>& c) {
    const cv::Matx33d h = GridToImage(c);
    double score = 0.0;
    for (int column = 0; column + 1 < 6; ++column) {
      const cv::Point2f a = Map(h, column + 0.5, 3.5), b = Map(h, column + 1.5, 3.5);
      auto at = [&](const cv::Point2f& p) {
        const int x = std::clamp(static_cast<int>(p.x), 0, gray.cols - 1);
        const int y = std::clamp(static_cast<int>(p.y), 0, gray.rows - 1);
        return static_cast<double>(gray.at<float>(y, x));
      };
      score += at(a) > at(b) ? 1.0 : -1.0;
    }
    return score;
  };
  std::array<cv::Point2f, 4> flipped = corners;
  std::rotate(flipped.begin(), flipped.begin() + 2, flipped.end());
  // Either way round, the corner order must stay clockwise in the image.
  return ramp_score(flipped) > ramp_score(corners) ? flipped : corners;
}
#endif

}  // namespace

cv::Point2f ChartLocation::PatchCentre(int patch) const {
  return Map(GridToImage(corners), patch % kChartColumns + 0.5, patch / kChartColumns + 0.5);
}

std::array<cv::Point2f, 4> ChartLocation::SamplingQuad(int patch, double fraction) const {
  const cv::Matx33d h = GridToImage(corners);
  const double cx = patch % kChartColumns + 0.5, cy = patch / kChartColumns + 0.5, half = 0.5 * fraction;
  return {Map(h, cx - half, cy - half), Map(h, cx + half, cy - half), Map(h, cx + half, cy + half),
          Map(h, cx - half, cy + half)};
}

bool LocateOptions::IsValid(std::string* why) const {
  if (!fixed_corners) return true;
  const std::array<cv::Point2f, 4>& corners = *fixed_corners;
  const auto fail = [&](const char* what) {
    if (why) *why = "fixed_corners (" + fixed_source + ") " + what;
    return false;
  };
  for (const cv::Point2f& p : corners)
    if (!std::isfinite(p.x) || !std::isfinite(p.y)) return fail("must be finite");
  // Convex, in order round it: every corner turns the same way, none goes straight on.
  int left = 0, right = 0;
  for (std::size_t i = 0; i < 4; ++i) {
    const cv::Point2f in = corners[(i + 1) % 4] - corners[i], out = corners[(i + 2) % 4] - corners[(i + 1) % 4];
    const double turn = double(in.x) * out.y - double(in.y) * out.x;
    left += turn > 0.0;
    right += turn < 0.0;
  }
  if (left != 4 && right != 4)
    return fail("must go in order round a convex quadrilateral, top-left first (no three in line, no edges crossing)");
  return true;
}

LocateResult LocateChart(const cv::Mat& image_bgr, const LocateOptions& options) {
  const solvers::core::SolveTimer timer;
  LocateResult result;
  std::string why;
  if (!options.IsValid(&why)) return timer.End(&result, Termination::kInvalidOptions, "invalid options: " + why);
  if (image_bgr.empty() || image_bgr.channels() != 3)
    return timer.End(&result, Termination::kInvalidInput, "chart image must have 3 channels (B, G, R)");
  std::string detector_note = "detector off";
  if (options.use_detector) {
#if PHOTORIG_HAVE_MCC
    cv::Ptr<cv::mcc::CCheckerDetector> detector = cv::mcc::CCheckerDetector::create();
    if (detector->process(DetectorView(image_bgr), cv::mcc::MCC24, 1)) {
      const std::vector<cv::Point2f> box = detector->getBestColorChecker()->getBox();
      if (box.size() == 4) {
        ChartLocation location;
        std::copy(box.begin(), box.end(), location.corners.begin());
        location.corners = OrientCorners(location.corners, image_bgr);
        location.method = "detector";
        result.location = location;
        return timer.End(&result, Termination::kSuccess, "chart found by the mcc detector");
      }
    }
    detector_note = "the mcc detector found no 24-patch chart";
#else
    detector_note = "this build has no mcc detector (libopencv-contrib-dev)";
#endif
  }
  if (options.fixed_corners) {
    for (const cv::Point2f& p : *options.fixed_corners)
      if (!(p.x >= 0.f && p.y >= 0.f && p.x <= image_bgr.cols && p.y <= image_bgr.rows)) {
        std::ostringstream message;
        message << detector_note << "; " << options.fixed_source << " has a corner at (" << p.x << ", " << p.y
                << "), outside the " << image_bgr.cols << " x " << image_bgr.rows << " image";
        return timer.End(&result, Termination::kInvalidInput, message.str());
      }
    result.location = ChartLocation{*options.fixed_corners, "fixed-roi"};
    return timer.End(&result, Termination::kSuccess, detector_note + "; using " + options.fixed_source);
  }
  return timer.End(&result, Termination::kFailure,
                            detector_note + " and no fixed chart position was given (--chart-roi or the rig's color_chart)");
}

std::optional<std::array<cv::Point2f, 4>> ParseChartCorners(const std::string& text, std::string* why) {
  const auto fail = [why](std::string reason) -> std::optional<std::array<cv::Point2f, 4>> {
    if (why) *why = std::move(reason);
    return std::nullopt;
  };
  std::vector<float> values;
  std::stringstream stream(text);
  std::string field;
  while (std::getline(stream, field, ',')) {
    // As std::stof (leading blanks allowed), with the whole field a number and in range.
    char* end = nullptr;
    errno = 0;
    const float value = std::strtof(field.c_str(), &end);
    if (end == field.c_str() || *end != '\0' || errno == ERANGE) return fail("'" + field + "' is not a number");
    values.push_back(value);
  }
  if (values.size() == 4) {
    const float x = values[0], y = values[1], w = values[2], h = values[3];
    if (w <= 0 || h <= 0) return fail("width and height must be > 0");
    return std::array{cv::Point2f(x, y), cv::Point2f(x + w, y), cv::Point2f(x + w, y + h), cv::Point2f(x, y + h)};
  }
  if (values.size() == 8)
    return std::array{cv::Point2f(values[0], values[1]), cv::Point2f(values[2], values[3]),
                      cv::Point2f(values[4], values[5]), cv::Point2f(values[6], values[7])};
  return fail(std::to_string(values.size()) + " numbers, not 4 (x,y,w,h) or 8 (four corners x0,y0,...,x3,y3)");
}

namespace {

constexpr core::NameTable<PatchFlag, 4> kPatchFlagNames = {{
    {PatchFlag::kOk, "ok"}, {PatchFlag::kSaturated, "saturated"}, {PatchFlag::kUnderexposed, "underexposed"},
    {PatchFlag::kTooFewPixels, "too-few-pixels"},
}};

}  // namespace

const char* PatchFlagName(PatchFlag flag) { return core::NameOf(kPatchFlagNames, flag); }

bool MeasureOptions::IsValid(std::string* why) const {
  if (!(sample_fraction > 0.0 && sample_fraction <= 1.0)) return core::Refuse(why, "sample_fraction must be in (0, 1]");
  if (!(trim_fraction >= 0.0 && trim_fraction < 0.5)) return core::Refuse(why, "trim_fraction must be in [0, 0.5)");
  if (!(max_clipped_fraction >= 0.0 && max_clipped_fraction <= 1.0)) return core::Refuse(why, "max_clipped_fraction must be in [0, 1]");
  if (clip_level < 0.0) return core::Refuse(why, "clip_level must be >= 0");
  if (min_pixels < 1) return core::Refuse(why, "min_pixels must be >= 1");
  return true;
}

solvers::core::Summary MeasurePatches(const cv::Mat& image_bgr, const cv::Mat& dark_bgr, const ChartLocation& location,
                                const MeasureOptions& options, std::vector<PatchMeasurement>* patches_out) {
  const solvers::core::SolveTimer timer;
  std::string why;
  if (!options.IsValid(&why)) return solvers::core::Ended(solvers::core::Termination::kInvalidOptions, "invalid options: " + why);
  if (image_bgr.empty() || image_bgr.channels() != 3) {
    return solvers::core::Ended(solvers::core::Termination::kInvalidInput, "chart image must have 3 channels (B, G, R)");
  }
  if (!dark_bgr.empty() && (dark_bgr.size() != image_bgr.size() || dark_bgr.type() != image_bgr.type())) {
    return solvers::core::Ended(solvers::core::Termination::kInvalidInput, "dark frame must have the chart image's size and type");
  }
  double clip_level = options.clip_level;
  if (clip_level == 0.0) {
    const int depth = image_bgr.depth();
    clip_level = depth == CV_8U ? 255.0 : depth == CV_16U ? 65535.0 : std::numeric_limits<double>::infinity();
  }
  cv::Mat image, dark;
  image_bgr.convertTo(image, CV_64FC3);
  if (!dark_bgr.empty()) dark_bgr.convertTo(dark, CV_64FC3);

  std::vector<PatchMeasurement> patches(kChartPatches);
  std::array<std::vector<double>, 3> values;
  for (int patch = 0; patch < kChartPatches; ++patch) {
    const std::array<cv::Point2f, 4> quad = location.SamplingQuad(patch, options.sample_fraction);
    std::vector<cv::Point> polygon;
    for (const auto& p : quad) polygon.emplace_back(cvRound(p.x), cvRound(p.y));
    const cv::Rect bounds = cv::boundingRect(polygon);
    const cv::Rect inside = bounds & cv::Rect(0, 0, image.cols, image.rows);
    PatchMeasurement& m = patches[static_cast<std::size_t>(patch)];
    if (inside != bounds || bounds.area() == 0) {
      m.flag = PatchFlag::kTooFewPixels;
      continue;
    }
    cv::Mat mask = cv::Mat::zeros(bounds.size(), CV_8U);
    for (auto& p : polygon) p -= bounds.tl();
    cv::fillConvexPoly(mask, polygon, cv::Scalar(255));
    for (auto& v : values) v.clear();
    for (int y = 0; y < bounds.height; ++y) {
      const cv::Vec3d* raw = image.ptr<cv::Vec3d>(bounds.y + y) + bounds.x;
      const cv::Vec3d* black = dark.empty() ? nullptr : dark.ptr<cv::Vec3d>(bounds.y + y) + bounds.x;
      const std::uint8_t* inside_mask = mask.ptr<std::uint8_t>(y);
      for (int x = 0; x < bounds.width; ++x) {
        if (!inside_mask[x]) continue;
        ++m.pixels;
        if (raw[x][0] >= clip_level || raw[x][1] >= clip_level || raw[x][2] >= clip_level) {
          ++m.clipped_pixels;
          continue;
        }
        for (int c = 0; c < 3; ++c)  // B, G, R in; r, g, b out
          values[static_cast<std::size_t>(2 - c)].push_back(raw[x][c] - (black ? black[x][c] : options.black_level));
      }
    }
    const int kept = m.pixels - m.clipped_pixels;
    if (m.pixels < options.min_pixels) {
      m.flag = PatchFlag::kTooFewPixels;
      continue;
    }
    if (m.clipped_pixels > options.max_clipped_fraction * m.pixels || kept < 2) {
      m.flag = PatchFlag::kSaturated;
      continue;
    }
    const std::size_t drop = static_cast<std::size_t>(options.trim_fraction * kept);
    double worst_snr = std::numeric_limits<double>::infinity();
    for (int c = 0; c < 3; ++c) {
      std::vector<double>& v = values[static_cast<std::size_t>(c)];
      std::sort(v.begin(), v.end());
      double sum = 0.0, sum_sq = 0.0;
      const std::size_t n = v.size() - 2 * drop;
      for (std::size_t i = drop; i < v.size() - drop; ++i) sum += v[i];
      const double mean = sum / static_cast<double>(n);
      for (std::size_t i = drop; i < v.size() - drop; ++i) sum_sq += (v[i] - mean) * (v[i] - mean);
      m.rgb[c] = mean;
      m.stddev[c] = std::sqrt(sum_sq / std::max<double>(1.0, static_cast<double>(n) - 1.0));
      const double standard_error = m.stddev[c] / std::sqrt(static_cast<double>(n));
      worst_snr = std::min(worst_snr, mean <= 0.0 ? 0.0 : standard_error > 0.0 ? mean / standard_error : worst_snr);
    }
    if (worst_snr < options.min_snr) m.flag = PatchFlag::kUnderexposed;
  }
  *patches_out = std::move(patches);
  return timer.Succeeded();
}

ChartReference ColorCheckerReference(Illuminant illuminant, const std::vector<double>& grid_nm) {
  ChartReference reference;
  const SampledSpectra& reflectance = ColorChecker24Reflectance();
  for (std::size_t patch = 0; patch < kChartPatches; ++patch)
    reference.xyz.push_back(ReflectanceToXyz(reflectance, patch, illuminant, grid_nm));
  reference.white_xyz = WhitePointXyz(illuminant, grid_nm);
  return reference;
}

std::optional<ChartCaptureSpectra> ChartCaptureSpectraFor(const std::string& camera, Illuminant illuminant,
                                                          const std::vector<double>& grid_nm) {
  const SampledSpectra* camera_sensitivity = CameraSensitivity(camera);
  if (!camera_sensitivity) return std::nullopt;
  ChartCaptureSpectra out;
  out.wavelength_nm = grid_nm;
  const SampledSpectra reflectance = ColorChecker24Reflectance().Resampled(grid_nm);
  out.patch_reflectance = reflectance.channels;
  out.illuminant = IlluminantSpd(illuminant).Resampled(grid_nm).channels[0];
  const SampledSpectra sensitivity = camera_sensitivity->Resampled(grid_nm);
  for (int c = 0; c < 3; ++c) out.camera_sensitivity[static_cast<std::size_t>(c)] = sensitivity.channels[static_cast<std::size_t>(c)];
  return out;
}

}  // namespace photorig::solvers::color
