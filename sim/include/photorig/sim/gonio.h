#pragma once
// The simulated gonioreflectometer: three rotary axes (light arm, camera arm,
// sample rotation) and the frame the camera on its arm sees of a flat
// material sample (Scene::Shape::kSamplePlane, untilted) on the turntable.
//
// Geometry: both arms swing in the x-z plane; an arm at angle t points along
// (sin t, 0, cos t), 0 = on the sample normal. The turntable turns the sample
// by `sample_rotation_deg` about its normal (z). The camera is orthographic
// and looks along minus its arm direction, image x along the arm's tangent
// (cos t, 0, -sin t), image y along y; a pixel at image-plane (u, v) sees the
// sample point (u / cos t, v), foreshortened as a real detector would.
// Per pixel, with w_i, w_o expressed in the sample's (rotated) frame:
//   L = sum_k level_k * E_k * f_r(w_i, w_o) * max(0, cos theta_i)
// where every lamp k rides the light arm (its rig direction is ignored).

#include "photorig/drivers/motion.h"
#include "photorig/sim/brdf.h"
#include "photorig/sim/camera_model.h"
#include "photorig/sim/faults.h"
#include "photorig/sim/renderer.h"
#include "photorig/sim/scene.h"
#include "photorig/solvers/tomography/geometry.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <chrono>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace photorig::sim {

struct ArmAngles {
  double light_arm_deg = 0.0;
  double camera_arm_deg = 0.0;
  double sample_rotation_deg = 0.0;
  double sample_changer_deg = 0.0;  // tomography: 0 holds the sample in the beam (RenderPhantomTransmission)
};

// A reflectance standard in a sample changer slot: while the changer stands
// within 0.5 deg of `sample_changer_deg` the arms see a Lambertian sample
// plane of `albedo` (the scene's radius) instead of the sample.
struct ReferenceTarget {
  double albedo = 0.99;
  double sample_changer_deg = 90.0;
};

// Unit direction of an arm at `angle_deg` in the sample's frame after the
// turntable turned it by `rotation_deg` (the arm is fixed, the sample turns).
Eigen::Vector3d ArmDirectionInSample(double angle_deg, double rotation_deg);

// Radiance of the sample seen by the camera arm. Throws std::invalid_argument
// for a scene that is not an untilted sample_plane or a delta BRDF (a mirror's
// reflection is a single direction the finite lamp model does not cover).
cv::Mat RenderGonioRadiance(const Scene& scene, const Brdf& brdf, const CameraModel& camera,
                            const std::vector<Light>& lights, const std::vector<double>& levels,
                            const ArmAngles& arms);
void CheckGonioScene(const Scene& scene);  // the same checks, before any frame

// The same rig as a tomograph (Scene::Shape::kPhantom): the arms are parked on
// one horizontal beam line across the turntable, the camera at +90 deg and the
// lamps (a diffuse backlight) opposite at -90 deg; elsewhere the camera does
// not see the backlight and the frame is black. The camera is orthographic
// (a telecentric lens, a parallel beam) with its rows along the turntable's
// axis, so the frame is view `sample_rotation_deg` of a parallel-beam
// solvers::tomography::Geometry with the camera's size and pitch. A sample changer
// holds the phantom in the beam at sample_changer_deg = 0 and an empty slot
// anywhere else more than 0.5 deg away (the open beam of flat fields):
//   L = sum_k level_k * E_k * backlight_radiance * exp(-tau),
// tau the phantom's line integral averaged over 2 x 2 rays per pixel.
cv::Mat RenderPhantomTransmission(const Scene& scene, const CameraModel& camera, const std::vector<Light>& lights,
                                  const std::vector<double>& levels, const ArmAngles& arms);
// The turntable geometry those frames follow, for a scan at `angles_deg`.
solvers::tomography::Geometry PhantomScanGeometry(const CameraModel& camera, const std::vector<double>& angles_deg);

// A trapezoidal (or, when too short to reach the velocity, triangular)
// velocity profile from rest to rest over `distance_deg`.
class TrapezoidMove {
 public:
  TrapezoidMove(double distance_deg, const drivers::MotionProfile& profile);
  double duration_s() const { return duration_s_; }
  double DistanceAt(double t_s) const;  // covered after t_s, clamped to [0, distance]

 private:
  double distance_deg_, accel_, peak_velocity_, accel_time_s_, duration_s_;
};

struct SimAxisOptions {
  // Simulated seconds per wall-clock second: > 1 runs moves faster than life
  // (tests), 1 moves like the real arm.
  double time_scale = 1.0;
  double power_on_deg = 0.0;  // where the axis stands before homing, in drive degrees (home is 0)
  drivers::MotionProfile homing{20.0, 80.0};
  AxisFaults faults;

  bool IsValid(std::string* why) const;
};

// One rotary axis, integrated against the wall clock (scaled by time_scale).
// `on_position` receives the position whenever it is read, so the world the
// camera renders follows the arm.
class SimRotaryAxis : public drivers::Motion {
 public:
  SimRotaryAxis(std::string id, drivers::AxisLimits limits, drivers::SettleOptions settle, SimAxisOptions options,
                std::function<void(double)> on_position);
  ~SimRotaryAxis() override;

  double position_deg() const;  // without polling; for tests
  int stops() const { return stops_; }
  int homings() const { return homings_; }

 protected:
  Status DoOpen() override;
  Status DoStartHome() override;
  Status DoStartMove(double target_deg, const drivers::MotionProfile& profile) override;
  Result<drivers::AxisStatus> DoReadStatus() override;
  Status DoStop() override;
  Status DoClearFault() override;
  Status DoClose() override;

 private:
  using Clock = std::chrono::steady_clock;
  struct Trajectory {
    double from_deg, to_deg;
    TrapezoidMove move;
    Clock::time_point start;
    bool homing;
  };
  double Advance();  // integrates up to now, returns the position
  void Start(double to_deg, const drivers::MotionProfile& profile, bool homing);

  SimAxisOptions options_;
  std::function<void(double)> on_position_;
  mutable std::mutex mutex_;
  double position_deg_;
  bool homed_ = false;
  int stops_ = 0;
  int homings_ = 0;
  std::uint64_t moves_ = 0;
  std::optional<Trajectory> trajectory_;
};

}  // namespace photorig::sim
