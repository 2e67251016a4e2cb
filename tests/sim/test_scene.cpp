// Shapes, lights, visibility, projection and transmission of the simulated scene.
#include "photorig/sim/renderer.h"
#include "photorig/sim/scene.h"
#include "photorig/sim/world.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

namespace photorig::sim {
namespace {

using Eigen::Vector3d;

// Unique to this process: CTest runs tests of one file in parallel processes.
std::string TempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("photorig_test_" + std::to_string(::getpid()) + "_" + name)).string();
}

Vector3d NormalAt(const SurfaceMaps& maps, int r, int c) {
  const cv::Vec3f n = maps.normals.at<cv::Vec3f>(r, c);
  return {n[0], n[1], n[2]};
}

// The per-pixel march this renderer used before the horizon sweep: slow but
// plainly right, kept here as the oracle.
cv::Mat MarchedShadows(const SurfaceMaps& s, const Vector3d& w) {
  cv::Mat shadow = cv::Mat::zeros(s.height.size(), CV_8U);
  double top;
  cv::minMaxLoc(s.height, nullptr, &top, nullptr, nullptr, s.mask);
  const double horizontal = std::hypot(w.x(), w.y());
  const double step = 0.05, dc = step * w.x() / horizontal, dr = -step * w.y() / horizontal;
  const double rise = step * s.pixel_pitch_mm * w.z() / horizontal;
  for (int r = 0; r < s.height.rows; ++r)
    for (int c = 0; c < s.height.cols; ++c) {
      double cc = c, rr = r, ray = s.height.at<float>(r, c);
      while (ray < top) {
        cc += dc, rr += dr, ray += rise;
        const int r0 = int(std::floor(rr)), c0 = int(std::floor(cc));
        if (r0 < 0 || c0 < 0 || r0 + 1 >= s.height.rows || c0 + 1 >= s.height.cols) break;
        const double tr = rr - r0, tc = cc - c0;
        const double h = (1 - tr) * ((1 - tc) * s.height.at<float>(r0, c0) + tc * s.height.at<float>(r0, c0 + 1)) +
                         tr * ((1 - tc) * s.height.at<float>(r0 + 1, c0) + tc * s.height.at<float>(r0 + 1, c0 + 1));
        if (h > ray + 1e-6) {
          shadow.at<std::uint8_t>(r, c) = 1;
          break;
        }
      }
    }
  return shadow;
}

TEST(CastShadowMask, HorizonSweepAgreesWithAFineMarchAtEveryAzimuth) {
  Scene scene;
  scene.shape = Scene::Shape::kBumps;
  scene.bumps = Scene::DefaultBumps(40.0);
  const SurfaceMaps maps = SampleSurface(scene, 120, 100, 0.4);
  for (double azimuth_deg : {0.0, 17.0, 45.0, 100.0, 180.0, 233.0, 300.0}) {
    const double a = azimuth_deg * M_PI / 180;
    const Vector3d w = Vector3d(std::cos(a), std::sin(a), 0.35).normalized();
    const cv::Mat swept = CastShadowMask(maps, w), marched = MarchedShadows(maps, w);
    const int shadowed = cv::countNonZero(marched);
    EXPECT_GT(shadowed, 300) << azimuth_deg;
    // The sweep assigns each exact line sample to the nearest pixel (half a
    // pixel of shift at most): only pixels on the shadow's edge may differ.
    cv::Mat grown, shrunk;
    cv::dilate(marched, grown, cv::Mat());
    cv::erode(marched, shrunk, cv::Mat());
    const cv::Mat interior_disagreement = (swept != marched) & (grown == shrunk);
    EXPECT_EQ(cv::countNonZero(interior_disagreement), 0) << "azimuth " << azimuth_deg;
    EXPECT_LT(cv::countNonZero(swept != marched), 0.1 * shadowed) << "azimuth " << azimuth_deg;
  }
}

