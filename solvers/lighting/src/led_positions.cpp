#include "photorig/solvers/lighting/led_positions.h"

#include "photorig/solvers/core/flags.h"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>

namespace photorig::solvers::lighting {

bool LedPositionOptions::IsValid(std::string* why) const {
  if (!highlight.IsValid(why)) return false;
  if (!(ray_tolerance_sigmas > 0.0) || !std::isfinite(ray_tolerance_sigmas))
    return core::Refuse(why, "ray_tolerance_sigmas must be > 0");
  if (!(min_ray_tolerance_mm >= 0.0) || !std::isfinite(min_ray_tolerance_mm))
    return core::Refuse(why, "min_ray_tolerance_mm must be >= 0");
  return true;
}

std::string LedFlagsToString(unsigned flags) {
  static constexpr std::array<std::pair<unsigned, const char*>, 4> kNames = {{{kLedTooFewRays, "too-few-rays"},
                                                                              {kLedRaysApart, "rays-apart"},
                                                                              {kLedNotTriangulated, "not-triangulated"},
                                                                              {kLedUncertain, "uncertain"}}};
  return core::FlagNames(flags, kNames);
}

namespace {

constexpr double kDegToRad = M_PI / 180.0;

// A ball as the highlight search sees it: its image circle (the projection of
// the known centre) and, for a pinhole camera, its centre in the camera frame
// in units of its radius. The camera frame is the dome's moved up to the
// pinhole, so the two share their axes.
SphereGeometry BallGeometry(const camera::Camera& camera, const Eigen::Vector3d& centre_mm, double radius_mm) {
  SphereGeometry ball;
  ball.valid = true;
  if (!camera.IsPinhole()) {
    const double p = camera.pixel_pitch_mm;
    ball.circle = {centre_mm.x() / p + 0.5 * camera.width_px - 0.5, 0.5 * camera.height_px - 0.5 - centre_mm.y() / p,
                   radius_mm / p};
    return ball;
  }
  const camera::PinholeLens& lens = camera.pinhole;
  ball.camera = {CameraModel::Projection::kPinhole, lens.fx_px, lens.fy_px, lens.cx_px, lens.cy_px};
  const Eigen::Vector3d centre = centre_mm - Eigen::Vector3d(0.0, 0.0, lens.distance_mm);
  ball.centre = centre / radius_mm;
  // The silhouette is the cone of rays grazing the ball; the circle about the
  // centre's image through the cone's farthest image point bounds it.
  const double sin_alpha = radius_mm / centre.norm(), cos_alpha = std::sqrt(1.0 - sin_alpha * sin_alpha);
  const Eigen::Vector3d axis = centre.normalized(), e1 = axis.unitOrthogonal(), e2 = axis.cross(e1);
  const auto project = [&lens](const Eigen::Vector3d& d) {
    return Eigen::Vector2d(lens.cx_px + lens.fx_px * d.x() / -d.z(), lens.cy_px - lens.fy_px * d.y() / -d.z());
  };
  const Eigen::Vector2d middle = project(axis);
  double reach = 0.0;
  for (int i = 0; i < 72; ++i) {
    const double phi = 2.0 * M_PI * i / 72.0;
    const Eigen::Vector3d grazing = cos_alpha * axis + sin_alpha * (std::cos(phi) * e1 + std::sin(phi) * e2);
    reach = std::max(reach, (project(grazing) - middle).norm());
  }
  ball.circle = {middle.x(), middle.y(), reach + 1.0};  // a pixel of margin for the 5-degree sampling
  return ball;
}

// What makes the balls unusable for this camera, or "" when nothing does.
std::string CheckLayout(const camera::Camera& camera, const MirrorSphereLayout& spheres) {
  std::string why;
  if (!camera.IsValid(&why)) return "camera: " + why;
  if (camera.IsPinhole() && std::any_of(camera.pinhole.distortion.begin(), camera.pinhole.distortion.end(),
                                        [](double k) { return k != 0.0; }))
    return "the camera's lens has distortion, which the highlight search does not model: undistort the frames "
           "and give the lens without distortion";
  if (spheres.centres_mm.size() < 2) return "LED positions need two or more mirror spheres";
  if (!(spheres.radius_mm > 0.0) || !std::isfinite(spheres.radius_mm)) return "the spheres' radius must be > 0";
  for (std::size_t i = 0; i < spheres.centres_mm.size(); ++i) {
    const Eigen::Vector3d& c = spheres.centres_mm[i];
    const std::string name = "sphere " + std::to_string(i);
    if (!c.allFinite()) return name + ": the centre must be finite";
    for (std::size_t j = 0; j < i; ++j)
      if ((c - spheres.centres_mm[j]).norm() < 2.0 * spheres.radius_mm)
        return name + " overlaps sphere " + std::to_string(j) + " (centres closer than two radii)";
    if (camera.IsPinhole() && !(c.z() + spheres.radius_mm < camera.pinhole.distance_mm))
      return name + " reaches the camera (its top above distance_mm)";
    const Circle circle = BallGeometry(camera, c, spheres.radius_mm).circle;
    if (circle.cx_px - circle.radius_px < -0.5 || circle.cy_px - circle.radius_px < -0.5 ||
        circle.cx_px + circle.radius_px > camera.width_px - 0.5 || circle.cy_px + circle.radius_px > camera.height_px - 0.5)
      return name + " at (" + std::to_string(c.x()) + ", " + std::to_string(c.y()) + ") mm is not wholly in the camera's view";
  }
  return "";
}

// The highlight's centre as the first moment of the background-subtracted
// light over a window holding the whole blob. The highlight search weights
// only what exceeds half the peak, which for a blob of a few pixels leaves
// its centroid quantised to a fraction of a pixel (0.2 px: 2 mm across a ray
// at 250 mm, five times that along it); a camera integrates each pixel's
// area, and the plain first moment of that is the blob's own, to the noise.
// The highlight's uncertainty_deg becomes this centre's.
void RefineHighlight(const cv::Mat& frame, const SphereGeometry& ball, LightDirectionEstimate* highlight) {
  const double reach = std::sqrt(highlight->blob_area_px / M_PI) + 3.0;
  const int r0 = std::max(0, static_cast<int>(std::floor(highlight->highlight_px.y() - reach)));
  const int r1 = std::min(frame.rows - 1, static_cast<int>(std::ceil(highlight->highlight_px.y() + reach)));
  const int c0 = std::max(0, static_cast<int>(std::floor(highlight->highlight_px.x() - reach)));
  const int c1 = std::min(frame.cols - 1, static_cast<int>(std::ceil(highlight->highlight_px.x() + reach)));
  cv::Mat window;
  frame(cv::Range(r0, r1 + 1), cv::Range(c0, c1 + 1)).convertTo(window, CV_64F);
  // The background: the median of the window's rim, which the blob does not reach.
  std::vector<double> rim;
  for (int r = 0; r < window.rows; ++r)
    for (int c = 0; c < window.cols; ++c)
      if (r == 0 || c == 0 || r == window.rows - 1 || c == window.cols - 1) rim.push_back(window.at<double>(r, c));
  const auto median = [](std::vector<double> values) {
    std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2), values.end());
    return values[values.size() / 2];
  };
  const double background = median(rim);
  for (double& value : rim) value = std::abs(value - background);
  const double noise = 1.4826 * median(rim);
  double sum = 0.0, su = 0.0, sv = 0.0;
  std::vector<Eigen::Vector2d> used;
  SurfacePoint point;
  for (int r = 0; r < window.rows; ++r)
    for (int c = 0; c < window.cols; ++c) {
      const double w = window.at<double>(r, c) - background;
      if (w <= 0.0 || !SurfaceAt(ball, c0 + c, r0 + r, &point)) continue;
      sum += w;
      su += w * (c0 + c);
      sv += w * (r0 + r);
      used.emplace_back(c0 + c, r0 + r);
    }
  if (!(sum > 0.0) || !SurfaceAt(ball, su / sum, sv / sum, &point)) return;  // keep the search's centroid
  highlight->highlight_px = {su / sum, sv / sum};
  highlight->normal = point.normal;
  highlight->surface_position = point.position;
  highlight->direction = (2.0 * point.to_camera.dot(point.normal) * point.normal - point.to_camera).normalized();
  // Each pixel's noise moves the first moment by its distance from it over
  // the sum; per axis sigma^2 = noise^2 sum d^2 / 2 / sum^2. Added to it,
  // kModelPx: a blob about 3 px across on the pixel grid, and the image of
  // a disc on a curved mirror not centred on its centre's image. With 0.02 px
  // the simulated dome's position errors are 0.89 times the predicted sigma
  // (RMS; 1.9 at most). The normal turns by sigma over the radius and cos(theta).
  constexpr double kModelPx = 0.02;
  // A blob narrower than a pixel is located to no better than the pixel: the
  // first moment of pixel-integrated light is that of each pixel's light put
  // at the pixel's centre, off by E[round(x) - x] under the blob, whose RMS
  // over where the blob falls is 1/sqrt(12) px for a point and falls as
  // exp(-2 pi^2 s^2) for a blob of width s (the sawtooth's first harmonic).
  // s^2 is the light's second moment less a pixel's own 1/12, over the
  // pixels clear of the noise (the noise's own spread would widen it).
  double squares = 0.0, moment = 0.0, clear = 0.0;
  for (const Eigen::Vector2d& at : used) {
    const double d2 = (at - highlight->highlight_px).squaredNorm();
    squares += d2;
    const double w = window.at<double>(static_cast<int>(at.y()) - r0, static_cast<int>(at.x()) - c0) - background;
    if (w <= 3.0 * noise) continue;
    moment += w * d2;
    clear += w;
  }
  const double blob_variance = clear > 0.0 ? std::max(0.0, 0.5 * moment / clear - 1.0 / 12.0) : 0.0;
  const double sampling_px = std::exp(-2.0 * M_PI * M_PI * blob_variance) / std::sqrt(12.0);
  const double sigma_px = std::sqrt(std::pow(noise * std::sqrt(0.5 * squares) / sum, 2) + kModelPx * kModelPx +
                                    sampling_px * sampling_px);
  const double cos_normal = std::clamp(point.to_camera.dot(point.normal), 1e-6, 1.0);
  highlight->uncertainty_deg = 2.0 * sigma_px / (ball.circle.radius_px * cos_normal) / kDegToRad;
}

