#include "photorig/solvers/lighting/sphere.h"

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace photorig::solvers::lighting {

bool CameraModel::IsValid(std::string* why) const {
  if (projection == Projection::kPinhole && !(fx_px > 0.0 && fy_px > 0.0)) {
    if (why) *why = "pinhole camera needs positive fx_px and fy_px";
    return false;
  }
  return true;
}

Eigen::Vector3d CameraModel::RayDirection(double u, double v) const {
  if (projection == Projection::kOrthographic) return {0.0, 0.0, -1.0};
  // Row 0 is the top and y points up, so image v grows against y.
  return Eigen::Vector3d((u - cx_px) / fx_px, -(v - cy_px) / fy_px, -1.0).normalized();
}

bool SphereFitOptions::IsValid(std::string* why) const {
  if (!(min_radius_px > 0.0) || !(outlier_sigma > 0.0) || refinement_rounds < 0) {
    if (why) *why = "min_radius_px and outlier_sigma must be positive, refinement_rounds >= 0";
    return false;
  }
  return true;
}

namespace {

double Percentile(const cv::Mat& image, double fraction) {
  std::vector<float> values(image.begin<float>(), image.end<float>());
  const auto k = static_cast<std::size_t>(fraction * static_cast<double>(values.size() - 1));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

// Kasa: x^2 + y^2 + D x + E y + F = 0, linear in (D, E, F).
Circle AlgebraicCircle(const std::vector<Eigen::Vector2d>& points) {
  Eigen::MatrixXd a(static_cast<Eigen::Index>(points.size()), 3);
  Eigen::VectorXd b(static_cast<Eigen::Index>(points.size()));
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto r = static_cast<Eigen::Index>(i);
    a.row(r) << points[i].x(), points[i].y(), 1.0;
    b(r) = -points[i].squaredNorm();
  }
  const Eigen::Vector3d s = a.colPivHouseholderQr().solve(b);
  Circle c;
  c.cx_px = -s(0) / 2.0;
  c.cy_px = -s(1) / 2.0;
  c.radius_px = std::sqrt(std::max(0.0, c.cx_px * c.cx_px + c.cy_px * c.cy_px - s(2)));
  return c;
}

// Gauss-Newton on the geometric distance |p - c| - r.
Circle GeometricCircle(const std::vector<Eigen::Vector2d>& points, Circle c) {
  for (int iteration = 0; iteration < 20; ++iteration) {
    Eigen::Matrix3d jtj = Eigen::Matrix3d::Zero();
    Eigen::Vector3d jtr = Eigen::Vector3d::Zero();
    for (const auto& p : points) {
      const Eigen::Vector2d d(p.x() - c.cx_px, p.y() - c.cy_px);
      const double distance = d.norm();
      if (distance < 1e-12) continue;
      const Eigen::Vector3d j(-d.x() / distance, -d.y() / distance, -1.0);
      jtj += j * j.transpose();
      jtr += j * (distance - c.radius_px);
    }
    const Eigen::Vector3d step = jtj.ldlt().solve(-jtr);
    c.cx_px += step(0);
    c.cy_px += step(1);
    c.radius_px += step(2);
    if (step.norm() < 1e-9) break;
  }
  return c;
}

}  // namespace

SphereFitSummary FitSphereSilhouette(const cv::Mat& image, const SphereFitOptions& options) {
  const solvers::core::SolveTimer timer;
  SphereFitSummary summary;
  if (solvers::core::EndIfInvalid(options, &summary)) return summary;
  if (image.empty() || image.channels() != 1) {
    summary.End(solvers::core::Termination::kInvalidInput, "sphere fit needs a non-empty single-channel image");
    return summary;
  }
  cv::Mat values;
  image.convertTo(values, CV_32F);
  const double threshold =
      options.threshold >= 0.0 ? options.threshold : 0.5 * (Percentile(values, 0.02) + Percentile(values, 0.98));

  cv::Mat inside = values >= threshold;
  cv::Mat labels, stats, centroids;
  const int count = cv::connectedComponentsWithStats(inside, labels, stats, centroids, 8, CV_32S);
  int best = -1;
  for (int label = 1; label < count; ++label) {
    if (best < 0 || stats.at<int>(label, cv::CC_STAT_AREA) > stats.at<int>(best, cv::CC_STAT_AREA)) best = label;
  }
  if (best < 0 || stats.at<int>(best, cv::CC_STAT_AREA) < M_PI * options.min_radius_px * options.min_radius_px) {
    summary.End(solvers::core::Termination::kFailure,
                "no blob above threshold " + std::to_string(threshold) + " large enough for a sphere");
    return summary;
  }
  const int left = stats.at<int>(best, cv::CC_STAT_LEFT), top = stats.at<int>(best, cv::CC_STAT_TOP);
  summary.touches_border = left == 0 || top == 0 ||
                           left + stats.at<int>(best, cv::CC_STAT_WIDTH) == image.cols ||
                           top + stats.at<int>(best, cv::CC_STAT_HEIGHT) == image.rows;
  // Crossings next to the chosen blob only: background speckle and other blobs stay out.
  cv::Mat near_blob;
  cv::dilate(labels == best, near_blob, cv::Mat(), cv::Point(-1, -1), 2);

  std::vector<Eigen::Vector2d> points;
  auto crossing = [&](double a, double b) { return (threshold - a) / (b - a); };
  for (int r = 0; r < values.rows; ++r) {
    const float* row = values.ptr<float>(r);
    const float* next_row = r + 1 < values.rows ? values.ptr<float>(r + 1) : nullptr;
    const std::uint8_t* near = near_blob.ptr<std::uint8_t>(r);
    for (int c = 0; c < values.cols; ++c) {
      if (!near[c]) continue;
      const bool here = row[c] >= threshold;
      if (c + 1 < values.cols && near[c + 1] && here != (row[c + 1] >= threshold)) {
        points.emplace_back(c + crossing(row[c], row[c + 1]), r);
      }
      if (next_row && near_blob.at<std::uint8_t>(r + 1, c) && here != (next_row[c] >= threshold)) {
        points.emplace_back(c, r + crossing(row[c], next_row[c]));
      }
    }
  }
  if (points.size() < 8) {
    summary.End(solvers::core::Termination::kFailure, "too few silhouette edge points");
    return summary;
  }

  Circle circle = GeometricCircle(points, AlgebraicCircle(points));
  std::size_t total = points.size();
  for (int round = 0; round < options.refinement_rounds; ++round) {
    std::vector<double> residuals;
    residuals.reserve(points.size());
    for (const auto& p : points) {
      residuals.push_back(std::abs((p - Eigen::Vector2d(circle.cx_px, circle.cy_px)).norm() - circle.radius_px));
    }
    std::vector<double> sorted = residuals;
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
    // Median absolute residual -> sigma; a floor keeps a perfect fit from rejecting rounding.
    const double sigma = std::max(1.4826 * sorted[sorted.size() / 2], 0.05);
    std::vector<Eigen::Vector2d> kept;
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (residuals[i] <= options.outlier_sigma * sigma) kept.push_back(points[i]);
    }
    if (kept.size() == points.size() || kept.size() < 8) break;
    points.swap(kept);
    circle = GeometricCircle(points, circle);
  }

  double sum_squares = 0.0;
  std::vector<cv::Point2f> cv_points;
  cv_points.reserve(points.size());
  for (const auto& p : points) {
    const double residual = (p - Eigen::Vector2d(circle.cx_px, circle.cy_px)).norm() - circle.radius_px;
    sum_squares += residual * residual;
    cv_points.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  }
  const cv::RotatedRect ellipse = cv::fitEllipse(cv_points);
  summary.ellipse_axis_ratio = std::min(ellipse.size.width, ellipse.size.height) /
                               std::max(ellipse.size.width, ellipse.size.height);
  summary.circle = circle;
  summary.rms_residual_px = std::sqrt(sum_squares / static_cast<double>(points.size()));
  summary.edge_points_used = static_cast<int>(points.size());
  summary.edge_points_rejected = static_cast<int>(total - points.size());
  summary.edge_points = std::move(points);
  if (circle.radius_px >= options.min_radius_px) {
    summary.End(solvers::core::Termination::kSuccess, summary.touches_border ? "silhouette touches the image border" : "");
  } else {
    summary.End(solvers::core::Termination::kFailure, "fitted circle smaller than min_radius_px");
  }
  timer.Finish(&summary);
  return summary;
}