TEST(CastShadowMask, PlaneFacingTheLightCastsNoShadowAndAStepShadowsItsFoot) {
  Scene plane;
  plane.shape = Scene::Shape::kSamplePlane;
  plane.sphere_radius_mm = 100;
  plane.tilt_deg = 20;
  const SurfaceMaps flat = SampleSurface(plane, 64, 64, 0.5);
  EXPECT_EQ(cv::countNonZero(CastShadowMask(flat, Vector3d(1, 0.3, 0.2).normalized())), 0);

  Scene steps;
  steps.shape = Scene::Shape::kSteps;
  steps.step_width_mm = 10, steps.step_height_mm = 2, steps.step_slope = 0;
  const SurfaceMaps stairs = SampleSurface(steps, 80, 8, 0.5);
  // Light from -x at 45 degrees: each 2 mm drop (towards +x) shadows 2 mm = 4 pixels past it.
  const cv::Mat shadow = CastShadowMask(stairs, Vector3d(-1, 0, 1).normalized());
  // Edges at x = 0, +-10 mm, i.e. columns 40, 20, 60: shadowed columns 40..42 etc.; the
  // fourth column lies exactly on the shadow's edge as sampled (the last high sample is half a pixel before the riser).
  for (int c = 0; c < 80; ++c) {
    if (c == 23 || c == 43 || c == 63) continue;
    const bool expected = (c >= 20 && c < 23) || (c >= 40 && c < 43) || (c >= 60 && c < 63);
    EXPECT_EQ(shadow.at<std::uint8_t>(4, c), expected ? 1 : 0) << "column " << c;
  }
}

TEST(Shapes, HeightfieldNormalsMatchTheirClosedForms) {
  Scene bowl;
  bowl.shape = Scene::Shape::kConcave;
  bowl.bowl_radius_mm = 10, bowl.rim_radius_mm = 8;
  const SurfaceMaps b = SampleSurface(bowl, 50, 50, 0.4);
  // Pixel (r, c) = (25, 30): x = 2.2, y = -0.2 inside the rim; the normal points at the bowl's centre of curvature.
  const double x = 2.2, y = -0.2, s = std::sqrt(100 - x * x - y * y);
  EXPECT_NEAR((NormalAt(b, 25, 30) - Vector3d(-x, -y, s) / 10).norm(), 0, 1e-6);
  EXPECT_NEAR(b.height.at<float>(25, 30), std::sqrt(36.0) - s, 1e-5);
  EXPECT_NEAR((NormalAt(b, 0, 0) - Vector3d::UnitZ()).norm(), 0, 1e-6);  // flat outside the rim

  Scene steps;
  steps.shape = Scene::Shape::kSteps;
  steps.step_width_mm = 5, steps.step_height_mm = 1, steps.step_slope = 0.2;
  const SurfaceMaps st = SampleSurface(steps, 40, 4, 0.5);
  // Columns 19 | 20 straddle the edge at x = 0: a drop and a different normal on each side.
  // z = -k h + slope_k (u - k - 0.5) w with u = x / w: tread -1 (slope -0.2) at x = -0.25, tread 0 (+0.2) at 0.25.
  EXPECT_NEAR(st.height.at<float>(1, 19), 1.0 - 0.2 * (0.95 - 0.5) * 5, 1e-5);
  EXPECT_NEAR(st.height.at<float>(1, 20), 0.2 * (0.05 - 0.5) * 5, 1e-5);
  EXPECT_NEAR((NormalAt(st, 1, 19) - Vector3d(0.2, 0, 1).normalized()).norm(), 0, 1e-6);
  EXPECT_NEAR((NormalAt(st, 1, 20) - Vector3d(-0.2, 0, 1).normalized()).norm(), 0, 1e-6);

  Scene sample;
  sample.shape = Scene::Shape::kSamplePlane;
  sample.tilt_deg = 30;
  sample.sphere_radius_mm = 5;
  const SurfaceMaps sp = SampleSurface(sample, 40, 40, 0.5);
  EXPECT_NEAR((NormalAt(sp, 20, 20) - Vector3d(0.5, 0, std::sqrt(0.75))).norm(), 0, 1e-6);
  // The disc of radius 5 mm tilted by 30 degrees projects to an ellipse of area pi 5^2 cos 30.
  EXPECT_NEAR(cv::countNonZero(sp.mask) * 0.25, M_PI * 25 * std::cos(M_PI / 6), 2.0);
}

