// Writes CHART_DIR/lighting_direction_error.csv: mirror-sphere light-direction
// error over a 48-LED dome vs sphere radius (noise 3 DN) and vs noise (radius
// 100 px), orthographic camera, with the mean predicted uncertainty; and
// lighting_envmap_roundtrip.csv: lat-long -> mirror ball -> lat-long error vs ball size;
// lighting_led_positions.csv: near LEDs placed from three chrome balls (12 LEDs
// of a 250 mm dome), error against the truth and time vs ball size and noise,
// orthographic and through a pinhole; lighting_sh_fit.csv: spherical-harmonic
// lighting fitted to a sphere's cap of normals (90 to 15 deg from the view) with
// each band selection, its error on the normals seen and on the whole visible
// hemisphere, and its time; lighting_intensity.csv: relative intensities from a
// white sphere under the 48-LED dome, the error against the truth, the model
// error, the lights refused and the time, vs a sheen on the sphere and vs the
// level of a dim 8-bit frame; lighting_led_weights.csv: a mixture of three of
// the 48 dome LEDs recovered as LED drive weights (FitLedWeights) from a
// sphere lit by it, vs the image noise and vs the pixel stride, with the
// simplest LED set and with every LED the least squares drives: the weights'
// error, the relit image's, the LEDs the fit drives, and its time.
#include "photorig/solvers/lighting/envmap.h"
#include "photorig/solvers/lighting/light_intensity.h"
#include "photorig/solvers/lighting/inverse_lighting.h"
#include "photorig/solvers/lighting/relight.h"
#include "photorig/solvers/lighting/mirror_sphere.h"
#include "led_dome_scene.h"
#include "synthetic_sphere.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