// The reflection ray of one ball's highlight, in the dome frame.
struct Ray {
  Eigen::Vector3d origin_mm;
  Eigen::Vector3d direction;
  double sigma_rad;  // one-sigma direction error per axis, predicted from the highlight
};

Ray ReflectionRay(const camera::Camera& camera, const Eigen::Vector3d& centre_mm, double radius_mm,
                  const LightDirectionEstimate& highlight) {
  // surface_position: relative to the centre (orthographic) or to the pinhole (pinhole), in radii.
  const Eigen::Vector3d base = camera.IsPinhole() ? Eigen::Vector3d(0.0, 0.0, camera.pinhole.distance_mm) : centre_mm;
  return {base + radius_mm * highlight.surface_position, highlight.direction, highlight.uncertainty_deg * kDegToRad};
}

// Triangulates the usable rays and judges them against their predicted spread.
void PlaceLed(const std::vector<Ray>& rays, const LedPositionOptions& options, LedPositionEstimate* led) {
  if (rays.size() < 2) {
    led->flags |= kLedTooFewRays;
    led->note = std::to_string(rays.size()) + " usable highlight(s): a position needs two";
    return;
  }
  std::vector<Eigen::Vector3d> origins, directions;
  for (const Ray& ray : rays) {
    origins.push_back(ray.origin_mm);
    directions.push_back(ray.direction);
  }
  const NearLightEstimate near = TriangulateNearLight(origins, directions);
  led->position_mm = near.position_mm;
  led->rms_ray_distance_mm = near.rms_ray_distance_mm;
  if (!near.usable) {
    led->flags |= kLedNotTriangulated;
    led->note = near.message;
    return;
  }
  // A direction error sigma moves ray k sideways by sigma L_k at the LED
  // (L_k its length): the position's covariance is A^-1 (sum (sigma L)^2 P_k) A^-1
  // with P_k the projector across ray k and A = sum P_k. The fit absorbs 3 of
  // the rays' 2N sideways components, so their mean squared distance from it
  // is (2N - 3) / (2N) of the 2 (sigma L)^2 each would show alone.
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero(), spread = Eigen::Matrix3d::Zero();
  double expected_squares = 0.0;
  for (const Ray& ray : rays) {
    const Eigen::Vector3d d = ray.direction.normalized();
    const Eigen::Matrix3d across = Eigen::Matrix3d::Identity() - d * d.transpose();
    const double sideways = ray.sigma_rad * (led->position_mm - ray.origin_mm).dot(d);
    a += across;
    spread += sideways * sideways * across;
    expected_squares += 2.0 * sideways * sideways;
  }
  const Eigen::Matrix3d inverse = a.inverse();
  const Eigen::Matrix3d covariance = inverse * spread * inverse;
  led->predicted_sigma_mm = std::sqrt(std::max(0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(covariance).eigenvalues()(2)));
  const double n = static_cast<double>(rays.size());
  const double expected_rms_mm = std::sqrt(expected_squares * (2.0 * n - 3.0) / (2.0 * n) / n);
  led->ray_tolerance_mm = std::max(options.min_ray_tolerance_mm, options.ray_tolerance_sigmas * expected_rms_mm);
  if (led->rms_ray_distance_mm > led->ray_tolerance_mm) {
    led->flags |= kLedRaysApart;
    led->note = "the rays pass " + std::to_string(led->rms_ray_distance_mm) + " mm RMS from their meeting point, more than " +
                std::to_string(led->ray_tolerance_mm) + " mm";
    return;
  }
  // The position's error as a direction from the sample's centre.
  const double uncertainty_deg = std::atan2(led->predicted_sigma_mm, led->position_mm.norm()) / kDegToRad;
  if (uncertainty_deg > options.highlight.max_uncertainty_deg) {
    led->flags |= kLedUncertain;
    std::ostringstream note;
    note.precision(3);
    note << "the position is known to " << led->predicted_sigma_mm << " mm (one sigma), " << uncertainty_deg
         << " deg seen from the sample, more than " << options.highlight.max_uncertainty_deg
         << " deg: larger balls or brighter, sharper highlights place it better";
    led->note = note.str();
    return;
  }
  led->usable = true;
  led->note = "triangulated from " + std::to_string(rays.size()) + " spheres";
}

}  // namespace