TEST(Shapes, DepthMapFromPngAndTiffReproducesTheSurface) {
  // A ramp z = 0.01 mm * (column + 100) stored as 16-bit PNG, 0 = no data.
  cv::Mat png(30, 40, CV_16U);
  for (int r = 0; r < 30; ++r)
    for (int c = 0; c < 40; ++c) png.at<std::uint16_t>(r, c) = static_cast<std::uint16_t>(r < 2 ? 0 : 100 + 20 * c);
  const std::string png_path = TempPath("depth.png");
  ASSERT_TRUE(cv::imwrite(png_path, png));
  Scene scene;
  scene.shape = Scene::Shape::kDepthMap;
  scene.depth_map_path = png_path;
  scene.depth_scale_mm = 0.01;
  const SurfaceMaps maps = SampleSurface(scene, 40, 30, 0.5);
  EXPECT_EQ(cv::countNonZero(maps.mask), 28 * 40);
  EXPECT_NEAR(maps.height.at<float>(10, 7), 0.01 * (100 + 140), 1e-5);
  // dz/dx = 0.2 mm / 0.5 mm.
  EXPECT_NEAR((NormalAt(maps, 10, 7) - Vector3d(-0.4, 0, 1).normalized()).norm(), 0, 1e-5);

  cv::Mat tiff;
  png.convertTo(tiff, CV_32F);
  tiff.setTo(std::numeric_limits<float>::quiet_NaN(), png == 0);
  const std::string tiff_path = TempPath("depth.tiff");
  ASSERT_TRUE(cv::imwrite(tiff_path, tiff));
  scene.depth_map_path = tiff_path;
  const SurfaceMaps from_tiff = SampleSurface(scene, 40, 30, 0.5);
  EXPECT_EQ(cv::norm(from_tiff.height, maps.height, cv::NORM_INF, maps.mask), 0.0);

  scene.depth_map_path = TempPath("missing.png");
  EXPECT_THROW(SampleSurface(scene, 8, 8, 1.0), std::runtime_error);
  std::filesystem::remove(png_path);
  std::filesystem::remove(tiff_path);
}

// A square pyramid of base 20 mm and height 5 mm: four faces of known normal.
TriangleMesh Pyramid() {
  TriangleMesh mesh;
  mesh.vertices = {{-10, -10, 0}, {10, -10, 0}, {10, 10, 0}, {-10, 10, 0}, {0, 0, 5}};
  mesh.faces = {{0, 1, 4}, {1, 2, 4}, {2, 3, 4}, {3, 0, 4}, {0, 2, 1}, {0, 3, 2}};
  return mesh;
}

TEST(Mesh, AsciiAndBinaryPlyRasteriseToThePyramidsNormalsAndDepth) {
  for (bool binary : {false, true}) {
    const std::string path = TempPath(binary ? "pyramid_bin.ply" : "pyramid_ascii.ply");
    SavePly(path, Pyramid(), binary);
    const TriangleMesh mesh = LoadPly(path);
    ASSERT_EQ(mesh.vertices.size(), 5u);
    ASSERT_EQ(mesh.faces.size(), 6u);
    Scene scene;
    scene.shape = Scene::Shape::kMesh;
    scene.mesh_path = path;
    const SurfaceMaps maps = SampleSurface(scene, 50, 50, 0.5);
    EXPECT_EQ(cv::countNonZero(maps.mask), 40 * 40);  // the base covers 40 x 40 pixel centres
    // Pixel (25, 35): x = 5.25, y = -0.25 on the +x face z = 5 (1 - x / 10), normal (5, 0, 10) normalised.
    EXPECT_NEAR(maps.height.at<float>(25, 35), 5 * (1 - 0.525), 1e-4);
    EXPECT_NEAR((NormalAt(maps, 25, 35) - Vector3d(1, 0, 2).normalized()).norm(), 0, 1e-5);
    EXPECT_NEAR((NormalAt(maps, 10, 25) - Vector3d(0, 1, 2).normalized()).norm(), 0, 1e-5);
    std::filesystem::remove(path);
  }
}

TEST(Mesh, MalformedPlyIsRejectedNamingTheFile) {
  const std::string path = TempPath("bad.ply");
  {
    std::ofstream out(path);
    out << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
           "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n";
  }
  try {
    LoadPly(path);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("vertex 7"), std::string::npos);
  }
  std::filesystem::remove(path);
}

