#include "photorig/sim/gonio.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace photorig::sim {
using solvers::core::Refuse;

namespace {

constexpr double kDegToRad = M_PI / 180.0;

}  // namespace

Eigen::Vector3d ArmDirectionInSample(double angle_deg, double rotation_deg) {
  const double t = angle_deg * kDegToRad, phi = -rotation_deg * kDegToRad;
  const Eigen::Vector3d arm(std::sin(t), 0.0, std::cos(t));
  return {std::cos(phi) * arm.x() - std::sin(phi) * arm.y(), std::sin(phi) * arm.x() + std::cos(phi) * arm.y(),
          arm.z()};
}

void CheckGonioScene(const Scene& scene) {
  if (scene.shape != Scene::Shape::kSamplePlane || scene.tilt_deg != 0.0)
    throw std::invalid_argument("a gonioreflectometer renders an untilted sample_plane scene, not '" +
                                std::string(Scene::ShapeName(scene.shape)) + "'");
  if (scene.material.model == Brdf::Model::kMirror)
    throw std::invalid_argument("a gonioreflectometer scene cannot use the mirror (delta) BRDF");
}

solvers::tomography::Geometry PhantomScanGeometry(const CameraModel& camera, const std::vector<double>& angles_deg) {
  solvers::tomography::Geometry geometry;
  geometry.beam = solvers::tomography::Beam::kParallel;
  geometry.detector_cols = camera.width;
  geometry.detector_rows = camera.height;
  geometry.pixel_mm = camera.pixel_pitch_mm;
  for (double deg : angles_deg) geometry.angles_rad.push_back(deg * kDegToRad);
  return geometry;
}

cv::Mat RenderPhantomTransmission(const Scene& scene, const CameraModel& camera, const std::vector<Light>& lights,
                                  const std::vector<double>& levels, const ArmAngles& arms) {
  if (scene.shape != Scene::Shape::kPhantom) throw std::invalid_argument("not a phantom scene");
  double level = 0.0;
  for (std::size_t k = 0; k < lights.size() && k < levels.size(); ++k) level += levels[k] * lights[k].irradiance;
  const bool on_beam_line = std::abs(arms.camera_arm_deg - 90.0) <= 0.5 && std::abs(arms.light_arm_deg + 90.0) <= 0.5;
  cv::Mat radiance(camera.height, camera.width, CV_32F, cv::Scalar(0));
  if (level <= 0.0 || !on_beam_line) return radiance;
  const double open_beam = level * scene.backlight_radiance;
  if (std::abs(arms.sample_changer_deg) > 0.5) {
    radiance.setTo(open_beam);
    return radiance;
  }
  const solvers::tomography::Geometry geometry = PhantomScanGeometry(camera, {arms.sample_rotation_deg});
  const std::vector<float> tau = ProjectPhantom(scene.phantom, geometry, 2);
  for (int row = 0; row < camera.height; ++row)
    for (int col = 0; col < camera.width; ++col)
      radiance.at<float>(row, col) =
          static_cast<float>(open_beam * std::exp(-tau[static_cast<std::size_t>(geometry.RayIndex(0, row, col))]));
  return radiance;
}

cv::Mat RenderGonioRadiance(const Scene& scene, const Brdf& brdf, const CameraModel& camera,
                            const std::vector<Light>& lights, const std::vector<double>& levels,
                            const ArmAngles& arms) {
  CheckGonioScene(scene);
  double irradiance = 0.0;  // every lamp rides the light arm
  for (std::size_t k = 0; k < lights.size() && k < levels.size(); ++k) irradiance += levels[k] * lights[k].irradiance;
  cv::Mat radiance(camera.height, camera.width, CV_32F, cv::Scalar(0));
  const double cos_camera = std::cos(arms.camera_arm_deg * kDegToRad);
  if (irradiance <= 0.0 || cos_camera <= 1e-6) return radiance;
  const Eigen::Vector3d wi = ArmDirectionInSample(arms.light_arm_deg, arms.sample_rotation_deg);
  const Eigen::Vector3d wo = ArmDirectionInSample(arms.camera_arm_deg, arms.sample_rotation_deg);
  const Eigen::Vector3d n(0.0, 0.0, 1.0);
  if (wi.z() <= 0.0) return radiance;
  const Material& m = scene.material;
  BrdfParams params;
  params.rho_s = static_cast<float>(m.rho_s);
  params.shininess = static_cast<float>(m.LobeShape());
  params.f0 = static_cast<float>(m.f0);
  const double phi = -arms.sample_rotation_deg * kDegToRad, c = std::cos(phi), s = std::sin(phi);
  const double radius2 = scene.sphere_radius_mm * scene.sphere_radius_mm;
  for (int row = 0; row < camera.height; ++row) {
    float* out = radiance.ptr<float>(row);
    for (int col = 0; col < camera.width; ++col) {
      Eigen::Vector3d origin, direction;
      camera.Ray(col, row, &origin, &direction);
      // Image-plane (u, v) -> the point on the sample plane, then into the turned sample's frame.
      const double x = origin.x() / cos_camera, y = origin.y();
      if (x * x + y * y > radius2) continue;
      const double sx = c * x - s * y, sy = s * x + c * y;
      params.rho_d = static_cast<float>(m.model == Brdf::Model::kTabulated ? scene.albedo.high : scene.albedo.At(sx, sy));
      out[col] = static_cast<float>(irradiance * brdf.Eval(n, wi, wo, params) * wi.z());
    }
  }
  return radiance;
}