namespace {

using namespace photorig::solvers::lighting;

void Sweep(std::ofstream& out, const std::string& name, double radius_px, double noise_dn) {
  testing::SyntheticCamera camera;
  testing::SyntheticSphere sphere;
  sphere.centre_mm = {0.37, -0.21, 0.0};
  sphere.radius_mm = radius_px * camera.pixel_pitch_mm;
  testing::SyntheticImageOptions options;
  options.width = options.height = static_cast<int>(2 * radius_px + 30);
  options.noise_sigma = noise_dn;
  const SphereGeometry geometry =
      LocateSphere(CameraModel{}, FitSphereSilhouette(testing::RenderSilhouette(camera, sphere, options)).circle);
  double sum = 0.0, worst = 0.0, predicted = 0.0;
  int used = 0, flagged = 0;
  unsigned seed = 1;
  for (const Eigen::Vector3d& direction : testing::DomeDirections()) {
    testing::SyntheticLight light;
    light.direction = direction;
    options.seed = seed++;
    const LightDirectionEstimate e =
        EstimateLightDirection(testing::RenderMirrorSphere(camera, sphere, {light}, options), geometry);
    if (!e.usable || e.flags != kLightOk) ++flagged;
    if (!e.usable) continue;
    const double error = testing::AngleDeg(e.direction, direction);
    sum += error;
    worst = std::max(worst, error);
    predicted += e.uncertainty_deg;
    ++used;
  }
  out << name << "," << radius_px << "," << noise_dn << "," << sum / std::max(used, 1) << "," << worst << ","
      << predicted / std::max(used, 1) << "," << flagged << "\n";
  std::printf("%s sweep: radius %.0f px noise %.0f DN: mean %.3f deg, max %.3f deg, flagged %d\n", name.c_str(), radius_px,
              noise_dn, sum / std::max(used, 1), worst, flagged);
}

// One point of the intensity sweeps: a 100 px white sphere of albedo 1 (plus
// `sheen`, a Blinn-Phong lobe of exponent 20) under each dome light with
// irradiance `level` x (1, 0.95, 0.9), noise `noise_dn`; 8-bit frames rounded
// to whole DN. The error is |E / E_true - 1|, the worst channel's, of the
// estimates the fit accepts and, for the chart's other points, of all.
void IntensitySweep(std::ofstream& out, const std::string& name, double sheen, double level, double noise_dn,
                    bool eight_bit) {
  testing::WhiteSphereScene scene = testing::MakeWhiteSphereScene(100.0, 230, noise_dn);
  scene.options.saturation = eight_bit ? 255.0 : 65535.0;
  const Eigen::Vector3d rgb = level * Eigen::Vector3d(1.0, 0.95, 0.9);
  double error_sum = 0.0, error_max = 0.0, model_error_sum = 0.0, residual_sum = 0.0, seconds = 0.0;
  int lights = 0, refused = 0;
  unsigned seed = 1;
  std::vector<Eigen::Vector3d> ratios;  // E / E_true per light, for the error relative to the set's mean
  for (const Eigen::Vector3d& direction : testing::DomeDirections()) {
    scene.options.seed = seed++;
    cv::Mat frame = scene.Render(direction, rgb, sheen, 20.0);
    if (eight_bit) frame.convertTo(frame, CV_8UC3);
    const auto start = std::chrono::steady_clock::now();
    const LightIntensityEstimate e = EstimateIntensityFromSphere(frame, scene.geometry, direction);
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ++lights;
    refused += e.usable ? 0 : 1;
    double error = 0.0;
    for (int c = 0; c < 3; ++c) error = std::max(error, std::abs(e.rgb(c) / rgb(c) - 1.0));
    error_sum += error;
    error_max = std::max(error_max, error);
    model_error_sum += e.model_error;
    residual_sum += e.relative_rms_residual;
    ratios.push_back(e.rgb.cwiseQuotient(rgb));
  }
  // As NormaliseIntensities leaves them: relative to the set's mean, which
  // takes out a bias every light shares.
  double mean_ratio = 0.0;
  for (const Eigen::Vector3d& ratio : ratios) mean_ratio += ratio.sum() / (3.0 * ratios.size());
  double relative_sum = 0.0;
  for (const Eigen::Vector3d& ratio : ratios) relative_sum += (ratio / mean_ratio - Eigen::Vector3d::Ones()).cwiseAbs().maxCoeff();
  out << name << "," << sheen << "," << level << "," << noise_dn << "," << (eight_bit ? 8 : 16) << ","
      << error_sum / lights << "," << error_max << "," << relative_sum / lights << "," << model_error_sum / lights << ","
      << residual_sum / lights << ","
      << refused << "," << lights << "," << 1e3 * seconds / lights << "\n";
  std::printf("intensity %s: sheen %.3f level %.0f noise %.1f DN %d-bit: error mean %.4f max %.4f, normalised %.4f, "
              "model error %.4f, residual %.4f, refused %d of %d, %.2f ms each\n",
              name.c_str(), sheen, level, noise_dn, eight_bit ? 8 : 16, error_sum / lights, error_max,
              relative_sum / lights, model_error_sum / lights, residual_sum / lights, refused, lights,
              1e3 * seconds / lights);
}

// One point of the LED-weight sweeps: a 256 px sphere (albedo 0.7) lit by
// LEDs 3, 20 and 44 of the dome at drives 0.7, 1.3 and 0.5, with Gaussian
// noise of `relative_noise` times the image's mean, fitted every
// `pixel_stride` pixels. The relit error is the RMS of the image the fitted
// weights make against the noise-free one, relative to its mean.
void LedWeightsSweep(std::ofstream& out, const std::string& name, double relative_noise, int pixel_stride,
                     bool simplest_led_set) {
  cv::Mat normals, mask;
  testing::SphereNormals(256, 0.95, &normals, &mask);
  const cv::Mat albedo(normals.size(), CV_32F, cv::Scalar(0.7));
  const std::vector<Eigen::Vector3d> dome = testing::DomeDirections();
  const std::vector<double> intensities(dome.size(), 1.0);
  Eigen::MatrixXd truth = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(dome.size()), 1);
  truth(3, 0) = 0.7;
  truth(20, 0) = 1.3;
  truth(44, 0) = 0.5;
  const auto relit = [&](const Eigen::MatrixXd& weights) {
    std::vector<double> drives(dome.size());
    for (std::size_t k = 0; k < dome.size(); ++k) drives[k] = weights(static_cast<Eigen::Index>(k), 0) * intensities[k];
    cv::Mat image;
    RenderDirectionalLights(normals, albedo, dome, drives, &image);
    return image;
  };
  const cv::Mat clean = relit(truth);
  const double mean = cv::mean(clean, mask)[0];
  cv::Mat noisy = clean.clone(), noise(clean.size(), CV_32F);
  cv::theRNG().state = 7;
  cv::randn(noise, 0.0, relative_noise * mean);
  noisy += noise;
  LedWeightsOptions options;
  options.pixel_stride = pixel_stride;
  options.simplest_led_set = simplest_led_set;
  const auto start = std::chrono::steady_clock::now();
  const LedWeightsSummary fit = FitLedWeights(normals, albedo, noisy, mask, dome, intensities, options);
  const double ms = 1e3 * std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  double weight_error = std::numeric_limits<double>::quiet_NaN(), relit_error = weight_error;
  if (fit.IsSolutionUsable()) {
    weight_error = (fit.weights - truth).cwiseAbs().maxCoeff();
    cv::Mat difference = relit(fit.weights) - clean;
    relit_error = std::sqrt(cv::mean(difference.mul(difference), mask)[0]) / mean;
  }
  out << name << "," << (simplest_led_set ? "simplest" : "all") << "," << relative_noise << "," << pixel_stride << ","
      << fit.IsSolutionUsable() << "," << weight_error
      << "," << relit_error << "," << fit.relative_rms_residual << "," << fit.active_leds << "," << ms << "\n";
  std::printf("led weights %s, %s: noise %.3f stride %d: weight error %.4f, relit error %.5f, residual %.4f, %d LEDs "
              "driven, %.1f ms\n",
              name.c_str(), simplest_led_set ? "simplest set" : "all LEDs", relative_noise, pixel_stride, weight_error,
              relit_error, fit.relative_rms_residual,
              fit.active_leds, ms);
}