TEST(PointLight, InverseSquareAndCosinePowerFalloff) {
  Light led;
  led.position_mm = Vector3d(0, 0, 100);
  led.axis = Vector3d(0, 0, -1);
  led.cos_exponent = 3;
  led.irradiance = 2.0;  // at the origin
  Vector3d wi;
  EXPECT_NEAR(led.IrradianceAt(Vector3d::Zero(), &wi), 2.0, 1e-12);
  EXPECT_NEAR((wi - Vector3d::UnitZ()).norm(), 0, 1e-12);
  // 50 mm off axis at z = 0: d^2 = 12500, cos = 100 / sqrt(12500).
  const double d2 = 12500, cosine = 100 / std::sqrt(d2);
  EXPECT_NEAR(led.IrradianceAt(Vector3d(50, 0, 0), &wi), 2.0 * 1e4 * std::pow(cosine, 3) / d2, 1e-12);
  EXPECT_NEAR((wi - Vector3d(-50, 0, 100).normalized()).norm(), 0, 1e-12);
  EXPECT_EQ(led.IrradianceAt(Vector3d(0, 0, 200), &wi), 0.0);  // behind the LED

  // Rendering a flat Lambertian plane: L = rho / pi * E(p) * (n . w_i).
  Scene plane;
  plane.shape = Scene::Shape::kSamplePlane;
  plane.sphere_radius_mm = 1000;
  plane.albedo.pattern = AlbedoTexture::Pattern::kUniform;
  plane.albedo.high = 0.5;
  const SurfaceMaps maps = SampleSurface(plane, 21, 21, 5.0);
  const cv::Mat radiance = RenderRadiance(maps, false, {led}, {1.0});
  const double x = 5.0 * (20 + 0.5 - 10.5), y = 5.0 * (10.5 - 10 - 0.5);  // pixel (10, 20)
  const Vector3d p(x, y, 0);
  const double e = led.IrradianceAt(p, &wi);
  EXPECT_NEAR(radiance.at<float>(10, 20), 0.5 / M_PI * e * wi.z(), 1e-6);
  EXPECT_LT(radiance.at<float>(10, 20), radiance.at<float>(10, 10));
}

TEST(Mirror, ChromeSphereShowsTheLightAsADiscAtTheMirrorPoint) {
  Scene scene;
  scene.shape = Scene::Shape::kMirrorSphere;
  scene.ApplyShapeDefaults(40.0);
  scene.sphere_radius_mm = 10;
  const SurfaceMaps maps = SampleSurface(scene, 200, 200, 0.1);
  Light light;
  light.direction = Vector3d(0.3, 0.2, 1).normalized();
  light.angular_radius_rad = 0.05;
  light.irradiance = 1.0;
  const cv::Mat radiance = RenderRadiance(maps, *scene.material.MakeBrdf(0.0), false, {light}, {1.0});
  // The highlight is centred where the normal bisects w_o = z and the light.
  const Vector3d h = (light.direction + Vector3d::UnitZ()).normalized();
  const int c = int(std::floor(h.x() * 10 / 0.1 + 100)), r = int(std::floor(100 - h.y() * 10 / 0.1));
  const double expected = 0.9 / (M_PI * std::pow(std::sin(0.05), 2));
  EXPECT_NEAR(radiance.at<float>(r, c), expected, 1e-3 * expected);
  // Its area: the normal may deviate by alpha / 2, a disc of radius R alpha / 2 (foreshortened).
  const double pixels = cv::countNonZero(radiance > 0);
  EXPECT_NEAR(pixels * 0.01, M_PI * 0.25 * 0.25 * h.z(), 0.03);
}

