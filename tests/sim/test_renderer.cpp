#include "photorig/sim/renderer.h"
#include "photorig/sim/scene.h"
#include "photorig/sim/world.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <optional>

namespace photorig::sim {
namespace {

Scene UniformSphere(double radius_mm, double albedo) {
  Scene scene;
  scene.shape = Scene::Shape::kSphere;
  scene.sphere_radius_mm = radius_mm;
  scene.albedo.pattern = AlbedoTexture::Pattern::kUniform;
  scene.albedo.high = albedo;
  return scene;
}

TEST(SampleSurface, SphereNormalsAreAnalyticAndUnitLength) {
  const SurfaceMaps maps = SampleSurface(UniformSphere(10.0, 0.5), 64, 64, 0.4);
  int on_sphere = 0;
  for (int r = 0; r < 64; ++r)
    for (int c = 0; c < 64; ++c) {
      if (!maps.mask.at<std::uint8_t>(r, c)) continue;
      ++on_sphere;
      const cv::Vec3f n = maps.normals.at<cv::Vec3f>(r, c);
      EXPECT_NEAR(cv::norm(n), 1.0, 1e-6);
      const double x = (c + 0.5 - 32) * 0.4, y = (32 - r - 0.5) * 0.4;
      EXPECT_NEAR(n[0], x / 10.0, 1e-6);
      EXPECT_NEAR(n[1], y / 10.0, 1e-6);  // y up: rows grow downwards
    }
  // Pixel-centre sampling of a disk of radius 25 px covers about pi r^2 pixels.
  EXPECT_NEAR(on_sphere, M_PI * 25 * 25, 60);
}

TEST(RenderRadiance, LambertianSphereMatchesTheClosedForm) {
  const SurfaceMaps maps = SampleSurface(UniformSphere(10.0, 0.6), 32, 32, 0.7);
  const Eigen::Vector3d w = Eigen::Vector3d(0.3, -0.2, 0.9).normalized();
  const cv::Mat radiance = RenderRadiance(maps, false, {{w, 2.5}}, {0.8});
  for (int r = 0; r < 32; ++r)
    for (int c = 0; c < 32; ++c) {
      if (!maps.mask.at<std::uint8_t>(r, c)) {
        EXPECT_EQ(radiance.at<float>(r, c), 0.0f);
        continue;
      }
      const cv::Vec3f n = maps.normals.at<cv::Vec3f>(r, c);
      const double cosine = std::max(0.0, n[0] * w.x() + n[1] * w.y() + n[2] * w.z());
      EXPECT_NEAR(radiance.at<float>(r, c), 0.6 / M_PI * 2.5 * 0.8 * cosine, 1e-6);
    }
}

TEST(RenderRadiance, LightsAddUp) {
  const SurfaceMaps maps = SampleSurface(UniformSphere(10.0, 0.6), 24, 24, 0.9);
  const std::vector<Light> lights = {{Eigen::Vector3d(0, 0, 1), 1.0},
                                                {Eigen::Vector3d(0.6, 0, 0.8), 2.0}};
  const cv::Mat both = RenderRadiance(maps, false, lights, {1.0, 0.5});
  const cv::Mat first = RenderRadiance(maps, false, lights, {1.0, 0.0});
  const cv::Mat second = RenderRadiance(maps, false, lights, {0.0, 0.5});
  EXPECT_LT(cv::norm(both, first + second, cv::NORM_INF), 1e-6);
}

TEST(CastShadowMask, BumpsShadowUnderGrazingLightOnly) {
  Scene scene;
  scene.shape = Scene::Shape::kBumps;
  scene.bumps = Scene::DefaultBumps(40.0);
  const SurfaceMaps maps = SampleSurface(scene, 100, 100, 0.4);
  EXPECT_EQ(cv::countNonZero(CastShadowMask(maps, Eigen::Vector3d(0, 0, 1))), 0);
  const int grazing = cv::countNonZero(CastShadowMask(maps, Eigen::Vector3d(1, 0, 0.25).normalized()));
  const int steep = cv::countNonZero(CastShadowMask(maps, Eigen::Vector3d(1, 0, 2.0).normalized()));
  EXPECT_GT(grazing, 200);
  EXPECT_LT(steep, grazing);
}

TEST(CastShadowMask, ShadowFallsOnTheFarSideOfABump) {
  Scene scene;
  scene.shape = Scene::Shape::kBumps;
  scene.bumps = {Bump{0.0, 0.0, 4.0, 2.0}};
  const SurfaceMaps maps = SampleSurface(scene, 81, 81, 0.25);
  // Light from +x, low: the shadow lies at -x of the bump centre (column 40), on its row.
  const cv::Mat shadow = CastShadowMask(maps, Eigen::Vector3d(1, 0, 0.3).normalized());
  int left = 0, right = 0;
  for (int c = 0; c < 81; ++c) (c < 40 ? left : right) += shadow.at<std::uint8_t>(40, c);
  EXPECT_GT(left, 5);
  EXPECT_EQ(right, 0);
}

}  // namespace
}  // namespace photorig::sim