LedPositionSummary EstimateLedPositions(const std::vector<cv::Mat>& frames, const camera::Camera& camera,
                                        const MirrorSphereLayout& spheres, const LedPositionOptions& options) {
  core::SolveTimer timer;
  LedPositionSummary summary;
  if (core::EndIfInvalid(options, &summary)) return summary;
  if (core::EndIfBadInput(CheckLayout(camera, spheres), &summary)) return summary;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const cv::Mat& frame = frames[k];
    if (!frame.empty() && (frame.channels() != 1 || frame.cols != camera.width_px || frame.rows != camera.height_px))
      return timer.End(&summary, core::Termination::kInvalidInput,
                       "frame " + std::to_string(k) + " is not a single-channel " + std::to_string(camera.width_px) +
                           " x " + std::to_string(camera.height_px) + " image of the camera");
  }
  if (frames.empty()) return timer.End(&summary, core::Termination::kInvalidInput, "no frames");
  std::vector<SphereGeometry> balls;
  for (const Eigen::Vector3d& centre : spheres.centres_mm) {
    balls.push_back(BallGeometry(camera, centre, spheres.radius_mm));
    summary.sphere_circles.push_back(balls.back().circle);
  }
  timer.SetupDone(&summary);

  double rms_sum = 0.0;
  for (const cv::Mat& frame : frames) {
    LedPositionEstimate& led = summary.leds.emplace_back();
    std::vector<Ray> rays;
    for (std::size_t s = 0; s < balls.size(); ++s) {
      LightDirectionEstimate highlight;
      if (frame.empty()) {
        highlight.flags = kLightMissing;
        highlight.note = "no frame";
      } else {
        highlight = EstimateLightDirection(frame, balls[s], options.highlight);
        if (highlight.usable) RefineHighlight(frame, balls[s], &highlight);
      }
      if (highlight.usable) {
        rays.push_back(ReflectionRay(camera, spheres.centres_mm[s], spheres.radius_mm, highlight));
        led.used_spheres.push_back(static_cast<int>(s));
      }
      led.highlights.push_back(std::move(highlight));
    }
    PlaceLed(rays, options, &led);
    if (led.usable) {
      ++summary.usable;
      rms_sum += led.rms_ray_distance_mm;
    } else {
      ++summary.unusable;
    }
  }
  summary.mean_rms_ray_distance_mm = summary.usable > 0 ? rms_sum / summary.usable : 0.0;
  const std::string counts = std::to_string(summary.usable) + " of " + std::to_string(summary.leds.size()) + " LEDs placed";
  return timer.End(&summary, summary.usable > 0 ? core::Termination::kSuccess : core::Termination::kFailure, counts);
}

}  // namespace photorig::solvers::lighting
