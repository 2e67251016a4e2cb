// Writes CHART_DIR/lighting_direction_error.csv: mirror-sphere light-direction
// error over a 48-LED dome vs sphere radius (noise 3 DN) and vs noise (radius
// 100 px), orthographic camera, with the mean predicted uncertainty; and
// lighting_envmap_roundtrip.csv: lat-long -> mirror ball -> lat-long error vs ball size.
#include "photorig/solvers/lighting/envmap.h"
#include "photorig/solvers/lighting/mirror_sphere.h"
#include "synthetic_sphere.h"

#include <cstdio>
#include <fstream>
#include <string>

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
  return 0;
}
