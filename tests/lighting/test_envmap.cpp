#include "photorig/solvers/lighting/envmap.h"
#include "photorig/solvers/lighting/inverse_lighting.h"
#include "photorig/solvers/lighting/relight.h"
#include "photorig/solvers/lighting/spherical_harmonics.h"
#include "solver_output.h"
#include "synthetic_sphere.h"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <filesystem>

namespace photorig::solvers::lighting {
namespace {

using testing::OutputOf;

// A smooth colour environment: a sky gradient plus a warm lobe.
cv::Mat SmoothEnvironment(int width) {
  cv::Mat map(width / 2, width, CV_32FC3);
  for (int v = 0; v < map.rows; ++v) {
    for (int u = 0; u < map.cols; ++u) {
      const Eigen::Vector3d d = LatLongDirection(u, v, map.cols, map.rows);
      const double lobe = std::exp(4.0 * (d.dot(Eigen::Vector3d(0.5, 0.6, 0.62).normalized()) - 1.0));
      map.at<cv::Vec3f>(v, u) = cv::Vec3f(static_cast<float>(0.5 + 0.3 * d.y()), static_cast<float>(0.4 + 0.2 * d.y() + 2.0 * lobe),
                                          static_cast<float>(0.3 + 3.0 * lobe));
    }
  }
  return map;
}

TEST(EnvMap, LatLongPixelInvertsLatLongDirection) {
  const Eigen::Vector2d p = LatLongPixel(LatLongDirection(37.0, 81.0, 256, 128), 256, 128);
  EXPECT_NEAR(p.x(), 37.0, 1e-9);
  EXPECT_NEAR(p.y(), 81.0, 1e-9);
  EXPECT_NEAR(LatLongPixel(Eigen::Vector3d::UnitZ(), 256, 128).x(), 127.5, 1e-9);  // the camera is mid-map
}

TEST(EnvMap, MirrorBallRoundTripIsAccurateAwayFromTheBlindCone) {
  const cv::Mat env = SmoothEnvironment(256);
  const cv::Mat ball = OutputOf<cv::Mat>([&](cv::Mat* out) { return LatLongToMirrorBall(env, 512, out); });
  Circle circle{255.5, 255.5, 256.0};
  UnwrapOptions options;
  options.width = 256;
  options.blind_cone_deg = 30.0;
  const LatLongMap back = OutputOf<LatLongMap>(
      [&](LatLongMap* out) { return MirrorBallToLatLong(ball, LocateSphere(CameraModel{}, circle), options, out); });
  double sum = 0.0, sum_ref = 0.0;
  int count = 0;
  for (int v = 0; v < env.rows; ++v) {
    for (int u = 0; u < env.cols; ++u) {
      if (!back.valid.at<std::uint8_t>(v, u)) continue;
      sum += cv::norm(back.radiance.at<cv::Vec3f>(v, u) - env.at<cv::Vec3f>(v, u), cv::NORM_L1);
      sum_ref += cv::norm(env.at<cv::Vec3f>(v, u), cv::NORM_L1);
      ++count;
    }
  }
  EXPECT_GT(count, env.total() * 0.9);
  EXPECT_LT(sum / sum_ref, 0.01);
  RecordProperty("relative_round_trip_error", std::to_string(sum / sum_ref));
}

TEST(EnvMap, ExposureBracketsMergeToRadianceAndFlagUnresolvedPixels) {
  cv::Mat radiance(8, 8, CV_32F);
  for (int i = 0; i < 64; ++i) radiance.at<float>(i / 8, i % 8) = static_cast<float>(0.01 * std::pow(1.25, i));
  std::vector<cv::Mat> frames;
  const std::vector<double> exposures = {100.0, 1000.0, 10000.0};
  for (double t : exposures) {
    cv::Mat frame;
    cv::Mat(radiance * t + 64.0).convertTo(frame, CV_16U);  // rounding is the only noise
    frame.setTo(4095, frame > 4095);
    frames.push_back(frame);
  }
  ExposureMergeOptions options;
  options.black_level = 64.0;
  options.saturation_level = 4095.0;
  HdrMerge merge;
  const solvers::core::Summary merged = MergeExposures(frames, exposures, options, &merge);
  ASSERT_EQ(merged.termination, solvers::core::Termination::kSuccess);
  EXPECT_NE(merged.message.find("saturated in every exposure"), std::string::npos) << merged.message;
  for (int i = 0; i < 64; ++i) {
    const float truth = radiance.at<float>(i / 8, i % 8);
    if (truth * 100.0 + 64 >= 4095) {
      EXPECT_EQ(merge.unresolved.at<std::uint8_t>(i / 8, i % 8), 255);
    } else if (truth * 10000.0 > 20.0) {  // above a few DN in the longest exposure
      EXPECT_NEAR(merge.radiance.at<float>(i / 8, i % 8) / truth, 1.0, 0.03) << i;
    }
  }
  EXPECT_GT(merge.unresolved_pixels, 0);

  // Radiance HDR (RGBE) keeps about 1% relative precision through a file.
  cv::Mat colour;
  cv::merge(std::vector<cv::Mat>{merge.radiance, merge.radiance, merge.radiance}, colour);
  const std::string path = (std::filesystem::temp_directory_path() / "photorig_lighting_merge.hdr").string();
  ASSERT_TRUE(cv::imwrite(path, colour));
  const cv::Mat read = cv::imread(path, cv::IMREAD_UNCHANGED);
  ASSERT_EQ(read.type(), CV_32FC3);
  cv::Mat ratio;
  cv::divide(read, colour, ratio);
  double low, high;
  cv::minMaxLoc(ratio.reshape(1), &low, &high);
  EXPECT_GT(low, 0.98);
  EXPECT_LT(high, 1.02);
  std::filesystem::remove(path);
}

TEST(EnvMap, RelightingWithAnEnvironmentBySphericalHarmonicsAndByTheDome) {
  const cv::Mat env = SmoothEnvironment(256);
  const Eigen::MatrixXd sh = OutputOf<Eigen::MatrixXd>([&](Eigen::MatrixXd* out) { return ProjectLatLongToSh(env, 2, out); });
  cv::Mat normals, mask;
  testing::SphereNormals(96, 0.95, &normals, &mask);
  const cv::Mat albedo(normals.size(), CV_32F, cv::Scalar(0.6));
  const cv::Mat reference = OutputOf<cv::Mat>([&](cv::Mat* out) { return RenderShLighting(normals, albedo, sh, out); });

  // The SH projection is the lighting inverse lighting would recover from that render.
  const ShLightingSummary fit = FitShLighting(normals, albedo, reference, mask);
  ASSERT_TRUE(fit.IsSolutionUsable());
  EXPECT_LT((fit.coefficients.topRows(9) - sh).cwiseAbs().maxCoeff() / sh.cwiseAbs().maxCoeff(), 0.02);

  // Image-based: one frame per dome LED, weighted by the map's light around each LED.
  const std::vector<Eigen::Vector3d> dome = testing::DomeDirections();
  const std::vector<double> intensities(dome.size(), 1.0);
  std::vector<cv::Mat> frames;
  for (const auto& d : dome) {
    frames.push_back(OutputOf<cv::Mat>([&](cv::Mat* out) { return RenderDirectionalLights(normals, albedo, {d}, {1.0}, out); }));
  }
  const Eigen::MatrixXd weights =
      OutputOf<Eigen::MatrixXd>([&](Eigen::MatrixXd* out) { return LatLongToLedWeights(env, dome, intensities, out); });
  const cv::Mat relit = OutputOf<cv::Mat>([&](cv::Mat* out) { return RelightFromFrames(frames, weights, out); });
  // The dome holds no light below the horizon and samples the rest coarsely: compare facing-up pixels.
  double diff = 0.0, ref = 0.0;
  for (int r = 0; r < normals.rows; ++r) {
    for (int c = 0; c < normals.cols; ++c) {
      if (!mask.at<std::uint8_t>(r, c) || normals.at<cv::Vec3f>(r, c)[2] < 0.8) continue;
      diff += cv::norm(relit.at<cv::Vec3f>(r, c) - reference.at<cv::Vec3f>(r, c), cv::NORM_L1);
      ref += cv::norm(reference.at<cv::Vec3f>(r, c), cv::NORM_L1);
    }
  }
  EXPECT_LT(diff / ref, 0.15);
  RecordProperty("dome_vs_sh_relative_error", std::to_string(diff / ref));
}

// A matte plane (albedo 0.5, facing the camera, 38 mm across) under a dome
// of LEDs 80 mm away, one frame per LED: relit by an environment, its exact
// radiance is albedo / pi times the map's light integrated over the upper
// hemisphere with the cosine.
struct NearPlane {
  static constexpr int kSize = 96;
  static constexpr double kPitchMm = 0.4, kDomeMm = 80.0, kAlbedo = 0.5;
  std::vector<camera::NearLight> leds;
  std::vector<double> scales;
  std::vector<Eigen::Vector3d> directions;  // from the dome's centre
  cv::Mat points;
  std::vector<cv::Mat> frames;