TrapezoidMove::TrapezoidMove(double distance_deg, const drivers::MotionProfile& profile)
    : distance_deg_(std::abs(distance_deg)), accel_(profile.acceleration_deg_s2) {
  peak_velocity_ = std::min(profile.velocity_deg_s, std::sqrt(distance_deg_ * accel_));
  accel_time_s_ = peak_velocity_ / accel_;
  const double cruise_deg = distance_deg_ - peak_velocity_ * accel_time_s_;
  duration_s_ = distance_deg_ > 0.0 ? 2.0 * accel_time_s_ + cruise_deg / peak_velocity_ : 0.0;
}

double TrapezoidMove::DistanceAt(double t) const {
  if (t <= 0.0) return 0.0;
  if (t >= duration_s_) return distance_deg_;
  if (t < accel_time_s_) return 0.5 * accel_ * t * t;
  const double left = duration_s_ - t;
  if (left < accel_time_s_) return distance_deg_ - 0.5 * accel_ * left * left;
  return 0.5 * peak_velocity_ * accel_time_s_ + peak_velocity_ * (t - accel_time_s_);
}

bool SimAxisOptions::IsValid(std::string* why) const {
  if (!(time_scale > 0)) return Refuse(why, "time_scale must be > 0");
  if (!(homing.velocity_deg_s > 0 && homing.acceleration_deg_s2 > 0))
    return Refuse(why, "homing velocity and acceleration must be > 0");
  return true;
}

SimRotaryAxis::SimRotaryAxis(std::string id, drivers::AxisLimits limits, drivers::SettleOptions settle,
                             SimAxisOptions options, std::function<void(double)> on_position)
    : Motion(std::move(id), limits, settle),
      options_(options),
      on_position_(std::move(on_position)),
      position_deg_(options.power_on_deg) {
  std::string why;
  if (!options_.IsValid(&why)) throw std::invalid_argument("simulated axis " + this->id() + ": " + why);
  if (on_position_) on_position_(position_deg_);
}

SimRotaryAxis::~SimRotaryAxis() { (void)Close(); }

double SimRotaryAxis::position_deg() const {
  std::lock_guard lock(mutex_);
  return position_deg_;
}

double SimRotaryAxis::Advance() {
  if (trajectory_) {
    const double t = options_.time_scale * std::chrono::duration<double>(Clock::now() - trajectory_->start).count();
    const double sign = trajectory_->to_deg >= trajectory_->from_deg ? 1.0 : -1.0;
    position_deg_ = trajectory_->from_deg + sign * trajectory_->move.DistanceAt(t);
    if (t >= trajectory_->move.duration_s()) {
      position_deg_ = trajectory_->to_deg;
      if (trajectory_->homing) homed_ = true;
      trajectory_.reset();
    }
  }
  if (on_position_) on_position_(position_deg_);
  return position_deg_;
}

void SimRotaryAxis::Start(double to_deg, const drivers::MotionProfile& profile, bool homing) {
  std::lock_guard lock(mutex_);
  Advance();
  trajectory_ = Trajectory{position_deg_, to_deg, TrapezoidMove(to_deg - position_deg_, profile), Clock::now(), homing};
}

Status SimRotaryAxis::DoOpen() { return Status::Ok(); }

Status SimRotaryAxis::DoStartHome() {
  {
    std::lock_guard lock(mutex_);
    homed_ = false;
    ++homings_;
  }
  Start(0.0, options_.homing, true);
  return Status::Ok();
}

Status SimRotaryAxis::DoStartMove(double target_deg, const drivers::MotionProfile& profile) {
  if (options_.faults.refused_moves.count(++moves_))
    return {StatusCode::kUnavailable, "simulated drive " + id() + " did not acknowledge move " + std::to_string(moves_)};
  Start(target_deg, profile, false);
  return Status::Ok();
}

Result<drivers::AxisStatus> SimRotaryAxis::DoReadStatus() {
  std::lock_guard lock(mutex_);
  drivers::AxisStatus status;
  status.position_deg = Advance();
  status.busy = trajectory_.has_value();
  status.homed = homed_;
  return status;
}

Status SimRotaryAxis::DoStop() {
  std::lock_guard lock(mutex_);
  Advance();
  trajectory_.reset();  // the simulated drive stops dead where it is
  ++stops_;
  return Status::Ok();
}

Status SimRotaryAxis::DoClearFault() { return Status::Ok(); }
Status SimRotaryAxis::DoClose() { return Status::Ok(); }

}  // namespace photorig::sim