TEST(Mirror, SeveralBallsOnThePlaneEachPixelSeesItsOwn) {
  Scene scene;
  scene.shape = Scene::Shape::kMirrorSphere;
  scene.ApplyShapeDefaults(40.0);
  scene.sphere_radius_mm = 4;
  scene.sphere_centres_mm = {{-5.0, 0.0}, {5.0, 1.0}};
  std::string why;
  ASSERT_TRUE(scene.IsValid(&why)) << why;
  for (const bool pinhole : {false, true}) {
    CameraModel camera(200, 100, 0.1);
    if (pinhole) {
      camera.projection = CameraModel::Projection::kPinhole;
      camera.fx = camera.fy = 1000;
      camera.distance_mm = 100;
    }
    const SurfaceMaps maps = SampleSurface(scene, camera);
    int on = 0;
    for (int r = 0; r < maps.mask.rows; ++r)
      for (int c = 0; c < maps.mask.cols; ++c) {
        if (!maps.mask.at<std::uint8_t>(r, c)) continue;
        ++on;
        const cv::Vec3f p = maps.position.at<cv::Vec3f>(r, c);
        const Vector3d centre(p[0] < 0 ? -5.0 : 5.0, p[0] < 0 ? 0.0 : 1.0, 0.0);
        const Vector3d offset = Vector3d(p[0], p[1], p[2]) - centre;
        EXPECT_NEAR(offset.norm(), 4.0, 1e-4);
        EXPECT_NEAR((NormalAt(maps, r, c) - offset / 4.0).norm(), 0.0, 1e-5);
      }
    // Two discs of 40 px radius (a little more through the pinhole, whose balls are nearer than the plane).
    EXPECT_NEAR(on, 2 * M_PI * 40 * 40, 0.06 * 2 * M_PI * 40 * 40) << (pinhole ? "pinhole" : "orthographic");
  }
  scene.sphere_centres_mm = {{-3.0, 0.0}, {3.0, 0.0}};
  EXPECT_FALSE(scene.IsValid(&why));
  EXPECT_NE(why.find("overlap"), std::string::npos) << why;
}

// A near LED's highlight on a ball is a pixel or two across; integrated over
// each pixel, its first moment lands where the LED's centre reflects.
TEST(Mirror, ANearLedsHighlightIsIntegratedOverThePixel) {
  Scene scene;
  scene.shape = Scene::Shape::kMirrorSphere;
  scene.ApplyShapeDefaults(40.0);
  scene.sphere_radius_mm = 17;
  const double pitch = 0.35;
  const SurfaceMaps maps = SampleSurface(scene, 120, 120, pitch);
  Light light;
  light.position_mm = Vector3d(150.0, 60.0, 180.0);
  light.axis = -light.position_mm->normalized();
  light.emitter_radius_mm = 10;
  const cv::Mat radiance = RenderRadiance(maps, *scene.material.MakeBrdf(0.0), false, {light}, {1.0});
  // Where the view (0, 0, 1) reflects into the LED: n bisects them at p = R n.
  Vector3d n = Vector3d::UnitZ();
  for (int i = 0; i < 50; ++i) n = (Vector3d::UnitZ() + (*light.position_mm - 17.0 * n).normalized()).normalized();
  const double u = 17.0 * n.x() / pitch + 59.5, v = 59.5 - 17.0 * n.y() / pitch;
  const cv::Moments m = cv::moments(radiance);
  EXPECT_NEAR(m.m10 / m.m00, u, 0.05);
  EXPECT_NEAR(m.m01 / m.m00, v, 0.05);
  // Partly covered pixels carry the edge: not every lit pixel is at the full radiance.
  double peak = 0.0;
  cv::minMaxLoc(radiance, nullptr, &peak);
  EXPECT_GT(cv::countNonZero(radiance > 0), cv::countNonZero(radiance >= 0.999 * peak));
}

