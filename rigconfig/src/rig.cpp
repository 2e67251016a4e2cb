#include "photorig/config/rig.h"

#include "driver_options_parse.h"
#include "photorig/config/scene.h"
#include "photorig/config/yaml_node.h"
#include "photorig/solvers/camera/calibration.h"
#include "photorig/solvers/color/spectrum.h"

#include <algorithm>
#include <cmath>
#include <set>

namespace photorig::config {
namespace {

LedConfig ParseLed(const YamlNode& node, int index) {
  node.ExpectKeys({"id", "direction", "position_mm", "axis", "cos_exponent", "intensity", "channel", "rgb_intensity"});
  LedConfig led;
  led.id = node.Int("id", index);
  // LED i is driven on controller output i (Modbus coil/register offset i,
  // GPIO line i of `lines`, relay i): a `channel` elsewhere would be ignored,
  // lighting the wrong LED, so it is refused rather than silently dropped.
  if (node.Has("channel") && node.Int("channel", index) != index)
    node["channel"].Fail("is " + std::to_string(node.Int("channel", index)) + " but this LED is entry " +
                         std::to_string(index) + " of lights.leds: photorig drives entry i on output i, so list "
                         "the LEDs in output order (or give channel: i)");
  const bool has_direction = node.Has("direction"), has_position = node.Has("position_mm");
  if (has_direction == has_position) node.Fail("give exactly one of 'direction' or 'position_mm'");
  // A position makes the LED near: photometric stereo and the simulator take
  // its light vector and falloff per point (docs/lights-and-motion.md).
  const YamlNode vector_node = has_direction ? node["direction"] : node["position_mm"];
  const Eigen::Vector3d vector = vector_node.AsVector3();
  if (vector.norm() < 1e-9) vector_node.Fail("must not be the zero vector");
  led.direction = vector.normalized();
  if (led.direction.z() <= 0.0) vector_node.Fail("points below the sample plane (z <= 0)");
  if (has_position) led.position_mm = vector;
  if (!has_position && (node.Has("axis") || node.Has("cos_exponent")))
    node.Fail("'axis' and 'cos_exponent' describe a near LED: give its position_mm");
  if (auto axis = node.Find("axis")) {
    const Eigen::Vector3d a = axis->AsVector3();
    if (a.norm() < 1e-9) axis->Fail("must not be the zero vector");
    led.axis = a.normalized();
    // An LED that does not face the origin lights the sample with its profile's flank or not at all.
    if (led.axis->dot(-vector.normalized()) <= 0.0) axis->Fail("points away from the sample (the origin)");
  }
  led.cos_exponent = node.Double("cos_exponent", led.cos_exponent);
  if (!(led.cos_exponent >= 0.0 && led.cos_exponent <= 1000.0)) node["cos_exponent"].Fail("must lie in [0, 1000]");
  led.intensity = node.Double("intensity", 1.0);
  if (!(led.intensity > 0.0 && led.intensity <= kMaxLedIntensity))
    node["intensity"].Fail("must lie in (0, " + std::to_string(static_cast<int>(kMaxLedIntensity)) + "]");
  if (auto rgb = node.Find("rgb_intensity")) {
    led.rgb_intensity = rgb->AsVector3();
    if (!(led.rgb_intensity.minCoeff() >= 0.0 && led.rgb_intensity.maxCoeff() > 0.0 &&
          led.rgb_intensity.maxCoeff() <= kMaxLedIntensity))
      rgb->Fail("needs three values in [0, " + std::to_string(static_cast<int>(kMaxLedIntensity)) +
                "], not all zero");
  }
  return led;
}

TriggerConfig ParseTrigger(const YamlNode& node) {
  node.ExpectKeys({"mode", "line", "pulse_us", "output"});
  TriggerConfig trigger;
  const std::string mode = node.String("mode", "software");
  if (mode == "hardware") trigger.mode = drivers::TriggerMode::kHardware;
  else if (mode != "software") node["mode"].Fail("expected software or hardware");
  trigger.line = node.String("line", trigger.line);
  trigger.pulse_us = node.Int("pulse_us", trigger.pulse_us);
  if (trigger.pulse_us < 1 || trigger.pulse_us > 1000000) node["pulse_us"].Fail("must lie in [1, 1000000]");
  if (trigger.mode == drivers::TriggerMode::kHardware) {
    const YamlNode output = node["output"];  // required: what fires the camera
    output.ExpectKeys({"driver", "chip", "offset", "active_low"});
    CheckDriver(output["driver"], "trigger output");
    trigger.output_driver = output["driver"].AsString();
    ParseTriggerOutput(output, &trigger);
  } else if (node.Has("output")) {
    node["output"].Fail("a trigger output needs mode: hardware");
  }
  return trigger;
}

sim::SensorModel ParseSensor(const YamlNode& node, int bit_depth) {
  node.ExpectKeys(
      {"response_e_per_us", "e_per_dn", "black_level_dn", "read_noise_e", "full_well_e", "shot_noise", "response_gamma"});
  sim::SensorModel sensor;
  sensor.bit_depth = bit_depth;
  // Bounds far beyond any sensor; within them the renderer's arithmetic stays finite.
  sensor.response_e_per_us = node.DoubleIn("response_e_per_us", sensor.response_e_per_us, 0.0, 1e9);
  sensor.e_per_dn = node.DoubleIn("e_per_dn", sensor.e_per_dn, 0.0, 1e6);
  sensor.black_level_dn = node.DoubleIn("black_level_dn", sensor.black_level_dn, 0.0, 65535.0);
  sensor.read_noise_e = node.DoubleIn("read_noise_e", sensor.read_noise_e, 0.0, 1e6);
  sensor.full_well_e = node.DoubleIn("full_well_e", sensor.full_well_e, 1.0, 1e9);
  sensor.shot_noise = node.Bool("shot_noise", sensor.shot_noise);
  sensor.response_gamma = node.Double("response_gamma", sensor.response_gamma);
  if (!(sensor.response_gamma >= 0.2 && sensor.response_gamma <= 5.0)) node["response_gamma"].Fail("must lie in [0.2, 5]");
  if (!(sensor.response_e_per_us > 0)) node["response_e_per_us"].Fail("must be > 0");
  if (!(sensor.e_per_dn > 0)) node["e_per_dn"].Fail("must be > 0");
  if (!(sensor.read_noise_e >= 0)) node["read_noise_e"].Fail("must be >= 0");
  if (!(sensor.full_well_e > 0)) node["full_well_e"].Fail("must be > 0");
  if (!(sensor.black_level_dn >= 0 && sensor.black_level_dn < sensor.max_dn()))
    node["black_level_dn"].Fail("must lie within the sensor's range");
  return sensor;
}

template <typename T>
std::set<T> IndexSet(const YamlNode& node, const char* key) {
  std::set<T> values;
  if (auto list = node.Find(key))
    for (const YamlNode& item : list->Items()) {
      const int value = item.AsInt();
      if (value < 0) item.Fail("must be >= 0");
      values.insert(static_cast<T>(value));
    }
  return values;
}

// sim.faults: {camera: {drop_frames: [..], short_frames: [..], corrupt_frames: [..], disconnect_at: [..],
//                       repeat_frames: [..], lens_cap: bool},
//              lights: {fail_commands: [..], stuck_off_channels: [..], dim_channels: {<channel>: fraction}},
//              motion: {<axis id>: {refused_moves: [..]}}}
void ParseFaults(const YamlNode& node, const std::optional<MotionConfig>& motion, SimConfig* sim) {
  node.ExpectKeys({"camera", "lights", "motion"});
  if (auto camera = node.Find("camera")) {
    camera->ExpectKeys({"drop_frames", "short_frames", "corrupt_frames", "disconnect_at", "repeat_frames", "lens_cap"});
    sim->camera_faults.drop_frames = IndexSet<std::uint64_t>(*camera, "drop_frames");
    sim->camera_faults.short_frames = IndexSet<std::uint64_t>(*camera, "short_frames");
    sim->camera_faults.corrupt_frames = IndexSet<std::uint64_t>(*camera, "corrupt_frames");
    sim->camera_faults.disconnect_at = IndexSet<std::uint64_t>(*camera, "disconnect_at");
    sim->camera_faults.repeat_frames = IndexSet<std::uint64_t>(*camera, "repeat_frames");
    sim->camera_faults.lens_cap = camera->Bool("lens_cap", false);
  }
  if (auto lights = node.Find("lights")) {
    lights->ExpectKeys({"fail_commands", "stuck_off_channels", "dim_channels"});
    sim->light_faults.fail_commands = IndexSet<std::uint64_t>(*lights, "fail_commands");
    sim->light_faults.stuck_off_channels = IndexSet<int>(*lights, "stuck_off_channels");
    if (auto dim = lights->Find("dim_channels"))
      for (const std::string& key : dim->Keys()) {
        const YamlNode fraction = (*dim)[key];
        int channel = -1;
        try {
          std::size_t used = 0;
          channel = std::stoi(key, &used);
          if (used != key.size()) channel = -1;
        } catch (const std::exception&) {
        }
        if (channel < 0) fraction.Fail("'" + key + "' is not a channel number (>= 0)");
        if (!(fraction.AsDouble() >= 0.0 && fraction.AsDouble() < 1.0))
          fraction.Fail("must lie in [0, 1): the fraction of its light the LED still emits");
        sim->light_faults.dim_channels[channel] = fraction.AsDouble();
      }
  }
  if (auto axes = node.Find("motion")) {
    if (!motion) axes->Fail("motion faults need a 'motion:' section");
    for (const std::string& id : axes->Keys()) {
      const YamlNode axis = (*axes)[id];
      if (!motion->axis(id)) axis.Fail("no axis '" + id + "' in motion.axes");
      axis.ExpectKeys({"refused_moves"});
      sim->axis_faults[id].refused_moves = IndexSet<std::uint64_t>(axis, "refused_moves");
    }
  }
}

// sim.ambient: {dome_fraction, stray_irradiance, samples}
sim::AmbientLight ParseAmbient(const YamlNode& node) {
  node.ExpectKeys({"dome_fraction", "stray_irradiance", "samples"});
  sim::AmbientLight ambient;
  ambient.dome_fraction = node.Double("dome_fraction", ambient.dome_fraction);
  ambient.stray_irradiance = node.Double("stray_irradiance", ambient.stray_irradiance);
  ambient.samples = node.Int("samples", ambient.samples);
  std::string why;
  if (!ambient.IsValid(&why)) node.Fail(why);
  return ambient;
}

// camera.color_chart: {box_px: [x, y, w, h]} or {corners_px: [[x, y] x 4]}, inside the frame.
ColorChartPlacement ParseColorChart(const YamlNode& node, int width, int height) {
  node.ExpectKeys({"box_px", "corners_px"});
  if (node.Has("box_px") == node.Has("corners_px")) node.Fail("give exactly one of 'box_px' or 'corners_px'");
  ColorChartPlacement chart;
  if (auto box = node.Find("box_px")) {
    const auto v = box->Items();
    if (v.size() != 4) box->Fail("expected [x, y, w, h], got " + std::to_string(v.size()) + " numbers");
    const double x = v[0].AsDouble(), y = v[1].AsDouble(), w = v[2].AsDouble(), h = v[3].AsDouble();
    if (!(w > 0 && h > 0)) box->Fail("width and height must be > 0");
    chart.corners_px = {Eigen::Vector2d(x, y), Eigen::Vector2d(x + w, y), Eigen::Vector2d(x + w, y + h),
                        Eigen::Vector2d(x, y + h)};
  } else {
    const YamlNode corners = node["corners_px"];
    const auto points = corners.Items();
    if (points.size() != 4) corners.Fail("expected four [x, y] points, got " + std::to_string(points.size()));
    for (std::size_t i = 0; i < 4; ++i) {
      const auto xy = points[i].Items();
      if (xy.size() != 2) points[i].Fail("expected [x, y]");
      chart.corners_px[i] = Eigen::Vector2d(xy[0].AsDouble(), xy[1].AsDouble());
    }
    // Shoelace area: clockwise in image coordinates (y down) is positive.
    double area = 0.0;
    for (std::size_t i = 0; i < 4; ++i) {
      const Eigen::Vector2d& a = chart.corners_px[i];
      const Eigen::Vector2d& b = chart.corners_px[(i + 1) % 4];
      area += a.x() * b.y() - b.x() * a.y();
    }
    if (!(area > 0.0)) corners.Fail("corners must run clockwise from the top-left and enclose an area");
  }
  for (const Eigen::Vector2d& p : chart.corners_px)
    if (p.x() < 0 || p.y() < 0 || p.x() > width || p.y() > height)
      node.Fail("chart corner (" + std::to_string(p.x()) + ", " + std::to_string(p.y()) + ") lies outside the " +
                std::to_string(width) + " x " + std::to_string(height) + " frame");
  return chart;
}

// motion: {driver, link, time_scale, profile: {velocity_deg_s, acceleration_deg_s2}, settle,
//          axes: [{id, min_deg, max_deg, base_address}], constraints: [{min_separation_deg, axes}]}
MotionConfig ParseMotion(const YamlNode& node) {
  node.ExpectKeys({"driver", "link", "time_scale", "profile", "settle", "axes", "constraints"});
  MotionConfig motion;
  motion.driver = node.String("driver", "modbus-tcp");
  if (node.Has("driver")) CheckDriver(node["driver"], "motion");
  if (auto profile = node.Find("profile")) {
    profile->ExpectKeys({"velocity_deg_s", "acceleration_deg_s2"});
    motion.profile.velocity_deg_s = profile->Double("velocity_deg_s", motion.profile.velocity_deg_s);
    motion.profile.acceleration_deg_s2 = profile->Double("acceleration_deg_s2", motion.profile.acceleration_deg_s2);
    if (!(motion.profile.velocity_deg_s > 0)) (*profile)["velocity_deg_s"].Fail("must be > 0");
    if (!(motion.profile.acceleration_deg_s2 > 0)) (*profile)["acceleration_deg_s2"].Fail("must be > 0");
  }
  drivers::SettleOptions& settle = motion.settle;
  if (auto s = node.Find("settle")) {
    s->ExpectKeys({"tolerance_deg", "settle_ms", "timeout_ms", "poll_ms", "stall_window_ms", "overshoot_deg"});
    settle.tolerance_deg = s->Double("tolerance_deg", settle.tolerance_deg);
    settle.settle_ms = s->Int("settle_ms", settle.settle_ms);
    settle.timeout_ms = s->Int("timeout_ms", settle.timeout_ms);
    settle.poll_ms = s->Int("poll_ms", settle.poll_ms);
    settle.stall_window_ms = s->Int("stall_window_ms", settle.stall_window_ms);
    settle.overshoot_deg = s->Double("overshoot_deg", settle.overshoot_deg);
    std::string why;
    if (!settle.IsValid(&why)) s->Fail(why);
  }
  for (const YamlNode& item : node["axes"].Items()) {
    item.ExpectKeys({"id", "base_address", "min_deg", "max_deg", "home_deg"});
    AxisConfig axis{item["id"].AsString(),
                    {item.Double("min_deg", -180.0), item.Double("max_deg", 180.0), item.Double("home_deg", 0.0)}};
    if (!(axis.limits.min_deg < axis.limits.max_deg)) item.Fail("needs min_deg < max_deg");
    if (!axis.limits.Contains(axis.limits.home_deg)) item.Fail("needs home_deg within [min_deg, max_deg]");
    if (motion.axis(axis.id)) item["id"].Fail("duplicate axis id '" + axis.id + "'");
    motion.axes.push_back(axis);
  }
  if (auto list = node.Find("constraints"))
    for (const YamlNode& item : list->Items()) {
      item.ExpectKeys({"min_separation_deg", "axes"});
      const auto names = item["axes"].Items();
      if (names.size() != 2) item["axes"].Fail("names exactly two axes");
      for (const YamlNode& name : names)
        if (!motion.axis(name.AsString())) name.Fail("no axis '" + name.AsString() + "' in motion.axes");
      const double min_deg = item["min_separation_deg"].AsDouble();
      if (!(min_deg >= 0)) item["min_separation_deg"].Fail("must be >= 0");
      motion.constraints.push_back({names[0].AsString(), names[1].AsString(), min_deg});
      const double home_gap = std::abs(motion.axis(names[0].AsString())->limits.home_deg -
                                       motion.axis(names[1].AsString())->limits.home_deg);
      if (home_gap < min_deg)
        item.Fail("the two arms' homes (home_deg) are " + std::to_string(home_gap) +
                  " deg apart, closer than min_separation_deg: homing would drive them into each other");
    }
  ParseMotionDriver(node, &motion);
  return motion;
}

// health: {enabled, lit_sigma, max_clipped_fraction, saturation_dn, min_neighbour_ratio, neighbours,
//          max_brightness_ratio}; `health` holds the defaults.
HealthConfig ParseHealth(const YamlNode& node, HealthConfig health) {
  node.ExpectKeys({"enabled", "lit_sigma", "max_clipped_fraction", "saturation_dn", "min_neighbour_ratio",
                   "neighbours", "max_brightness_ratio"});
  health.enabled = node.Bool("enabled", health.enabled);
  auto in_range = [&node](const char* key, double value, double low, double high, const char* range) {
    if (!(value >= low && value <= high)) node[key].Fail(std::string("must lie in ") + range);
    return value;
  };
  health.lit_sigma = in_range("lit_sigma", node.Double("lit_sigma", health.lit_sigma), 3.0, 1000.0, "[3, 1000]");
  health.max_clipped_fraction = in_range(
      "max_clipped_fraction", node.Double("max_clipped_fraction", health.max_clipped_fraction), 0.0, 1.0, "[0, 1]");
  health.saturation_dn =
      in_range("saturation_dn", node.Double("saturation_dn", health.saturation_dn), 0.0, 65535.0, "[0, 65535]");
  health.min_neighbour_ratio = in_range(
      "min_neighbour_ratio", node.Double("min_neighbour_ratio", health.min_neighbour_ratio), 0.0, 0.99, "[0, 0.99]");
  health.neighbours = static_cast<int>(
      in_range("neighbours", node.Int("neighbours", health.neighbours), 1, 16, "[1, 16]"));
  health.max_brightness_ratio = in_range(
      "max_brightness_ratio", node.Double("max_brightness_ratio", health.max_brightness_ratio), 1.1, 100.0,
      "[1.1, 100]");
  return health;
}

// reference_target: {albedo, pose: {light_arm_deg, camera_arm_deg, sample_rotation_deg, sample_changer_deg}}
ReferenceTargetConfig ParseReferenceTarget(const YamlNode& node, const RigConfig& rig) {
  if (!rig.motion) node.Fail("only a gonioreflectometer rig has a reference target");
  node.ExpectKeys({"albedo", "pose"});
  ReferenceTargetConfig target;
  // Above 1 would be a fluorescent or retro-reflecting target, not a diffuse standard.
  target.albedo = node["albedo"].AsDoubleIn(0.01, 1.0);
  const YamlNode pose = node["pose"];
  pose.ExpectKeys({"light_arm_deg", "camera_arm_deg", "sample_rotation_deg", "sample_changer_deg"});
  target.pose = {pose["light_arm_deg"].AsDouble(), pose["camera_arm_deg"].AsDouble(),
                 pose.Double("sample_rotation_deg", 0.0), std::nullopt};
  std::map<std::string, double> at = {{"light_arm", target.pose.light_arm_deg},
                                      {"camera_arm", target.pose.camera_arm_deg},
                                      {"sample_rotation", target.pose.sample_rotation_deg}};
  if (auto changer = pose.Find("sample_changer_deg")) {
    target.pose.sample_changer_deg = changer->AsDouble();
    // 0 holds the sample: the target needs a slot of its own.
    if (std::abs(*target.pose.sample_changer_deg) <= 0.5) changer->Fail("0 is the sample's slot, not the target's");
    at["sample_changer"] = *target.pose.sample_changer_deg;
  }
  if (const std::string why = rig.motion->CheckPose(at); !why.empty()) pose.Fail("the arms cannot reach it: " + why);
  // The target is measured at the one pose: a grazing one would weigh its
  // departure from Lambertian and its tilt error most.
  if (std::abs(target.pose.light_arm_deg) > 60.0 || std::abs(target.pose.camera_arm_deg) > 60.0)
    pose.Fail("light and camera arms within 60 deg of the normal (a diffuse standard is Lambertian only there)");
  return target;
}

}  // namespace

const AxisConfig* MotionConfig::axis(const std::string& id) const {
  for (const AxisConfig& a : axes)
    if (a.id == id) return &a;
  return nullptr;
}

std::string MotionConfig::CheckPose(const std::map<std::string, double>& positions_deg) const {
  for (const auto& [id, deg] : positions_deg) {
    const AxisConfig* a = axis(id);
    if (!a) return "no axis '" + id + "'";
    if (!a->limits.Contains(deg))
      return "axis " + id + " target " + std::to_string(deg) + " deg outside its soft limits [" +
             std::to_string(a->limits.min_deg) + ", " + std::to_string(a->limits.max_deg) + "]";
  }
  for (const drivers::SeparationConstraint& c : constraints) {
    const auto a = positions_deg.find(c.axis_a), b = positions_deg.find(c.axis_b);
    if (a == positions_deg.end() || b == positions_deg.end()) continue;
    const double separation = std::abs(a->second - b->second);
    if (separation < c.min_deg)
      return c.axis_a + " and " + c.axis_b + " " + std::to_string(separation) + " deg apart, below the minimum " +
             std::to_string(c.min_deg) + " deg";
  }
  return {};
}

namespace {

// lights.position_calibration: where the LEDs' positions came from
// (`photorig calibrate leds`). For people reading the rig; checked so a hand
// edit stays readable.
void CheckPositionCalibrationRecord(const YamlNode& record) {
  record.ExpectKeys({"date", "source_run", "method", "spheres_mm", "radius_mm", "leds_placed",
                     "mean_rms_ray_distance_mm", "max_rms_ray_distance_mm", "mean_shift_mm", "max_shift_mm"});
  record["date"].AsString();
  if (auto run = record.Find("source_run")) run->AsString();
  if (auto method = record.Find("method")) method->AsString();
  if (auto spheres = record.Find("spheres_mm"))
    for (const YamlNode& centre : spheres->Items()) centre.AsVector3();
  if (auto radius = record.Find("radius_mm")) radius->AsDoubleIn(1e-3, 1e4);
  if (auto placed = record.Find("leds_placed")) placed->AsInt();
  for (const char* figure : {"mean_rms_ray_distance_mm", "max_rms_ray_distance_mm", "mean_shift_mm", "max_shift_mm"})
    if (auto value = record.Find(figure)) value->AsDoubleIn(0.0, 1e4);
}

// camera.calibration: where a pinhole lens came from (`photorig calibrate
// camera`). For people reading the rig; checked so a hand edit stays readable.
void CheckCalibrationRecord(const YamlNode& record) {
  record.ExpectKeys({"date", "rms_px", "distortion_model", "tilt_deg", "board", "plane_image", "images", "rejected"});
  record["date"].AsString();
  record["rms_px"].AsDoubleIn(0.0, 1e3);
  record.Choice("distortion_model", solvers::camera::kDistortionModelNames, solvers::camera::DistortionModel::kNone);
  if (auto tilt = record.Find("tilt_deg")) tilt->AsDoubleIn(0.0, 90.0);
  if (auto board = record.Find("board")) {
    board->ExpectKeys({"inner_corners", "square_mm"});
    if ((*board)["inner_corners"].AsIntList().size() != 2) (*board)["inner_corners"].Fail("needs [cols, rows]");
    (*board)["square_mm"].AsDoubleIn(1e-3, 1e4);
  }
  if (auto plane = record.Find("plane_image")) plane->AsString();
  for (const char* list : {"images", "rejected"})
    if (auto files = record.Find(list))
      for (const YamlNode& file : files->Items()) file.AsString();
}

// lights.radiance_calibration: where the LEDs' intensities and exponents
// came from (`photorig calibrate radiance`, docs/lighting.md).
void CheckRadianceCalibrationRecord(const YamlNode& record) {
  record.ExpectKeys({"date", "source_run", "albedo", "exponent", "worst_model_error"});
  record["date"].AsString();
  record["source_run"].AsString();
  record["albedo"].AsDoubleIn(1e-6, 1.0);
  record["exponent"].AsString();
  record["worst_model_error"].AsDoubleIn(0.0, 1.0);
}

// camera.projection: orthographic with its pixel pitch, or pinhole with its
// lens; a pinhole's pixel pitch is its pixel's size on the sample plane.
void ParseProjection(const YamlNode& camera, CameraConfig* cam) {
  cam->projection = camera.Choice("projection", solvers::camera::kProjectionNames, cam->projection);
  if (cam->projection == solvers::camera::Projection::kOrthographic) {
    if (auto lens = camera.Find("pinhole")) lens->Fail("a pinhole: lens needs projection: pinhole");
    if (auto record = camera.Find("calibration")) record->Fail("a lens calibration needs projection: pinhole");
    cam->pixel_pitch_mm = camera.Double("pixel_pitch_mm", cam->pixel_pitch_mm);
    if (!(cam->pixel_pitch_mm > 0 && cam->pixel_pitch_mm <= 1000)) camera["pixel_pitch_mm"].Fail("must lie in (0, 1000]");
    return;
  }
  if (auto pitch = camera.Find("pixel_pitch_mm"))
    pitch->Fail("a pinhole camera's pixel size on the object follows from pinhole: fx_px and distance_mm; leave "
                "pixel_pitch_mm out");
  const YamlNode lens = camera["pinhole"];
  lens.ExpectKeys({"fx_px", "fy_px", "cx_px", "cy_px", "distortion", "distance_mm"});
  solvers::camera::PinholeLens& pinhole = cam->pinhole;
  pinhole.fx_px = lens["fx_px"].AsDoubleIn(1.0, 1e6);
  pinhole.fy_px = lens.DoubleIn("fy_px", pinhole.fx_px, 1.0, 1e6);
  // OpenCV's convention: pixel centres at whole numbers, the middle of the image at (W - 1) / 2.
  pinhole.cx_px = lens.DoubleIn("cx_px", 0.5 * (cam->width - 1), 0.0, cam->width - 1.0);
  pinhole.cy_px = lens.DoubleIn("cy_px", 0.5 * (cam->height - 1), 0.0, cam->height - 1.0);
  if (auto distortion = lens.Find("distortion")) {
    const std::vector<YamlNode> k = distortion->Items();
    if (k.size() != 5 && k.size() != 4) distortion->Fail("needs OpenCV's k1, k2, p1, p2[, k3]");
    for (std::size_t i = 0; i < k.size(); ++i) pinhole.distortion[i] = k[i].AsDoubleIn(-10.0, 10.0);
  }
  pinhole.distance_mm = lens["distance_mm"].AsDoubleIn(1.0, 1e5);
  cam->pixel_pitch_mm = pinhole.distance_mm / pinhole.fx_px;
  if (std::string why; !cam->Geometry().IsValid(&why)) lens.Fail(why);
  if (auto record = camera.Find("calibration")) CheckCalibrationRecord(*record);
}

}  // namespace

RigConfig LoadRigConfig(const std::string& path) {
  const YamlNode root = YamlNode::LoadFile(path);
  root.ExpectKeys({"rig", "lights", "camera", "sim", "motion", "health", "solve", "reference_target"});
  RigConfig rig;
  rig.path = path;
  const YamlNode header = root["rig"];
  header.ExpectKeys({"name", "kind", "description"});
  rig.name = header["name"].AsString();
  rig.kind = header.Choice("kind", kRigKindNames, rig.kind);
  if (auto motion = root.Find("motion")) {
    if (rig.kind != RigKind::kGonioreflectometer) motion->Fail("only a gonioreflectometer rig has motion");
    rig.motion = ParseMotion(*motion);
    for (const char* axis : {"light_arm", "camera_arm", "sample_rotation"})
      if (!rig.motion->axis(axis)) (*motion)["axes"].Fail(std::string("a gonioreflectometer needs an axis '") + axis + "'");
  } else if (rig.kind == RigKind::kGonioreflectometer) {
    root.Fail("a gonioreflectometer rig needs a 'motion:' section");
  }
  if (auto target = root.Find("reference_target")) rig.reference_target = ParseReferenceTarget(*target, rig);

  const YamlNode lights = root["lights"];
  lights.ExpectKeys({"driver", "id", "leds", "options", "position_calibration", "radiance_calibration"});
  if (auto record = lights.Find("position_calibration")) CheckPositionCalibrationRecord(*record);
  CheckDriver(lights["driver"], "light");
  if (auto record = lights.Find("radiance_calibration")) CheckRadianceCalibrationRecord(*record);
  rig.lights.driver = lights["driver"].AsString();
  rig.lights.id = lights.String("id", "lights");
  std::set<int> ids;
  const auto leds = lights["leds"].Items();
  for (std::size_t i = 0; i < leds.size(); ++i) {
    LedConfig led = ParseLed(leds[i], static_cast<int>(i));
    if (!ids.insert(led.id).second) leds[i].Fail("duplicate LED id " + std::to_string(led.id));
    rig.lights.leds.push_back(led);
  }
  if (rig.lights.leds.empty()) lights["leds"].Fail("a light dome needs at least one LED");
  const bool simulated = root.Has("sim");
  ParseLightsOptions(lights, simulated, &rig.lights);

  const YamlNode camera = root["camera"];
  camera.ExpectKeys({"driver", "id", "options", "projection", "pinhole", "width", "height", "pixel_pitch_mm", "bit_depth",
                     "exposure_us", "gain_db", "dn_per_radiance_per_us", "e_per_dn", "color_chart", "trigger",
                     "pixel_format", "color_model", "calibration"});
  CameraConfig& cam = rig.camera;
  CheckDriver(camera["driver"], "camera");
  cam.driver = camera["driver"].AsString();
  cam.id = camera.String("id", "camera");
  ParseCameraOptions(camera, simulated, &cam);
  cam.width = camera["width"].AsInt();
  cam.height = camera["height"].AsInt();
  if (cam.width < 8 || cam.width > 16384) camera["width"].Fail("must be within [8, 16384]");
  if (cam.height < 8 || cam.height > 16384) camera["height"].Fail("must be within [8, 16384]");
  ParseProjection(camera, &cam);
  cam.bit_depth = camera.Int("bit_depth", cam.bit_depth);
  if (cam.bit_depth != 8 && cam.bit_depth != 10 && cam.bit_depth != 12 && cam.bit_depth != 16)
    camera["bit_depth"].Fail("must be 8, 10, 12 or 16");
  cam.exposure_us = camera.DoubleIn("exposure_us", cam.exposure_us, kMinExposureUs, kMaxExposureUs);
  cam.gain_db = camera.DoubleIn("gain_db", cam.gain_db, kMinGainDb, kMaxGainDb);
  if (auto trigger = camera.Find("trigger")) cam.trigger = ParseTrigger(*trigger);
  if (auto chart = camera.Find("color_chart")) cam.color_chart = ParseColorChart(*chart, cam.width, cam.height);
  if (auto format = camera.Find("pixel_format")) {
    cam.pixel_format = format->AsString();
    const std::string mosaic = drivers::MosaicOfPixelFormat(cam.pixel_format);
    const int bits = drivers::BitsOfPixelFormat(cam.pixel_format);
    if (mosaic.empty() || mosaic == "RGB")
      format->Fail("'" + cam.pixel_format + "' is not a format frames can be stored in (Mono8/10/12/16, "
                   "BayerRG/GR/GB/BG 8/10/12/16)");
    if (bits != cam.bit_depth)
      format->Fail(cam.pixel_format + " delivers " + std::to_string(bits) + " bits but bit_depth is " +
                   std::to_string(cam.bit_depth));
    cam.mosaic = mosaic;
  }
  if (auto model = camera.Find("color_model")) {
    if (cam.mosaic == "mono") model->Fail("a colour model needs a colour camera (pixel_format Bayer*)");
    cam.color_model = LoadColorModelFile(model->AsPath());
  }

  if (auto solve = root.Find("solve")) {
    solve->ExpectKeys({"executor", "partition", "time", "mem", "photorig", "poll_ms"});
    rig.solve = ParseSolveExecutor(*solve, rig.solve);
  }
  if (auto sim_node = root.Find("sim")) {
    sim_node->ExpectKeys(
        {"seed", "sensor", "scene", "faults", "led_direction_error_deg", "led_intensity_error_pct",
         "led_emitter_radius_mm", "ambient", "color"});
    SimConfig sim;
    sim.seed = static_cast<std::uint64_t>(sim_node->Int("seed", 1));
    sim.led_direction_error_deg = sim_node->Double("led_direction_error_deg", 0.0);
    if (!(sim.led_direction_error_deg >= 0.0 && sim.led_direction_error_deg < 30.0))
      (*sim_node)["led_direction_error_deg"].Fail("must lie in [0, 30)");
    sim.led_intensity_error_pct = sim_node->Double("led_intensity_error_pct", 0.0);
    if (!(sim.led_intensity_error_pct >= 0.0 && sim.led_intensity_error_pct < 30.0))
      (*sim_node)["led_intensity_error_pct"].Fail("must lie in [0, 30)");
    sim.led_emitter_radius_mm = sim_node->Double("led_emitter_radius_mm", sim.led_emitter_radius_mm);
    if (!(sim.led_emitter_radius_mm > 0.0 && sim.led_emitter_radius_mm <= 50.0))
      (*sim_node)["led_emitter_radius_mm"].Fail("must lie in (0, 50]");
    if (auto ambient = sim_node->Find("ambient")) sim.ambient = ParseAmbient(*ambient);
    if (auto color = sim_node->Find("color")) {
      color->ExpectKeys({"camera", "illuminant"});
      sim.color.camera = color->String("camera", sim.color.camera);
      const auto& cameras = solvers::color::CameraNames();
      if (std::find(cameras.begin(), cameras.end(), sim.color.camera) == cameras.end())
        (*color)["camera"].Fail("unknown camera '" + sim.color.camera + "'");
      const std::string illuminant = color->String("illuminant", "D65");
      const auto parsed = solvers::color::ParseIlluminant(illuminant);
      if (!parsed) (*color)["illuminant"].Fail("unknown illuminant '" + illuminant + "' (known: D50, D65, A)");
      sim.color.illuminant = *parsed;
    }
    const auto sensor = sim_node->Find("sensor");
    sim.sensor = sensor ? ParseSensor(*sensor, cam.bit_depth) : sim::SensorModel{};
    sim.sensor.bit_depth = cam.bit_depth;
    if (auto scene = sim_node->Find("scene")) sim.scene = ParseScene(*scene, FrameWidthMm(rig));
    if (auto faults = sim_node->Find("faults")) ParseFaults(*faults, rig.motion, &sim);
    // A simulated camera is calibrated by construction.
    cam.dn_per_radiance_per_us = sim.sensor.response_e_per_us / sim.sensor.e_per_dn;
    cam.e_per_dn = sim.sensor.e_per_dn;
    rig.sim = sim;
    // The simulator shows its target in a sample changer slot, nowhere else.
    if (rig.reference_target && !rig.reference_target->pose.sample_changer_deg)
      root["reference_target"]["pose"].Fail(
          "a simulated gonioreflectometer shows its reference target in a sample changer slot: give sample_changer_deg");
  }
  if (auto conversion = camera.Find("e_per_dn")) {
    cam.e_per_dn = conversion->AsDouble();
    if (!(cam.e_per_dn > 0)) conversion->Fail("must be > 0");
  }
  if (auto calibration = camera.Find("dn_per_radiance_per_us")) {
    cam.dn_per_radiance_per_us = calibration->AsDouble();
    if (!(cam.dn_per_radiance_per_us > 0)) calibration->Fail("must be > 0");
  }
  if (rig.sim) {
    const sim::SensorModel& sensor = rig.sim->sensor;
    rig.health.saturation_dn =
        std::min(sensor.max_dn(), sensor.black_level_dn + sensor.full_well_e / sensor.e_per_dn) -
        3.0 * sensor.read_noise_e / sensor.e_per_dn;
  }
  if (auto health = root.Find("health")) rig.health = ParseHealth(*health, rig.health);
  if ((rig.lights.driver == "sim" || cam.driver == "sim") && !rig.sim)
    root.Fail("simulated devices need a 'sim:' section");
  return rig;
}

double FrameWidthMm(const RigConfig& rig) { return rig.camera.width * rig.camera.pixel_pitch_mm; }

SolveExecutorConfig ParseSolveExecutor(const YamlNode& node, SolveExecutorConfig solve) {
  solve.executor = node.Choice("executor", kExecutorNames, solve.executor);
  solve.partition = node.String("partition", solve.partition);
  solve.time = node.String("time", solve.time);
  solve.mem = node.String("mem", solve.mem);
  solve.photorig = node.String("photorig", solve.photorig);
  solve.poll_ms = node.Int("poll_ms", solve.poll_ms);
  if (solve.poll_ms < 100 || solve.poll_ms > 600000) node["poll_ms"].Fail("must lie in [100, 600000]");
  return solve;
}

}  // namespace photorig::config