  explicit NearPlane(const std::vector<Eigen::Vector3d>& dome = testing::DomeDirections())
      : points(kSize, kSize, CV_32FC3) {
    for (const Eigen::Vector3d& d : dome) {
      leds.push_back({kDomeMm * d.normalized(), -d.normalized(), 1.0});
      scales.push_back(1000.0);
      directions.push_back(d.normalized());
    }
    for (int r = 0; r < kSize; ++r)
      for (int c = 0; c < kSize; ++c)
        points.at<cv::Vec3f>(r, c) = cv::Vec3f(float((c + 0.5 - 0.5 * kSize) * kPitchMm), float((0.5 * kSize - r - 0.5) * kPitchMm), 0.0f);
    for (std::size_t k = 0; k < leds.size(); ++k) {
      cv::Mat frame(kSize, kSize, CV_32F);
      for (int r = 0; r < kSize; ++r)
        for (int c = 0; c < kSize; ++c) {
          const cv::Vec3f& p = points.at<cv::Vec3f>(r, c);
          Eigen::Vector3d towards;
          const double irradiance = scales[k] * leds[k].RelativeIrradiance(Eigen::Vector3d(p[0], p[1], p[2]), &towards);
          frame.at<float>(r, c) = static_cast<float>(kAlbedo / M_PI * std::max(0.0, towards.z()) * irradiance);
        }
      frames.push_back(frame);
    }
  }

