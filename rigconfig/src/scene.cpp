#include "photorig/config/scene.h"

#include "photorig/config/sim_color.h"
#include "photorig/sim/mesh.h"

#include <memory>
#include <stdexcept>

namespace photorig::config {

namespace {

// centres_mm: [[x, y], ...]: several spheres on the sample plane (mirror balls
// for near-LED positions); each an [x, y] pair, none overlapping another.
void ParseSphereCentres(const YamlNode& centres, sim::Scene* scene) {
  if (!scene->IsSphere()) centres.Fail("only sphere shapes take centres_mm");
  for (const YamlNode& item : centres.Items()) {
    const std::vector<YamlNode> xy = item.Items();
    if (xy.size() != 2) item.Fail("each of centres_mm is [x, y] in millimetres");
    scene->sphere_centres_mm.emplace_back(xy[0].AsDouble(), xy[1].AsDouble());
  }
  if (scene->sphere_centres_mm.empty()) centres.Fail("give at least one [x, y] centre (or leave centres_mm out)");
  std::string why;
  if (!scene->IsValid(&why)) centres.Fail(why);
}

}  // namespace

sim::Scene ParseScene(const YamlNode& node, double frame_width_mm) {
  node.ExpectKeys({"shape", "radius_mm", "albedo", "cast_shadows", "brdf", "path", "depth_scale_mm", "depth_pitch_mm",
                   "mesh_scale", "tilt_deg", "bowl_radius_mm", "rim_radius_mm", "step_width_mm", "step_height_mm",
                   "step_slope", "backlight_radiance", "peak_density_per_mm", "interreflection_samples", "phantom",
                   "half_extent_mm", "centres_mm"});
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
  if (auto centres = node.Find("centres_mm")) ParseSphereCentres(*centres, &scene);
  scene.cast_shadows = node.Bool("cast_shadows", true);
  scene.interreflection_samples = node.Int("interreflection_samples", 0);
  if (scene.interreflection_samples < 0 || scene.interreflection_samples > 4096)
    node["interreflection_samples"].Fail("must lie in [0, 4096] (0: direct light only)");
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
  if (scene.shape == sim::Scene::Shape::kPhantom) {
    // phantom: shepp_logan_3d | shepp_logan_2d, half_extent_mm, peak_density_per_mm (sigma of amplitude 1)
    const std::string kind = node.String("phantom", "shepp_logan_3d");
    const double half_extent_mm = node.Double("half_extent_mm", scene.phantom.half_extent_mm);
    const double sigma_per_mm = node.Double("peak_density_per_mm", scene.phantom.sigma_per_mm);
    if (!(half_extent_mm > 0)) node["half_extent_mm"].Fail("must be > 0");
    if (!(sigma_per_mm >= 0)) node["peak_density_per_mm"].Fail("must be >= 0");
    if (kind == "shepp_logan_3d") scene.phantom = sim::Phantom::SheppLogan3d(half_extent_mm, sigma_per_mm);
    else if (kind == "shepp_logan_2d") scene.phantom = sim::Phantom::SheppLogan2d(half_extent_mm, sigma_per_mm);
    else node["phantom"].Fail("unknown phantom '" + kind + "' (expected shepp_logan_3d or shepp_logan_2d)");
  } else {
    for (const char* key : {"phantom", "half_extent_mm"})
      if (node.Has(key)) node[key].Fail("only a phantom scene takes this key");
    if (auto density = node.Find("peak_density_per_mm")) {
      if (!(density->AsDouble() >= 0)) density->Fail("must be >= 0");
      scene.volume = sim::DensityGrid::Blobs(0.8 * frame_width_mm, 64, density->AsDouble());
    }
  }
  // Files named in a recipe are relative to the recipe, and must load now, not mid-run.
  if (auto path = node.Find("path")) {
    if (scene.shape == sim::Scene::Shape::kDepthMap) scene.depth_map_path = path->AsPath();
    else if (scene.shape == sim::Scene::Shape::kMesh) scene.mesh_path = path->AsPath();
    else path->Fail("only depth_map and mesh scenes read a file");
    try {
      if (scene.shape == sim::Scene::Shape::kMesh) sim::LoadPly(scene.mesh_path);
      else sim::SampleSurface(scene, 8, 8, 1.0);
    } catch (const std::runtime_error& e) {
      path->Fail(e.what());
    }
  }
  if (auto albedo = node.Find("albedo")) {
    albedo->ExpectKeys({"pattern", "low", "high", "period_mm", "paints"});
    const std::string pattern = albedo->String("pattern", "checker");
    if (pattern == "uniform") scene.albedo.pattern = sim::AlbedoTexture::Pattern::kUniform;
    else if (pattern == "checker") scene.albedo.pattern = sim::AlbedoTexture::Pattern::kChecker;
    else if (pattern == "rings") scene.albedo.pattern = sim::AlbedoTexture::Pattern::kRings;
    else (*albedo)["pattern"].Fail("unknown pattern '" + pattern + "' (expected uniform, checker or rings)");
    scene.albedo.low = albedo->Double("low", scene.albedo.low);
    // high: [r, g, b] is a uniform sample's albedo per camera channel; a grey camera sees their mean.
    if (auto high = albedo->Find("high"); high && high->IsSequence()) {
      if (scene.albedo.pattern != sim::AlbedoTexture::Pattern::kUniform)
        high->Fail("an albedo per channel [r, g, b] needs pattern: uniform");
      const Eigen::Vector3d channels = high->AsVector3();
      if (!(channels.minCoeff() >= 0 && channels.maxCoeff() <= 1)) high->Fail("every channel's albedo must lie in [0, 1]");
      scene.albedo.high_channels = channels;
      scene.albedo.low = scene.albedo.high = channels.mean();
    } else {
      scene.albedo.high = albedo->Double("high", scene.albedo.high);
    }
    if (auto paints = albedo->Find("paints")) {
      const auto items = paints->Items();
      if (items.size() != 2) paints->Fail("needs two ColorChecker patch names: [low, high]");
      for (const YamlNode& item : items) {
        const std::string name = item.AsString();
        if (ColorCheckerPatch(name) < 0) item.Fail("unknown ColorChecker patch '" + name + "' (e.g. red, blue, green, yellow, white 9.5 (.05 D))");
        scene.albedo.paints.push_back(name);
      }
    }
    scene.albedo.period_mm = albedo->Double("period_mm", scene.albedo.period_mm);
    if (!(scene.albedo.low >= 0 && scene.albedo.high <= 1 && scene.albedo.low <= scene.albedo.high))
      albedo->Fail("albedo needs 0 <= low <= high <= 1");
    if (!(scene.albedo.period_mm > 0)) (*albedo)["period_mm"].Fail("must be > 0");
  }
  // brdf: {model: lambertian|blinn_phong|ggx|cook_torrance|mirror|tabulated, rho_s, exponent, roughness, f0, table,
  //        paint_rho_s: [low paint, high paint] (blinn_phong)}
  if (auto brdf = node.Find("brdf")) {
    brdf->ExpectKeys({"model", "rho_s", "exponent", "roughness", "f0", "table", "paint_rho_s"});
    sim::Material& m = scene.material;
    try {
      m.model = sim::Brdf::ParseModel((*brdf)["model"].AsString());
    } catch (const std::invalid_argument& e) {
      (*brdf)["model"].Fail(e.what());
    }
    // rho_s: [r, g, b] per camera channel (blinn_phong, cook_torrance); a grey camera sees their mean.
    if (auto rho_s = brdf->Find("rho_s"); rho_s && rho_s->IsSequence()) {
      m.rho_s_channels = rho_s->AsVector3();
      m.rho_s = m.rho_s_channels->mean();
    } else {
      m.rho_s = brdf->Double("rho_s", m.rho_s);
    }
    m.exponent = brdf->Double("exponent", m.exponent);
    m.roughness = brdf->Double("roughness", m.roughness);
    m.f0 = brdf->Double("f0", m.f0);
    if (auto paint_rho_s = brdf->Find("paint_rho_s"))
      for (const YamlNode& item : paint_rho_s->Items()) m.paint_rho_s.push_back(item.AsDouble());
    if (auto table = brdf->Find("table")) {
      if (m.model != sim::Brdf::Model::kTabulated) table->Fail("only the tabulated model reads a table");
      solvers::brdf::MeasuredBrdf measured;
      const solvers::core::Summary read = solvers::brdf::ReadMeasured(table->AsPath(), &measured);
      if (!read.IsSolutionUsable()) table->Fail(read.message);
      m.table = std::make_shared<const solvers::brdf::MeasuredBrdf>(std::move(measured));
    }
    std::string why;
    if (!m.IsValid(&why)) brdf->Fail(why);
  }
  std::string why;
  if (!scene.IsValid(&why)) node.Fail(why);
  return scene;
}

}  // namespace photorig::config
