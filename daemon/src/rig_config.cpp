#include "photorig/daemon/rig_config.h"

#include "photorig/daemon/device_factory.h"
#include "photorig/daemon/yaml_node.h"

#include <filesystem>
#include <set>
#include <stdexcept>

namespace photorig::daemon {
namespace {

LedConfig ParseLed(const YamlNode& node, int index) {
  node.ExpectKeys({"id", "direction", "position_mm", "intensity", "channel", "rgb_intensity"});
  LedConfig led;
  led.id = node.Int("id", index);
  led.channel = node.Int("channel", index);
  if (led.channel < 0) node["channel"].Fail("must be >= 0");
  const bool has_direction = node.Has("direction"), has_position = node.Has("position_mm");
  if (has_direction == has_position) node.Fail("give exactly one of 'direction' or 'position_mm'");
  // A position far from a small object is a direction; near-field falloff is
  // the renderer's business, not the solver's.
  const YamlNode vector_node = has_direction ? node["direction"] : node["position_mm"];
  const Eigen::Vector3d vector = vector_node.AsVector3();
  if (vector.norm() < 1e-9) vector_node.Fail("must not be the zero vector");
  led.direction = vector.normalized();
  if (led.direction.z() <= 0.0) vector_node.Fail("points below the sample plane (z <= 0)");
  led.intensity = node.Double("intensity", 1.0);
  if (!(led.intensity > 0.0)) node["intensity"].Fail("must be > 0");
  if (auto rgb = node.Find("rgb_intensity")) {
    led.rgb_intensity = rgb->AsVector3();
    if (!(led.rgb_intensity.minCoeff() >= 0.0 && led.rgb_intensity.maxCoeff() > 0.0))
      rgb->Fail("needs three values >= 0, not all zero");
  }
  return led;
}

sim::SensorModel ParseSensor(const YamlNode& node, int bit_depth) {
  node.ExpectKeys({"response_e_per_us", "e_per_dn", "black_level_dn", "read_noise_e", "full_well_e", "shot_noise"});
  sim::SensorModel sensor;
  sensor.bit_depth = bit_depth;
  sensor.response_e_per_us = node.Double("response_e_per_us", sensor.response_e_per_us);
  sensor.e_per_dn = node.Double("e_per_dn", sensor.e_per_dn);
  sensor.black_level_dn = node.Double("black_level_dn", sensor.black_level_dn);
  sensor.read_noise_e = node.Double("read_noise_e", sensor.read_noise_e);
  sensor.full_well_e = node.Double("full_well_e", sensor.full_well_e);
  sensor.shot_noise = node.Bool("shot_noise", sensor.shot_noise);
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

// sim.faults: {camera: {drop_frames: [..], short_frames: [..], corrupt_frames: [..], disconnect_at: [..]},
//              lights: {fail_commands: [..], stuck_off_channels: [..]}}
void ParseFaults(const YamlNode& node, SimConfig* sim) {
  node.ExpectKeys({"camera", "lights"});
  if (auto camera = node.Find("camera")) {
    camera->ExpectKeys({"drop_frames", "short_frames", "corrupt_frames", "disconnect_at"});
    sim->camera_faults.drop_frames = IndexSet<std::uint64_t>(*camera, "drop_frames");
    sim->camera_faults.short_frames = IndexSet<std::uint64_t>(*camera, "short_frames");
    sim->camera_faults.corrupt_frames = IndexSet<std::uint64_t>(*camera, "corrupt_frames");
    sim->camera_faults.disconnect_at = IndexSet<std::uint64_t>(*camera, "disconnect_at");
  }
  if (auto lights = node.Find("lights")) {
    lights->ExpectKeys({"fail_commands", "stuck_off_channels"});
    sim->light_faults.fail_commands = IndexSet<std::uint64_t>(*lights, "fail_commands");
    sim->light_faults.stuck_off_channels = IndexSet<int>(*lights, "stuck_off_channels");
  }
}

}  // namespace

sim::Scene ParseScene(const YamlNode& node, double frame_width_mm) {
  node.ExpectKeys({"shape", "radius_mm", "albedo", "cast_shadows", "brdf", "path", "depth_scale_mm", "depth_pitch_mm",
                   "mesh_scale", "tilt_deg", "bowl_radius_mm", "rim_radius_mm", "step_width_mm", "step_height_mm",
                   "step_slope", "backlight_radiance", "peak_density_per_mm"});
  sim::Scene scene;
  const YamlNode shape = node["shape"];
  try {
    scene.shape = sim::Scene::ParseShape(shape.AsString());
  } catch (const std::invalid_argument& e) {
    shape.Fail(e.what());
  }
  scene.ApplyShapeDefaults(frame_width_mm);
  scene.sphere_radius_mm = node.Double("radius_mm", scene.sphere_radius_mm);
  if (!(scene.sphere_radius_mm > 0)) node["radius_mm"].Fail("must be > 0");
  scene.cast_shadows = node.Bool("cast_shadows", true);
  scene.tilt_deg = node.Double("tilt_deg", scene.tilt_deg);
  scene.bowl_radius_mm = node.Double("bowl_radius_mm", scene.bowl_radius_mm);
  scene.rim_radius_mm = node.Double("rim_radius_mm", scene.rim_radius_mm);
  scene.step_width_mm = node.Double("step_width_mm", scene.step_width_mm);
  scene.step_height_mm = node.Double("step_height_mm", scene.step_height_mm);
  scene.step_slope = node.Double("step_slope", scene.step_slope);
  scene.depth_scale_mm = node.Double("depth_scale_mm", scene.depth_scale_mm);
  scene.depth_pitch_mm = node.Double("depth_pitch_mm", scene.depth_pitch_mm);
  scene.mesh_scale = node.Double("mesh_scale", scene.mesh_scale);
  scene.backlight_radiance = node.Double("backlight_radiance", scene.backlight_radiance);
  if (auto density = node.Find("peak_density_per_mm")) {
    if (!(density->AsDouble() >= 0)) density->Fail("must be >= 0");
    scene.volume = sim::DensityGrid::Blobs(0.8 * frame_width_mm, 64, density->AsDouble());
  }
  // Files named in a recipe are relative to the recipe, and must load now, not mid-run.
  auto resolve = [](const YamlNode& path_node) {
    const std::filesystem::path path = path_node.AsString();
    return (path.is_absolute() ? path : std::filesystem::path(path_node.file()).parent_path() / path).string();
  };
  if (auto path = node.Find("path")) {
    if (scene.shape == sim::Scene::Shape::kDepthMap) scene.depth_map_path = resolve(*path);
    else if (scene.shape == sim::Scene::Shape::kMesh) scene.mesh_path = resolve(*path);
    else path->Fail("only depth_map and mesh scenes read a file");
    try {
      if (scene.shape == sim::Scene::Shape::kMesh) sim::LoadPly(scene.mesh_path);
      else sim::SampleSurface(scene, 8, 8, 1.0);
    } catch (const std::runtime_error& e) {
      path->Fail(e.what());
    }
  }
  if (auto albedo = node.Find("albedo")) {
    albedo->ExpectKeys({"pattern", "low", "high", "period_mm"});
    const std::string pattern = albedo->String("pattern", "checker");
    if (pattern == "uniform") scene.albedo.pattern = sim::AlbedoTexture::Pattern::kUniform;
    else if (pattern == "checker") scene.albedo.pattern = sim::AlbedoTexture::Pattern::kChecker;
    else if (pattern == "rings") scene.albedo.pattern = sim::AlbedoTexture::Pattern::kRings;
    else (*albedo)["pattern"].Fail("unknown pattern '" + pattern + "' (expected uniform, checker or rings)");
    scene.albedo.low = albedo->Double("low", scene.albedo.low);
    scene.albedo.high = albedo->Double("high", scene.albedo.high);
    scene.albedo.period_mm = albedo->Double("period_mm", scene.albedo.period_mm);
    if (!(scene.albedo.low >= 0 && scene.albedo.high <= 1 && scene.albedo.low <= scene.albedo.high))
      albedo->Fail("albedo needs 0 <= low <= high <= 1");
    if (!(scene.albedo.period_mm > 0)) (*albedo)["period_mm"].Fail("must be > 0");
  }
  // brdf: {model: lambertian|blinn_phong|ggx|mirror|tabulated, rho_s, exponent, roughness, f0, table}
  if (auto brdf = node.Find("brdf")) {
    brdf->ExpectKeys({"model", "rho_s", "exponent", "roughness", "f0", "table"});
    sim::Material& m = scene.material;
    try {
      m.model = sim::Brdf::ParseModel((*brdf)["model"].AsString());
    } catch (const std::invalid_argument& e) {
      (*brdf)["model"].Fail(e.what());
    }
    m.rho_s = brdf->Double("rho_s", m.rho_s);
    m.exponent = brdf->Double("exponent", m.exponent);
    m.roughness = brdf->Double("roughness", m.roughness);
    m.f0 = brdf->Double("f0", m.f0);
    if (auto table = brdf->Find("table")) {
      if (m.model != sim::Brdf::Model::kTabulated) table->Fail("only the tabulated model reads a table");
      try {
        m.table = std::make_shared<sim::MerlTable>(sim::MerlTable::Load(resolve(*table)));
      } catch (const std::runtime_error& e) {
        table->Fail(e.what());
      }
    }
    std::string why;
    if (!m.IsValid(&why)) brdf->Fail(why);
  }
  std::string why;
  if (!scene.IsValid(&why)) node.Fail(why);
  return scene;
}

RigConfig LoadRigConfig(const std::string& path) {
  const YamlNode root = YamlNode::LoadFile(path);
  root.ExpectKeys({"rig", "lights", "camera", "sim"});
  RigConfig rig;
  rig.path = path;
  const YamlNode header = root["rig"];
  header.ExpectKeys({"name", "kind", "description"});
  rig.name = header["name"].AsString();
  if (header.String("kind", "light_dome") != "light_dome")
    header["kind"].Fail("only 'light_dome' rigs are supported so far");

  const YamlNode lights = root["lights"];
  lights.ExpectKeys({"driver", "id", "leds", "options"});
  rig.lights.driver = lights["driver"].AsString();
  if (!IsKnownLightDriver(rig.lights.driver))
    lights["driver"].Fail("unknown driver '" + rig.lights.driver + "' (available: " + LightDriverNames() + ")");
  rig.lights.id = lights.String("id", "lights");
  rig.lights.options = lights.Find("options");
  std::set<int> ids;
  const auto leds = lights["leds"].Items();
  for (std::size_t i = 0; i < leds.size(); ++i) {
    LedConfig led = ParseLed(leds[i], static_cast<int>(i));
    if (!ids.insert(led.id).second) leds[i].Fail("duplicate LED id " + std::to_string(led.id));
    rig.lights.leds.push_back(led);
  }
  if (rig.lights.leds.empty()) lights["leds"].Fail("a light dome needs at least one LED");

  const YamlNode camera = root["camera"];
  camera.ExpectKeys({"driver", "id", "options", "projection", "width", "height", "pixel_pitch_mm", "bit_depth",
                     "exposure_us", "gain_db", "dn_per_radiance_per_us", "e_per_dn"});
  CameraConfig& cam = rig.camera;
  cam.driver = camera["driver"].AsString();
  if (!IsKnownCameraDriver(cam.driver))
    camera["driver"].Fail("unknown driver '" + cam.driver + "' (available: " + CameraDriverNames() + ")");
  cam.id = camera.String("id", "camera");
  cam.options = camera.Find("options");
  cam.projection = camera.String("projection", "orthographic");
  if (cam.projection != "orthographic") camera["projection"].Fail("only 'orthographic' is supported so far");
  cam.width = camera["width"].AsInt();
  cam.height = camera["height"].AsInt();
  if (cam.width < 8 || cam.width > 16384) camera["width"].Fail("must be within [8, 16384]");
  if (cam.height < 8 || cam.height > 16384) camera["height"].Fail("must be within [8, 16384]");
  cam.pixel_pitch_mm = camera.Double("pixel_pitch_mm", cam.pixel_pitch_mm);
  if (!(cam.pixel_pitch_mm > 0)) camera["pixel_pitch_mm"].Fail("must be > 0");
  cam.bit_depth = camera.Int("bit_depth", cam.bit_depth);
  if (cam.bit_depth != 8 && cam.bit_depth != 10 && cam.bit_depth != 12 && cam.bit_depth != 16)
    camera["bit_depth"].Fail("must be 8, 10, 12 or 16");
  cam.exposure_us = camera.Double("exposure_us", cam.exposure_us);
  if (!(cam.exposure_us > 0)) camera["exposure_us"].Fail("must be > 0");
  cam.gain_db = camera.Double("gain_db", cam.gain_db);

  if (auto sim_node = root.Find("sim")) {
    sim_node->ExpectKeys({"seed", "sensor", "scene", "faults"});
    SimConfig sim;
    sim.seed = static_cast<std::uint64_t>(sim_node->Int("seed", 1));
    const auto sensor = sim_node->Find("sensor");
    sim.sensor = sensor ? ParseSensor(*sensor, cam.bit_depth) : sim::SensorModel{};
    sim.sensor.bit_depth = cam.bit_depth;
    if (auto scene = sim_node->Find("scene")) sim.scene = ParseScene(*scene, cam.width * cam.pixel_pitch_mm);
    if (auto faults = sim_node->Find("faults")) ParseFaults(*faults, &sim);
    // A simulated camera is calibrated by construction.
    cam.dn_per_radiance_per_us = sim.sensor.response_e_per_us / sim.sensor.e_per_dn;
    cam.e_per_dn = sim.sensor.e_per_dn;
    rig.sim = sim;
  }
  if (auto conversion = camera.Find("e_per_dn")) {
    cam.e_per_dn = conversion->AsDouble();
    if (!(cam.e_per_dn > 0)) conversion->Fail("must be > 0");
  }
  if (auto calibration = camera.Find("dn_per_radiance_per_us")) {
    cam.dn_per_radiance_per_us = calibration->AsDouble();
    if (!(cam.dn_per_radiance_per_us > 0)) calibration->Fail("must be > 0");
  }
  if ((rig.lights.driver == "sim" || cam.driver == "sim") && !rig.sim)
    root.Fail("simulated devices need a 'sim:' section");
  return rig;
}

}  // namespace photorig::daemon