namespace photorig::sim {
namespace {

// Inside a sphere every surface point sees any region of the sphere with the
// same cosine-weighted view factor, area / (4 pi R^2). A bowl cut from a
// sphere of radius R with depth d therefore sees its own wall with factor
// d / (2 R) from every point: under a uniform radiance L on the surface, one
// bounce brings rho L d / (2 R) everywhere inside, and nothing to the flat
// surround, which no ray leaves the plane to meet.
TEST(OneBounce, InsideABowlEveryPointSeesTheSameShareOfWall) {
  Scene scene;
  scene.shape = Scene::Shape::kConcave;
  scene.bowl_radius_mm = 15.0;
  scene.rim_radius_mm = 12.0;
  scene.albedo.pattern = AlbedoTexture::Pattern::kUniform;
  scene.albedo.high = 0.5;
  const double pitch_mm = 0.25;
  const int size = 112;
  const SurfaceMaps maps = SampleSurface(scene, size, size, pitch_mm);
  const cv::Mat uniform(maps.mask.size(), CV_32F, cv::Scalar(1.0));
  const cv::Mat bounce = RenderOneBounce(maps, *MakeBrdf(Brdf::Model::kLambertian), uniform, 144, 7);
  const double depth_mm = 15.0 - std::sqrt(15.0 * 15.0 - 12.0 * 12.0);
  const double expected = 0.5 * depth_mm / (2.0 * 15.0);
  double inside_sum = 0.0, worst_outside = 0.0;
  int inside = 0;
  for (int r = 0; r < size; ++r)
    for (int c = 0; c < size; ++c) {
      const double radius_mm = std::hypot((c + 0.5 - 0.5 * size) * pitch_mm, (0.5 * size - r - 0.5) * pitch_mm);
      const double value = bounce.at<float>(r, c);
      if (radius_mm < 0.8 * 12.0) {
        inside_sum += value;
        ++inside;
        EXPECT_NEAR(value, expected, 0.25 * expected) << r << "," << c;  // 144 samples per pixel
      } else if (radius_mm > 12.5) {
        worst_outside = std::max(worst_outside, std::abs(value));
      }
    }
  EXPECT_NEAR(inside_sum / inside, expected, 0.02 * expected);
  EXPECT_EQ(worst_outside, 0.0);
}

TEST(OneBounce, ConvexSurfacesReceiveNothingAndResultsAreDeterministic) {
  Scene plane;
  plane.shape = Scene::Shape::kSamplePlane;
  plane.sphere_radius_mm = 6.0;
  plane.tilt_deg = 25.0;
  const SurfaceMaps flat = SampleSurface(plane, 96, 96, 0.15);
  const cv::Mat uniform(flat.mask.size(), CV_32F, cv::Scalar(1.0));
  const auto lambertian = MakeBrdf(Brdf::Model::kLambertian);
  EXPECT_EQ(cv::countNonZero(RenderOneBounce(flat, *lambertian, uniform, 64, 1)), 0);

  Scene bowl;
  bowl.shape = Scene::Shape::kConcave;
  bowl.bowl_radius_mm = 8.0;
  bowl.rim_radius_mm = 6.0;
  const SurfaceMaps maps = SampleSurface(bowl, 96, 96, 0.15);
  const cv::Mat direct = RenderRadiance(maps, true, {{Eigen::Vector3d(0.5, 0.2, 0.84).normalized(), 1.0}}, {1.0});
  const cv::Mat a = RenderOneBounce(maps, *lambertian, direct, 16, 3), b = RenderOneBounce(maps, *lambertian, direct, 16, 3);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::countNonZero(a), 0);
  EXPECT_GT(cv::norm(a, RenderOneBounce(maps, *lambertian, direct, 16, 4), cv::NORM_INF), 0.0);  // the seed matters
  // The mirror's delta lobe is not sampled by a diffuse bounce: nothing is added.
  EXPECT_EQ(cv::countNonZero(RenderOneBounce(maps, *MakeBrdf(Brdf::Model::kMirror), direct, 16, 3)), 0);
}

// Under a sky of irradiance 1 above the horizontal plane, a Lambertian point
// with normal n sees the part of its hemisphere above that plane:
// rho / pi (1 + n_z) / 2.
TEST(SkyResponse, LambertianSphereMatchesTheClosedForm) {
  const SurfaceMaps maps = SampleSurface(UniformSphere(10.0, 0.6), 48, 48, 0.45);
  const cv::Mat response = RenderSkyResponse(maps, *MakeBrdf(Brdf::Model::kLambertian), 256, 5);
  double worst = 0.0, sum_error = 0.0;
  int count = 0;
  for (int r = 0; r < 48; ++r)
    for (int c = 0; c < 48; ++c) {
      if (!maps.mask.at<std::uint8_t>(r, c)) {
        EXPECT_EQ(response.at<float>(r, c), 0.0f);
        continue;
      }
      const double expected = 0.6 / M_PI * (1.0 + maps.normals.at<cv::Vec3f>(r, c)[2]) / 2.0;
      const double error = response.at<float>(r, c) / expected - 1.0;
      worst = std::max(worst, std::abs(error));
      sum_error += error;
      ++count;
    }
  // 16 x 16 strata: only the ~30 strata the horizon cuts are random, each
  // in or out, so a pixel's share of sky has an error of up to about 2 % (one
  // sigma) where the horizon crosses its hemisphere; the worst of ~900 pixels
  // stays within 8 %, the mean within 0.2 %.
  EXPECT_LT(worst, 0.08);
  EXPECT_NEAR(sum_error / count, 0.0, 0.002);
}

// A 24 x 24 view of an upward-facing plane of uniform albedo 0.5, no lights.
WorldConfig GreyPlane() {
  WorldConfig config;
  config.scene.shape = Scene::Shape::kSamplePlane;
  config.scene.sphere_radius_mm = 2.0;
  config.scene.albedo.pattern = AlbedoTexture::Pattern::kUniform;
  config.scene.albedo.high = 0.5;
  config.camera = {24, 24, 0.2};
  return config;
}

// An upward-facing plane sees the whole sky: the ambient light adds exactly
// the stated irradiance, dome_fraction * level * E per lit LED plus the stray
// light, reflected as rho / pi of it.
TEST(SkyResponse, AmbientLightAddsTheStatedIrradiance) {
  WorldConfig config = GreyPlane();
  config.lights = {{Eigen::Vector3d(0, 0, 1), 2.0}, {Eigen::Vector3d(0.6, 0, 0.8), 3.0}};
  const World direct_only(config);
  config.ambient.dome_fraction = 0.04;
  config.ambient.stray_irradiance = 0.25;
  World with_ambient(config);
  for (const std::vector<double>& levels : {std::vector<double>{0.0, 0.0}, {1.0, 0.0}, {0.5, 1.0}}) {
    World lit_directly(direct_only.config());
    lit_directly.SetLevels(levels);
    with_ambient.SetLevels(levels);
    const double sky = 0.25 + 0.04 * (2.0 * levels[0] + 3.0 * levels[1]);
    const cv::Mat added = with_ambient.RenderRadiance() - lit_directly.RenderRadiance();
    const cv::Mat& mask = with_ambient.surface().mask;
    ASSERT_GT(cv::countNonZero(mask), 100);
    for (int r = 0; r < mask.rows; ++r)
      for (int c = 0; c < mask.cols; ++c)
        EXPECT_NEAR(added.at<float>(r, c), mask.at<std::uint8_t>(r, c) ? 0.5 / M_PI * sky : 0.0, 1e-6);
  }
}

TEST(SkyResponse, AMirrorReflectsTheSkyOnlyWhereItsMirrorDirectionPointsUp) {
  const SurfaceMaps maps = SampleSurface(UniformSphere(10.0, 0.6), 48, 48, 0.45);
  cv::Mat params = maps.brdf_params.clone();
  for (auto it = params.begin<cv::Vec4f>(); it != params.end<cv::Vec4f>(); ++it) (*it)[1] = 0.9f;
  SurfaceMaps mirror = maps;
  mirror.brdf_params = params;
  const cv::Mat response = RenderSkyResponse(mirror, *MakeBrdf(Brdf::Model::kMirror), 1, 5);
  int lit = 0, dark = 0;
  for (int r = 0; r < 48; ++r)
    for (int c = 0; c < 48; ++c) {
      if (!maps.mask.at<std::uint8_t>(r, c)) continue;
      // The mirror direction of the view (0, 0, 1) has z = 2 n_z^2 - 1.
      const double nz = maps.normals.at<cv::Vec3f>(r, c)[2];
      const bool up = 2.0 * nz * nz - 1.0 > 0.0;
      EXPECT_NEAR(response.at<float>(r, c), up ? 0.9 / M_PI : 0.0, 1e-6);
      (up ? lit : dark) += 1;
    }
  EXPECT_GT(lit, 100);
  EXPECT_GT(dark, 100);
}

// On a colour dome a tabulated material is seen through each channel's
// response to the light, as a parametric one is: a grey Lambertian table
// renders as the Lambertian model of the same albedo.
TEST(ColourDome, ATabulatedMaterialIsScaledByEachChannelsResponseToTheLight) {
  WorldConfig config = GreyPlane();
  config.lights = {{Eigen::Vector3d(0.3, 0.2, 0.93).normalized(), 2.0}};
  config.color.mosaic = "RGGB";
  config.color.light_rgb = Eigen::Vector3d(0.8, 1.0, 0.6);
  config.color.low_rgb = config.color.high_rgb = 0.5 * config.color.light_rgb;  // a grey paint of albedo 0.5
  World parametric(config);
  config.scene.material.model = Brdf::Model::kTabulated;
  config.scene.material.table = std::make_shared<const solvers::brdf::MeasuredBrdf>(
      [](const Eigen::Vector3d&, const Eigen::Vector3d&) { return std::optional<Eigen::Vector3d>(Eigen::Vector3d::Constant(0.5 / M_PI)); });
  World tabulated(config);
  parametric.SetLevels({1.0});
  tabulated.SetLevels({1.0});
  const cv::Mat a = parametric.RenderRadiance(), b = tabulated.RenderRadiance();
  ASSERT_GT(cv::countNonZero(a > 0.0f), 100);
  EXPECT_LT(cv::norm(a, b, cv::NORM_INF), 1e-5 * cv::norm(a, cv::NORM_INF));
}

}  // namespace
}  // namespace photorig::sim