void LedPositionSweep(std::ofstream& out, const std::string& name, double radius_mm, double noise_dn, bool pinhole) {
  const std::vector<Eigen::Vector3d> truth = testing::LedPositionsMm();
  const MirrorSphereLayout balls = testing::ThreeBalls(radius_mm);
  const LedPositionSummary summary =
      EstimateLedPositions(testing::RenderLedFrames(pinhole, balls, truth, noise_dn), testing::DomeCamera(pinhole), balls);
  const testing::PositionErrors e = testing::ErrorsAgainst(summary, truth);
  // NaN figures where no LED is placed (each flagged).
  double predicted = summary.usable > 0 ? 0.0 : std::numeric_limits<double>::quiet_NaN();
  for (const LedPositionEstimate& led : summary.leds)
    if (led.usable) predicted += led.predicted_sigma_mm / summary.usable;
  const double radius_px = radius_mm / testing::DomeCamera(false).pixel_pitch_mm;
  out << name << "," << (pinhole ? "pinhole" : "orthographic") << "," << radius_mm << "," << radius_px << ","
      << noise_dn << "," << e.mean_mm << "," << e.max_mm << "," << predicted << "," << summary.unusable << ","
      << e.beyond_two_sigma << ","
      << summary.total_ms / truth.size() << "\n";
  std::printf("LED positions, %s sweep, %s: balls %.0f mm (%.0f px), noise %.1f DN: mean %.3f mm, max %.3f mm "
              "(predicted sigma %.3f mm, %d beyond 2 sigma), %d unusable, %.2f ms per LED\n",
              name.c_str(), pinhole ? "pinhole" : "orthographic", radius_mm, radius_px, noise_dn, e.mean_mm, e.max_mm,
              predicted, e.beyond_two_sigma, summary.unusable, summary.total_ms / truth.size());
}

