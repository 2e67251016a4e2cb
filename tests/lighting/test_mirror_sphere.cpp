#include "photorig/solvers/lighting/mirror_sphere.h"
#include "synthetic_sphere.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace photorig::solvers::lighting {
namespace {

using testing::AngleDeg;
using testing::SyntheticCamera;
using testing::SyntheticImageOptions;
using testing::SyntheticLight;
using testing::SyntheticSphere;

struct SphereScene {
  SyntheticCamera camera;
  SyntheticSphere sphere;
  SyntheticImageOptions options;
  SphereGeometry geometry;
};

SphereScene Orthographic(double radius_px) {
  SphereScene s;
  s.sphere.centre_mm = {0.83, -0.41, 0.0};
  s.sphere.radius_mm = radius_px * s.camera.pixel_pitch_mm;
  s.options.width = s.options.height = static_cast<int>(2 * radius_px + 40);
  s.options.noise_sigma = 3.0;
  const SphereFitSummary fit = FitSphereSilhouette(testing::RenderSilhouette(s.camera, s.sphere, s.options));
  s.geometry = LocateSphere(CameraModel{}, fit.circle);
  return s;
}

SphereScene Pinhole() {
  SphereScene s;
  s.camera.pinhole = true;
  s.camera.fx_px = s.camera.fy_px = 1400.0;
  s.camera.cx_px = 319.5;
  s.camera.cy_px = 239.5;
  s.sphere.centre_mm = {40.0, 20.0, -330.0};
  s.sphere.radius_mm = 25.0;
  s.options.width = 640;
  s.options.height = 480;
  s.options.noise_sigma = 3.0;
  CameraModel model;
  model.projection = CameraModel::Projection::kPinhole;
  model.fx_px = model.fy_px = 1400.0;
  model.cx_px = 319.5;
  model.cy_px = 239.5;
  const SphereFitSummary fit = FitSphereSilhouette(testing::RenderSilhouette(s.camera, s.sphere, s.options));
  s.geometry = LocateSphere(model, fit.circle, fit.edge_points);
  return s;
}

// Mean direction error over the dome's lights; every light must be usable.
double MeanDomeError(const SphereScene& s, const SphereGeometry& geometry, double* worst_normalised = nullptr) {
  double sum = 0.0;
  int count = 0;
  for (const Eigen::Vector3d& direction : testing::DomeDirections()) {
    SyntheticLight light;
    light.direction = direction;
    SyntheticImageOptions options = s.options;
    options.seed = static_cast<unsigned>(count + 7);
    const LightDirectionEstimate e =
        EstimateLightDirection(testing::RenderMirrorSphere(s.camera, s.sphere, {light}, options), geometry);
    EXPECT_TRUE(e.usable) << e.note;
    const double error = AngleDeg(e.direction, direction);
    if (worst_normalised) *worst_normalised = std::max(*worst_normalised, error / e.uncertainty_deg);
    sum += error;
    ++count;
  }
  return sum / count;
}

TEST(MirrorSphere, OrthographicDomeWithinHalfADegree) {
  const SphereScene s = Orthographic(110.0);
  ASSERT_TRUE(s.geometry.valid);
  double worst = 0.0;
  const double mean = MeanDomeError(s, s.geometry, &worst);
  EXPECT_LE(mean, 0.5);
  RecordProperty("mean_error_deg", std::to_string(mean));
  // The predicted one-sigma uncertainty is a usable scale for the error.
  EXPECT_LT(worst, 4.0);
}

TEST(MirrorSphere, PinholeModelWithinOneDegreeWhereOrthographicIsNot) {
  const SphereScene s = Pinhole();
  ASSERT_TRUE(s.geometry.valid) << s.geometry.message;
  EXPECT_LE(MeanDomeError(s, s.geometry), 1.0);
  // The same images read with the orthographic model are measurably wrong.
  const SphereGeometry orthographic = LocateSphere(CameraModel{}, s.geometry.circle);
  double sum = 0.0;
  int count = 0;
  const std::vector<Eigen::Vector3d> dome = testing::DomeDirections();
  for (std::size_t k = 0; k < dome.size(); k += 4) {
    SyntheticLight light;
    light.direction = dome[k];
    const LightDirectionEstimate e =
        EstimateLightDirection(testing::RenderMirrorSphere(s.camera, s.sphere, {light}, s.options), orthographic);
    sum += AngleDeg(e.direction, dome[k]);
    ++count;
  }
  EXPECT_GT(sum / count, 2.0);
}

TEST(MirrorSphere, SaturatedBlobCentroidStaysAccurate) {
  const SphereScene s = Orthographic(110.0);
  SyntheticLight light;
  light.direction = Eigen::Vector3d(0.5, -0.3, 0.8).normalized();
  light.peak = 40000.0;  // ten times full scale: a wide clipped blob
  light.angular_sigma_deg = 1.5;
  const LightDirectionEstimate e =
      EstimateLightDirection(testing::RenderMirrorSphere(s.camera, s.sphere, {light}, s.options), s.geometry);
  EXPECT_TRUE(e.flags & kLightSaturated);
  EXPECT_TRUE(e.usable) << e.note;
  EXPECT_GT(e.blob_area_px, 20);
  EXPECT_LT(AngleDeg(e.direction, light.direction), 0.5);
}

TEST(MirrorSphere, MissingNearSilhouetteAndDoubleHighlightsAreFlagged) {
  const SphereScene s = Orthographic(110.0);
  const LightDirectionEstimate dark =
      EstimateLightDirection(testing::RenderMirrorSphere(s.camera, s.sphere, {}, s.options), s.geometry);
  EXPECT_FALSE(dark.usable);
  EXPECT_TRUE(dark.flags & kLightMissing);

  SyntheticLight grazing;  // 170 degrees from the view: normal 85 degrees from it
  grazing.direction = Eigen::Vector3d(std::sin(170 * M_PI / 180), 0.0, std::cos(170 * M_PI / 180));
  const LightDirectionEstimate rim =
      EstimateLightDirection(testing::RenderMirrorSphere(s.camera, s.sphere, {grazing}, s.options), s.geometry);
  EXPECT_FALSE(rim.usable);
  EXPECT_TRUE(rim.flags & kLightNearSilhouette) << rim.note;

  SyntheticLight a, b;
  a.direction = Eigen::Vector3d(0.3, 0.2, 0.9).normalized();
  b.direction = Eigen::Vector3d(-0.5, 0.1, 0.8).normalized();
  b.peak = 2900.0;
  const LightDirectionEstimate two =
      EstimateLightDirection(testing::RenderMirrorSphere(s.camera, s.sphere, {a, b}, s.options), s.geometry);
  EXPECT_FALSE(two.usable);
  EXPECT_TRUE(two.flags & kLightMultipleHighlights) << two.note;
}

TEST(MirrorSphere, UncertaintyGrowsAsTheSphereShrinks) {
  SyntheticLight light;
  light.direction = Eigen::Vector3d(0.4, 0.3, 0.87).normalized();
  const SphereScene big = Orthographic(110.0), small = Orthographic(30.0);
  const auto estimate = [&](const SphereScene& s) {
    return EstimateLightDirection(testing::RenderMirrorSphere(s.camera, s.sphere, {light}, s.options), s.geometry);
  };
  EXPECT_GT(estimate(small).uncertainty_deg, 2.5 * estimate(big).uncertainty_deg);
}

TEST(MirrorSphere, TwoSpheresTriangulateANearLight) {
  SyntheticCamera camera;
  SyntheticImageOptions options;
  options.width = 640;
  options.height = 320;
  SyntheticLight light;
  light.near = true;
  light.position_mm = {20.0, 35.0, 150.0};
  std::vector<Eigen::Vector3d> origins, directions;
  for (double x_mm : {-16.0, 16.0}) {
    SyntheticSphere sphere;
    sphere.centre_mm = {x_mm, 0.0, 0.0};
    sphere.radius_mm = 12.0;
    const SphereFitSummary fit = FitSphereSilhouette(testing::RenderSilhouette(camera, sphere, options));
    // Frame of the image: pixel (0, 0) at the origin; shift the truth accordingly.
    const SphereGeometry geometry = LocateSphere(CameraModel{}, fit.circle);
    const LightDirectionEstimate e =
        EstimateLightDirection(testing::RenderMirrorSphere(camera, sphere, {light}, options), geometry);
    ASSERT_TRUE(e.usable) << e.note;
    origins.push_back(ReflectionPointMm(geometry, e, camera.pixel_pitch_mm, 0.0));
    directions.push_back(e.direction);
  }
  const NearLightEstimate near = TriangulateNearLight(origins, directions);
  ASSERT_TRUE(near.usable) << near.message;
  const Eigen::Vector3d offset((options.width - 1) / 2.0 * camera.pixel_pitch_mm,
                               -(options.height - 1) / 2.0 * camera.pixel_pitch_mm, 0.0);
  EXPECT_LT((near.position_mm - (light.position_mm + offset)).norm(), 3.0);
}

}  // namespace
}  // namespace photorig::solvers::lighting

