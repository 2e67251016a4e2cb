#include "photorig/solvers/lighting/sphere.h"
#include "synthetic_sphere.h"

#include <gtest/gtest.h>

namespace photorig::solvers::lighting {
namespace {

using testing::SyntheticCamera;
using testing::SyntheticImageOptions;
using testing::SyntheticSphere;

TEST(SphereFit, SubPixelCentreAndRadiusOfAnOffCentreSphere) {
  SyntheticCamera camera;
  SyntheticSphere sphere;
  sphere.centre_mm = {1.437, -2.219, 0.0};
  sphere.radius_mm = 12.04;
  SyntheticImageOptions options;
  cv::Mat image = testing::RenderSilhouette(camera, sphere, options);
  cv::Mat noise(image.size(), CV_32F);
  cv::randn(noise, 0.0, 20.0);
  image += noise;
  const SphereFitSummary fit = FitSphereSilhouette(image);
  ASSERT_TRUE(fit.IsSolutionUsable()) << fit.message;
  const Eigen::Vector2d truth = testing::OrthographicPixel(camera, options, 1.437, -2.219);
  EXPECT_NEAR(fit.circle.cx_px, truth.x(), 0.03);
  EXPECT_NEAR(fit.circle.cy_px, truth.y(), 0.03);
  EXPECT_NEAR(fit.circle.radius_px, 120.4, 0.03);
  EXPECT_GT(fit.ellipse_axis_ratio, 0.998);
  EXPECT_FALSE(fit.touches_border);
}

TEST(SphereFit, FlagsASilhouetteCutByTheBorderAndRejectsEmptyImages) {
  SyntheticCamera camera;
  SyntheticSphere sphere;
  sphere.centre_mm = {15.0, 0.0, 0.0};
  const SphereFitSummary cut = FitSphereSilhouette(testing::RenderSilhouette(camera, sphere, {}));
  EXPECT_TRUE(cut.touches_border);
  const SphereFitSummary empty = FitSphereSilhouette(cv::Mat::zeros(64, 64, CV_32F));
  EXPECT_FALSE(empty.IsSolutionUsable());
  EXPECT_FALSE(empty.message.empty());
}

TEST(SphereFit, PinholeSilhouetteIsAnEllipseAndTheConeRecoversTheCentre) {
  SyntheticCamera camera;
  camera.pinhole = true;
  camera.fx_px = camera.fy_px = 1400.0;
  camera.cx_px = 319.5;
  camera.cy_px = 239.5;
  SyntheticSphere sphere;
  sphere.centre_mm = {60.0, 30.0, -350.0};
  sphere.radius_mm = 25.0;
  SyntheticImageOptions options;
  options.width = 640;
  options.height = 480;
  const SphereFitSummary fit = FitSphereSilhouette(testing::RenderSilhouette(camera, sphere, options));
  ASSERT_TRUE(fit.IsSolutionUsable()) << fit.message;
  EXPECT_LT(fit.ellipse_axis_ratio, 0.995);
  CameraModel model;
  model.projection = CameraModel::Projection::kPinhole;
  model.fx_px = model.fy_px = 1400.0;
  model.cx_px = 319.5;
  model.cy_px = 239.5;
  const SphereGeometry located = LocateSphere(model, fit.circle, fit.edge_points);
  ASSERT_TRUE(located.valid) << located.message;
  const Eigen::Vector3d truth = sphere.centre_mm / sphere.radius_mm;
  EXPECT_LT((located.centre - truth).norm() / truth.norm(), 2e-3);
}

}  // namespace
}  // namespace photorig::solvers::lighting