// Relative RMS of `fitted` against `truth` over the pixels of `mask`.
double RelativeRms(const cv::Mat& fitted, const cv::Mat& truth, const cv::Mat& mask) {
  double squares = 0.0, reference = 0.0;
  for (int r = 0; r < truth.rows; ++r)
    for (int c = 0; c < truth.cols; ++c) {
      if (!mask.at<std::uint8_t>(r, c)) continue;
      const double d = fitted.at<float>(r, c) - truth.at<float>(r, c);
      squares += d * d;
      reference += static_cast<double>(truth.at<float>(r, c)) * truth.at<float>(r, c);
    }
  return std::sqrt(squares / std::max(reference, 1e-300));
}

void ShFitSweep(std::ofstream& out) {
  cv::Mat normals, hemisphere;
  testing::SphereNormals(256, 1.0, &normals, &hemisphere);
  const cv::Mat albedo(normals.size(), CV_32F, cv::Scalar(0.7));
  Eigen::MatrixXd truth_sh = Eigen::MatrixXd::Zero(9, 1);
  truth_sh << 2.0, 0.4, 0.9, -0.3, 0.15, -0.1, 0.2, 0.12, -0.15;
  cv::Mat truth;
  RenderShLighting(normals, albedo, truth_sh, &truth);
  struct Selection {
    const char* name;
    ShFitOptions::Selection selection;
    int band;
  };
  const Selection selections[] = {{"held-out", ShFitOptions::Selection::kHeldOut, 0},
                                  {"bic", ShFitOptions::Selection::kBic, 0},
                                  {"band 1", ShFitOptions::Selection::kFixed, 1},
                                  {"band 2", ShFitOptions::Selection::kFixed, 2},
                                  {"band 4", ShFitOptions::Selection::kFixed, 4}};
  for (const double cap_deg : {90.0, 60.0, 40.0, 25.0, 15.0}) {
    // The normals within cap_deg of the view: a sphere seen whole down to a nearly flat patch.
    cv::Mat cap = hemisphere.clone();
    for (int r = 0; r < cap.rows; ++r)
      for (int c = 0; c < cap.cols; ++c)
        if (normals.at<cv::Vec3f>(r, c)[2] < std::cos(cap_deg * M_PI / 180.0) - 1e-9) cap.at<std::uint8_t>(r, c) = 0;
    cv::Mat image = truth.clone(), noise(truth.size(), CV_32F);
    cv::RNG rng(7);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, 0.01 * cv::mean(truth, cap)[0]);
    image += noise;
    for (const Selection& s : selections) {
      ShFitOptions options;
      options.selection = s.selection;
      options.fixed_band = s.band;
      const ShLightingSummary fit = FitShLighting(normals, albedo, image, cap, options);
      cv::Mat rendered;
      RenderShLighting(normals, albedo, fit.coefficients, &rendered);
      const double seen = RelativeRms(rendered, truth, cap), whole = RelativeRms(rendered, truth, hemisphere);
      out << cap_deg << "," << s.name << "," << fit.band << "," << (fit.IsSolutionUsable() ? 1 : 0) << ","
          << fit.condition_number << "," << fit.hemisphere_relative_sigma << "," << seen << "," << whole << ","
          << fit.total_ms << "\n";
      std::printf("SH lighting, normals within %.0f deg, %s: band %d, condition %.3g, error %.4f on the normals seen, "
                  "%.4f on the hemisphere (predicted sigma %.4f at the worst normal), %.1f ms\n",
                  cap_deg, s.name, fit.band, fit.condition_number, seen, whole, fit.hemisphere_relative_sigma,
                  fit.total_ms);
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s CHART_DIR\n", argv[0]);
    return 2;
  }
  const std::string dir = argv[1];
  std::ofstream out(dir + "/lighting_direction_error.csv");
  out << "sweep,radius_px,noise_dn,mean_error_deg,max_error_deg,mean_predicted_deg,flagged_lights\n";
  for (double radius : {15.0, 25.0, 40.0, 60.0, 100.0, 150.0, 220.0}) Sweep(out, "radius", radius, 3.0);
  for (double noise : {0.0, 3.0, 10.0, 30.0, 100.0, 200.0}) Sweep(out, "noise", 100.0, noise);

  std::ofstream envmap(dir + "/lighting_envmap_roundtrip.csv");
  envmap << "ball_px,blind_cone_deg,relative_error\n";
  cv::Mat env(128, 256, CV_32F);
  for (int v = 0; v < env.rows; ++v)
    for (int u = 0; u < env.cols; ++u) {
      const Eigen::Vector3d d = LatLongDirection(u, v, env.cols, env.rows);
      env.at<float>(v, u) = static_cast<float>(0.5 + 0.3 * d.y() + 2.0 * std::exp(4.0 * (d.x() * 0.6 + d.y() * 0.5 + d.z() * 0.62 - 1.0)));
    }
  for (int size : {128, 256, 512, 1024}) {
    for (double cone : {10.0, 30.0, 60.0}) {
      UnwrapOptions options;
      options.width = 256;
      options.blind_cone_deg = cone;
      cv::Mat ball;
      LatLongMap back;
      LatLongToMirrorBall(env, size, &ball);
      MirrorBallToLatLong(ball, LocateSphere(CameraModel{}, Circle{(size - 1) / 2.0, (size - 1) / 2.0, size / 2.0}),
                          options, &back);
      cv::Mat diff;
      cv::absdiff(back.radiance, env, diff);
      const double error = cv::sum(diff.setTo(0, back.valid == 0))[0] / cv::sum(env.clone().setTo(0, back.valid == 0))[0];
      envmap << size << "," << cone << "," << error << "\n";
      std::printf("envmap ball %d px, blind cone %.0f deg: relative error %.4f\n", size, cone, error);
    }
  }
  std::ofstream leds(dir + "/lighting_led_positions.csv");
  leds << "sweep,camera,radius_mm,radius_px,noise_dn,mean_error_mm,max_error_mm,mean_predicted_mm,unusable,beyond_two_sigma,ms_per_led\n";
  for (const bool pinhole : {false, true}) {
    for (double radius : {6.0, 10.0, 17.0, 25.0}) LedPositionSweep(leds, "radius", radius, 2.0, pinhole);
    for (double noise : {0.5, 8.0, 32.0, 128.0}) LedPositionSweep(leds, "noise", 17.0, noise, pinhole);
  }

  std::ofstream sh(dir + "/lighting_sh_fit.csv");
  sh << "cap_deg,selection,band,usable,condition_number,predicted_hemisphere_sigma,error_seen,error_hemisphere,time_ms\n";
  ShFitSweep(sh);

  std::ofstream intensity(dir + "/lighting_intensity.csv");
  intensity << "sweep,sheen,level,noise_dn,bits,mean_error,max_error,mean_normalised_error,mean_model_error,"
               "mean_relative_residual,refused,"
               "lights,ms_per_light\n";
  for (double sheen : {0.0, 0.005, 0.01, 0.02, 0.04, 0.08, 0.16}) IntensitySweep(intensity, "sheen", sheen, 3000.0, 2.0, false);
  for (double level : {25.0, 50.0, 100.0, 200.0, 400.0}) IntensitySweep(intensity, "dim8", 0.0, level, 1.5, true);

  std::ofstream weights(dir + "/lighting_led_weights.csv");
  weights << "sweep,led_set,relative_noise,pixel_stride,usable,max_weight_error,relit_relative_rms,"
             "relative_rms_residual,active_leds,time_ms\n";
  for (const bool simplest : {true, false}) {
    for (double noise : {0.0, 0.001, 0.003, 0.01, 0.03, 0.1}) LedWeightsSweep(weights, "noise", noise, 1, simplest);
    for (int stride : {1, 2, 4, 8, 16}) LedWeightsSweep(weights, "stride", 0.01, stride, simplest);
  }
  return 0;
}