namespace photorig::solvers::lighting {
namespace {

// Mirror-sphere frames of the dome, the true directions, and nominal ones
// tilted by about `nominal_error_deg` as a dome's drawing is off its build.
struct HighlightScene {
  SphereScene scene;
  std::vector<cv::Mat> frames;
  std::vector<Eigen::Vector3d> truth, nominal;
  Circle true_circle;
};

HighlightScene RenderDomeFrames(double nominal_error_deg) {
  HighlightScene h;
  h.scene = Orthographic(110.0);
  const Eigen::Vector2d centre = testing::OrthographicPixel(h.scene.camera, h.scene.options, h.scene.sphere.centre_mm.x(),
                                                            h.scene.sphere.centre_mm.y());
  h.true_circle = {centre.x(), centre.y(), 110.0};
  std::mt19937 rng(11);
  std::normal_distribution<double> tilt(0.0, nominal_error_deg * M_PI / 180.0 / std::sqrt(2.0));
  for (const Eigen::Vector3d& direction : testing::DomeDirections()) {
    SyntheticLight light;
    light.direction = direction;
    SyntheticImageOptions options = h.scene.options;
    options.seed = static_cast<unsigned>(h.frames.size() + 3);
    h.frames.push_back(testing::RenderMirrorSphere(h.scene.camera, h.scene.sphere, {light}, options));
    h.truth.push_back(direction);
    const Eigen::Vector3d u = direction.unitOrthogonal(), v = direction.cross(u);
    h.nominal.push_back((direction + tilt(rng) * u + tilt(rng) * v).normalized());
  }
  return h;
}

// Rendered once for all the tests below (48 supersampled frames).
const HighlightScene& DomeFrames() {
  static const HighlightScene scene = RenderDomeFrames(1.5);
  return scene;
}

TEST(HighlightCircle, PlacesTheSphereFromItsHighlightsWellEnoughForHalfADegree) {
  const HighlightScene& h = DomeFrames();
  const HighlightCircleSummary fit = LocateSphereFromHighlights(h.frames, h.nominal);
  ASSERT_TRUE(fit.IsSolutionUsable()) << fit.message;
  EXPECT_NEAR(fit.circle.cx_px, h.true_circle.cx_px, 1.0);
  EXPECT_NEAR(fit.circle.cy_px, h.true_circle.cy_px, 1.0);
  EXPECT_NEAR(fit.circle.radius_px, h.true_circle.radius_px, 1.5);
  EXPECT_GT(fit.rms_residual_px, 0.5);  // the nominal directions' errors show in the residual
  const SphereGeometry sphere = LocateSphere(CameraModel{}, fit.circle);
  double nominal_sum = 0.0, calibrated_sum = 0.0;
  for (std::size_t k = 0; k < h.frames.size(); ++k) {
    const LightDirectionEstimate e = EstimateLightDirection(h.frames[k], sphere);
    ASSERT_TRUE(e.usable) << k << ": " << e.note;
    calibrated_sum += AngleDeg(e.direction, h.truth[k]);
    nominal_sum += AngleDeg(h.nominal[k], h.truth[k]);
  }
  EXPECT_GT(nominal_sum / h.frames.size(), 1.0);
  EXPECT_LT(calibrated_sum / h.frames.size(), 0.5);
}

TEST(HighlightCircle, AKnownRadiusLeavesOnlyTheCentre) {
  const HighlightScene& h = DomeFrames();
  HighlightCircleOptions options;
  options.fixed_radius_px = 110.0;
  const HighlightCircleSummary fit = LocateSphereFromHighlights(h.frames, h.nominal, options);
  ASSERT_TRUE(fit.IsSolutionUsable()) << fit.message;
  EXPECT_EQ(fit.circle.radius_px, 110.0);
  EXPECT_NEAR(fit.circle.cx_px, h.true_circle.cx_px, 1.0);
  EXPECT_NEAR(fit.circle.cy_px, h.true_circle.cy_px, 1.0);
}

TEST(HighlightCircle, WrongDirectionsAndMissingHighlightsAreReportedNotFitted) {
  const HighlightScene& h = DomeFrames();
  // Directions listed in the wrong order: no single sphere explains the highlights.
  std::vector<Eigen::Vector3d> shuffled(h.nominal.rbegin(), h.nominal.rend());
  const HighlightCircleSummary wrong = LocateSphereFromHighlights(h.frames, shuffled);
  EXPECT_FALSE(wrong.IsSolutionUsable());
  EXPECT_NE(wrong.message.find("do not fit"), std::string::npos) << wrong.message;
  // Dark frames have no highlight: they are listed, and too few left is an error.
  std::vector<cv::Mat> dark(h.frames.size());
  for (std::size_t k = 0; k < dark.size(); ++k)
    dark[k] = k < 2 ? h.frames[k] : cv::Mat(h.frames[k].size(), h.frames[k].type(), cv::Scalar(20));
  const HighlightCircleSummary missing = LocateSphereFromHighlights(dark, h.nominal);
  EXPECT_FALSE(missing.IsSolutionUsable());
  EXPECT_NE(missing.message.find("only 2 highlights"), std::string::npos) << missing.message;
  EXPECT_EQ(missing.rejected.size(), dark.size() - 2);
  EXPECT_FALSE(LocateSphereFromHighlights(h.frames, std::vector<Eigen::Vector3d>(3)).IsSolutionUsable());  // count mismatch
}

}  // namespace
}  // namespace photorig::solvers::lighting