TEST(Pinhole, SphereSeenThroughAPinholeHasPerPixelViewDirections) {
  Scene scene;
  scene.sphere_radius_mm = 10;
  CameraModel camera;
  camera.projection = CameraModel::Projection::kPinhole;
  camera.width = camera.height = 64;
  camera.fx = camera.fy = 200;
  camera.distance_mm = 100;
  const SurfaceMaps maps = SampleSurface(scene, camera);
  // The silhouette of a sphere at distance D: tangent cone half-angle asin(R / D).
  const double radius_px = 200 * std::tan(std::asin(0.1));
  EXPECT_NEAR(cv::countNonZero(maps.mask), M_PI * radius_px * radius_px, 0.05 * M_PI * radius_px * radius_px);
  for (int r = 0; r < 64; r += 7)
    for (int c = 0; c < 64; c += 7) {
      if (!maps.mask.at<std::uint8_t>(r, c)) continue;
      const cv::Vec3f p = maps.position.at<cv::Vec3f>(r, c), v = maps.view.at<cv::Vec3f>(r, c);
      EXPECT_NEAR(cv::norm(p), 10.0, 1e-4);
      // The view direction points at the camera centre and the point projects to its pixel.
      const Vector3d to_camera = (Vector3d(0, 0, 100) - Vector3d(p[0], p[1], p[2])).normalized();
      EXPECT_NEAR((Vector3d(v[0], v[1], v[2]) - to_camera).norm(), 0, 1e-5);
      EXPECT_NEAR(200 * p[0] / (100 - p[2]) + 32, c + 0.5, 1e-3);
      EXPECT_NEAR(maps.depth.at<float>(r, c), 100 - p[2], 1e-4);
    }
  // A heightfield under a pinhole camera: the fixed point lands on the surface.
  Scene bumps;
  bumps.shape = Scene::Shape::kBumps;
  bumps.bumps = Scene::DefaultBumps(30);
  const SurfaceMaps hf = SampleSurface(bumps, camera);
  EXPECT_EQ(cv::countNonZero(hf.mask), 64 * 64);
  EXPECT_FALSE(hf.height_on_pixel_grid);
}

TEST(Volume, LineIntegralsMatchTheGaussianBlobsClosedForm) {
  // One Gaussian blob sigma0 exp(-r^2 / 2 s^2): tau(x, y) = sigma0 sqrt(2 pi) s exp(-(x^2 + y^2) / 2 s^2).
  DensityGrid grid;
  grid.nx = grid.ny = grid.nz = 48;
  grid.voxel_mm = 0.5;
  grid.sigma_per_mm.resize(48 * 48 * 48);
  const double s = 2.5, sigma0 = 0.3;
  for (int k = 0; k < 48; ++k)
    for (int j = 0; j < 48; ++j)
      for (int i = 0; i < 48; ++i) {
        const double x = (i - 23.5) * 0.5, y = (j - 23.5) * 0.5, z = (k - 23.5) * 0.5;
        grid.sigma_per_mm[(k * 48 + j) * 48 + i] = float(sigma0 * std::exp(-(x * x + y * y + z * z) / (2 * s * s)));
      }
  CameraModel camera;
  camera.width = camera.height = 24;
  camera.pixel_pitch_mm = 1.0;
  const cv::Mat tau = LineIntegrals(grid, camera);
  for (int r = 0; r < 24; r += 3)
    for (int c = 0; c < 24; c += 3) {
      const double x = c + 0.5 - 12, y = 12 - r - 0.5;
      const double expected = sigma0 * std::sqrt(2 * M_PI) * s * std::exp(-(x * x + y * y) / (2 * s * s));
      EXPECT_NEAR(tau.at<float>(r, c), expected, 0.02 * sigma0 * s + 0.01 * expected);
    }
  const cv::Mat radiance = RenderTransmission(tau, 3.0);
  EXPECT_NEAR(radiance.at<float>(12, 12), 3.0 * std::exp(-tau.at<float>(12, 12)), 1e-6);
  EXPECT_NEAR(radiance.at<float>(0, 0), 3.0, 1e-3);  // far from the blob: the bare backlight
}

TEST(World, SameSeedSameFramesWhateverTheScene) {
  WorldConfig config;
  config.scene.shape = Scene::Shape::kBumps;
  config.scene.bumps = Scene::DefaultBumps(6.4);
  config.scene.material.model = Brdf::Model::kGgx;
  config.camera = {64, 64, 0.1};
  config.lights = {{Vector3d(1, 0, 0.5).normalized(), 1.0}};
  World a(config), b(config);
  a.SetLevels({1.0});
  b.SetLevels({1.0});
  const cv::Mat ra = a.RenderRadiance(), rb = b.RenderRadiance();
  EXPECT_EQ(cv::norm(ra, rb, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::countNonZero(ra == 0), 0);  // cast shadows are on

  config.scene.shape = Scene::Shape::kMirrorSphere;  // with the Lambertian material: contradictory
  EXPECT_THROW(World{config}, std::invalid_argument);
}

}  // namespace
}  // namespace photorig::sim