  // The plane's exact radiance under `map` (stored B, G, R like the map).
  static cv::Vec3f Reference(const cv::Mat& map) {
    cv::Vec3d sum(0.0, 0.0, 0.0);
    for (int v = 0; v < map.rows; ++v) {
      const double theta0 = M_PI * v / map.rows, theta1 = M_PI * (v + 1) / map.rows;
      const double d_omega = 2.0 * M_PI / map.cols * (std::cos(theta0) - std::cos(theta1));
      for (int u = 0; u < map.cols; ++u) {
        const double cosine = LatLongDirection(u, v, map.cols, map.rows).z();
        if (cosine > 0.0) sum += cv::Vec3d(map.at<cv::Vec3f>(v, u)) * (cosine * d_omega);
      }
    }
    return cv::Vec3f(sum * (kAlbedo / M_PI));
  }
};

// Worst relative error (over channels) of a relit image against the plane's reference.
double WorstRelativeError(const cv::Mat& relit, const cv::Vec3f& reference) {
  double worst = 0.0;
  for (int r = 0; r < relit.rows; ++r)
    for (int c = 0; c < relit.cols; ++c)
      for (int ch = 0; ch < 3; ++ch)
        worst = std::max(worst, std::abs(relit.at<cv::Vec3f>(r, c)[ch] / reference[ch] - 1.0));
  return worst;
}

// n directions spread evenly over the hemisphere above 3 deg of elevation (a Fibonacci spiral).
std::vector<Eigen::Vector3d> DenseDome(int n) {
  std::vector<Eigen::Vector3d> dome;
  const double golden = M_PI * (3.0 - std::sqrt(5.0)), lowest = std::sin(3.0 * M_PI / 180.0);
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (1.0 - lowest) * (i + 0.5) / n, radius = std::sqrt(1.0 - z * z);
    dome.emplace_back(radius * std::cos(golden * i), radius * std::sin(golden * i), z);
  }
  return dome;
}

TEST(EnvMap, NearLedFramesAreRelitWithEachPixelsOwnDirectionsAndFalloff) {
  // A dome dense enough (300 LEDs) that its cells sum the lit hemisphere to about a percent, so
  // what remains is the frames' own falloff and directions, which only per-pixel weights take out.
  const NearPlane plane(DenseDome(300));
  // Worst relative error of the relit plane with per-pixel weights, and with one direction and
  // intensity per LED as for a distant dome.
  auto errors = [&](const cv::Mat& env) {
    const cv::Vec3f reference = NearPlane::Reference(env);
    const cv::Mat near = OutputOf<cv::Mat>([&](cv::Mat* out) {
      return RelightNearFromEnvironment({}, env, plane.leds, plane.scales, plane.frames, plane.points, out);
    });
    const Eigen::MatrixXd weights = OutputOf<Eigen::MatrixXd>(
        [&](Eigen::MatrixXd* out) { return LatLongToLedWeights(env, plane.directions, plane.scales, out); });
    const cv::Mat distant = OutputOf<cv::Mat>([&](cv::Mat* out) { return RelightFromFrames(plane.frames, weights, out); });
    return std::pair(WorstRelativeError(near, reference), WorstRelativeError(distant, reference));
  };
  // Uniform light: a shell of Lambertian emitters aimed at its centre lights every point inside
  // alike (an integrating sphere), so here one weight per LED is right too.
  const auto [uniform_near, uniform_distant] = errors(cv::Mat(128, 256, CV_32FC3, cv::Scalar::all(1.0)));
  EXPECT_LT(uniform_near, 0.03);
  EXPECT_LT(uniform_distant, 0.03);
  // A sky with a warm lobe: 1.3 % per pixel, 38 % with one weight per LED.
  const auto [sky_near, sky_distant] = errors(SmoothEnvironment(256));
  EXPECT_LT(sky_near, 0.03);
  EXPECT_GT(sky_distant, 0.2);
}

TEST(EnvMap, NearRelightingWeightsAreBilinearBetweenGridPoints) {
  const NearPlane plane;
  const cv::Mat env = SmoothEnvironment(256);
  NearRelightOptions fine;
  fine.grid_px = 2;
  cv::Mat coarse, dense;
  ASSERT_TRUE(RelightNearFromEnvironment({}, env, plane.leds, plane.scales, plane.frames, plane.points, &coarse)
                  .IsSolutionUsable());
  ASSERT_TRUE(RelightNearFromEnvironment(fine, env, plane.leds, plane.scales, plane.frames, plane.points, &dense)
                  .IsSolutionUsable());
  cv::Mat ratio;
  cv::divide(coarse, dense, ratio);
  double low, high;
  cv::minMaxLoc(ratio.reshape(1), &low, &high);
  EXPECT_GT(low, 1.0 - 5e-3);
  EXPECT_LT(high, 1.0 + 5e-3);
}

TEST(EnvMap, NearRelightingRefusesWhatItCannotUse) {
  const cv::Mat env = SmoothEnvironment(64);
  const NearPlane plane;
  cv::Mat out;
  NearRelightOptions coarse;
  coarse.grid_px = 1;
  EXPECT_EQ(RelightNearFromEnvironment(coarse, env, plane.leds, plane.scales, plane.frames, plane.points, &out).termination,
            core::Termination::kInvalidOptions);
  const cv::Mat four_channels(32, 64, CV_32FC4, cv::Scalar::all(1.0));
  EXPECT_EQ(RelightNearFromEnvironment({}, four_channels, plane.leds, plane.scales, plane.frames, plane.points, &out)
                .termination,
            core::Termination::kInvalidInput);
  std::vector<cv::Mat> fewer(plane.frames.begin(), plane.frames.end() - 1);
  EXPECT_EQ(RelightNearFromEnvironment({}, env, plane.leds, plane.scales, fewer, plane.points, &out).termination,
            core::Termination::kInvalidInput);
  cv::Mat holes = plane.points.clone();
  holes.at<cv::Vec3f>(5, 5)[2] = std::nanf("");
  const core::Summary refused = RelightNearFromEnvironment({}, env, plane.leds, plane.scales, plane.frames, holes, &out);
  EXPECT_EQ(refused.termination, core::Termination::kInvalidInput);
  EXPECT_NE(refused.message.find("finite"), std::string::npos) << refused.message;
  EXPECT_TRUE(out.empty());
}

}  // namespace
}  // namespace photorig::solvers::lighting