SphereGeometry LocateSphere(const CameraModel& camera, const Circle& circle,
                            const std::vector<Eigen::Vector2d>& edge_points) {
  SphereGeometry sphere;
  sphere.camera = camera;
  sphere.circle = circle;
  std::string why;
  if (!camera.IsValid(&why)) {
    sphere.message = why;
    return sphere;
  }
  if (!(circle.radius_px > 0.0)) {
    sphere.message = "circle radius must be positive";
    return sphere;
  }
  if (camera.projection == CameraModel::Projection::kOrthographic) {
    sphere.valid = true;
    return sphere;
  }
  // Rays d_i grazing the sphere make a fixed angle alpha with the axis a:
  // d_i . (a / cos alpha) = 1 is linear in b = a / cos alpha.
  std::vector<Eigen::Vector2d> points = edge_points;
  if (points.size() < 8) {
    points.clear();
    for (int i = 0; i < 72; ++i) {
      const double angle = 2.0 * M_PI * i / 72.0;
      points.emplace_back(circle.cx_px + circle.radius_px * std::cos(angle),
                          circle.cy_px + circle.radius_px * std::sin(angle));
    }
  }
  Eigen::MatrixXd rays(static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t i = 0; i < points.size(); ++i) {
    rays.row(static_cast<Eigen::Index>(i)) = camera.RayDirection(points[i].x(), points[i].y()).transpose();
  }
  const Eigen::Vector3d b =
      rays.colPivHouseholderQr().solve(Eigen::VectorXd::Ones(static_cast<Eigen::Index>(points.size())));
  const double cos_alpha = 1.0 / b.norm();
  if (!(cos_alpha < 1.0)) {
    sphere.message = "silhouette cone is degenerate";
    return sphere;
  }
  const double sin_alpha = std::sqrt(1.0 - cos_alpha * cos_alpha);
  sphere.centre = b.normalized() / sin_alpha;  // distance 1 / sin(alpha) radii
  sphere.valid = true;
  return sphere;
}

bool SurfaceAt(const SphereGeometry& sphere, double u, double v, SurfacePoint* point) {
  if (sphere.camera.projection == CameraModel::Projection::kOrthographic) {
    const double x = (u - sphere.circle.cx_px) / sphere.circle.radius_px;
    const double y = -(v - sphere.circle.cy_px) / sphere.circle.radius_px;
    const double rho2 = x * x + y * y;
    if (rho2 > 1.0) return false;
    point->normal = Eigen::Vector3d(x, y, std::sqrt(1.0 - rho2));
    point->to_camera = Eigen::Vector3d(0.0, 0.0, 1.0);
    point->position = point->normal;
    return true;
  }
  const Eigen::Vector3d d = sphere.camera.RayDirection(u, v);
  const double b = d.dot(sphere.centre);
  const double discriminant = b * b - sphere.centre.squaredNorm() + 1.0;
  if (discriminant < 0.0) return false;
  const double t = b - std::sqrt(discriminant);
  point->position = t * d;
  point->normal = (point->position - sphere.centre).normalized();
  point->to_camera = -d;
  return true;
}

}  // namespace photorig::solvers::lighting
