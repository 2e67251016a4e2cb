#include "photorig/sim/scene.h"

#include "photorig/solvers/codecs/image_codecs.h"
#include "photorig/solvers/core/image_file_format.h"


#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <vector>

namespace photorig::sim {
using solvers::core::Refuse;

namespace {

using Eigen::Vector3d;

// A surface z = h(x, y) with its gradient; false where it does not exist.
using HeightFunction = std::function<bool(double x, double y, double* z, double* dzdx, double* dzdy)>;

cv::Mat LoadDepthMap(const Scene& scene) {
  std::vector<std::uint8_t> bytes;
  std::string why;
  const cv::Mat raw = solvers::core::ReadImageFileBytes(scene.depth_map_path, &bytes, &why)
                          ? solvers::codecs::DecodeImage(bytes, solvers::codecs::ReadMode::kAsStored, &why)
                          : cv::Mat();
  if (raw.empty()) throw std::runtime_error("cannot read depth map '" + scene.depth_map_path + "' (" + why + ")");
  if (raw.channels() != 1 || (raw.depth() != CV_16U && raw.depth() != CV_32F))
    throw std::runtime_error("depth map '" + scene.depth_map_path +
                             "': expected a single-channel 16-bit PNG or float TIFF");
  cv::Mat depth;
  raw.convertTo(depth, CV_32F, scene.depth_scale_mm);
  // No data: 0 in a PNG (it has no NaN), NaN in a TIFF.
  if (raw.depth() == CV_16U) depth.setTo(std::numeric_limits<float>::quiet_NaN(), raw == 0);
  return depth;
}

HeightFunction MakeHeightFunction(const Scene& scene, double pitch_mm) {
  switch (scene.shape) {
    case Scene::Shape::kBumps:
      // z = sum a exp(-d^2 / 2 s^2).
      return [&scene](double x, double y, double* z, double* dzdx, double* dzdy) {
        *z = *dzdx = *dzdy = 0.0;
        for (const Bump& b : scene.bumps) {
          const double dx = x - b.x_mm, dy = y - b.y_mm, s2 = b.sigma_mm * b.sigma_mm;
          const double g = b.amplitude_mm * std::exp(-(dx * dx + dy * dy) / (2.0 * s2));
          *z += g;
          *dzdx -= g * dx / s2;
          *dzdy -= g * dy / s2;
        }
        return true;
      };
    case Scene::Shape::kConcave:
      // A bowl cut from a sphere of radius R so that its rim (radius a) lies at z = 0.
      return [R = scene.bowl_radius_mm, a = scene.rim_radius_mm](double x, double y, double* z, double* dzdx,
                                                                   double* dzdy) {
        const double r2 = x * x + y * y;
        *z = *dzdx = *dzdy = 0.0;
        if (r2 >= a * a) return true;
        const double s = std::sqrt(R * R - r2);
        *z = std::sqrt(R * R - a * a) - s;
        *dzdx = x / s;
        *dzdy = y / s;
        return true;
      };
    case Scene::Shape::kSteps:
      // Terraces of width w descending by h towards +x; tread k is tilted by
      // +-slope alternately, so the two sides of every edge differ in depth and normal.
      return [w = scene.step_width_mm, h = scene.step_height_mm, s = scene.step_slope](
                 double x, double, double* z, double* dzdx, double* dzdy) {
        const double u = x / w;
        const double k = std::floor(u);
        const double slope = (static_cast<long>(k) % 2 == 0) ? s : -s;
        *z = -k * h + slope * (u - k - 0.5) * w;
        *dzdx = slope;
        *dzdy = 0.0;
        return true;
      };
    case Scene::Shape::kSamplePlane: {
      const double t = scene.tilt_deg * M_PI / 180.0, radius = scene.sphere_radius_mm;
      return [t, radius](double x, double y, double* z, double* dzdx, double* dzdy) {
        const double u = x / std::cos(t);  // in-plane coordinate of the tilted disc
        if (u * u + y * y >= radius * radius) return false;
        *z = -x * std::tan(t);
        *dzdx = -std::tan(t);
        *dzdy = 0.0;
        return true;
      };
    }
    case Scene::Shape::kDepthMap: {
      auto depth = std::make_shared<cv::Mat>(LoadDepthMap(scene));
      const double d = scene.depth_pitch_mm > 0 ? scene.depth_pitch_mm : pitch_mm;
      // Bilinear between depth-map pixel centres; the map is centred on the origin.
      auto at = [depth, d](double x, double y, double* z) {
        const double fc = x / d + 0.5 * depth->cols - 0.5, fr = 0.5 * depth->rows - y / d - 0.5;
        const int c0 = static_cast<int>(std::floor(fc)), r0 = static_cast<int>(std::floor(fr));
        const double tc = fc - c0, tr = fr - r0;
        double sum = 0.0, weight = 0.0;
        for (int i = 0; i < 2; ++i)
          for (int j = 0; j < 2; ++j) {
            const int r = std::clamp(r0 + i, 0, depth->rows - 1), c = std::clamp(c0 + j, 0, depth->cols - 1);
            const double wgt = (i ? tr : 1 - tr) * (j ? tc : 1 - tc);
            const float v = depth->at<float>(r, c);
            if (wgt == 0.0) continue;
            if (!std::isfinite(v)) return false;
            sum += wgt * v;
            weight += wgt;
          }
        if (fc < -0.5 || fr < -0.5 || fc > depth->cols - 0.5 || fr > depth->rows - 0.5) return false;
        *z = sum / weight;
        return true;
      };
      // Central differences one depth-map pixel wide, one-sided at the edge of the data.
      return [at, d](double x, double y, double* z, double* dzdx, double* dzdy) {
        if (!at(x, y, z)) return false;
        auto slope = [&](double ex, double ey) {
          double plus = 0.0, minus = 0.0;
          const bool p = at(x + ex * d, y + ey * d, &plus), m = at(x - ex * d, y - ey * d, &minus);
          if (p && m) return (plus - minus) / (2 * d);
          if (p) return (plus - *z) / d;
          if (m) return (*z - minus) / d;
          return 0.0;
        };
        *dzdx = slope(1, 0);
        *dzdy = slope(0, 1);
        return true;
      };
    }
    default: return nullptr;
  }
}

// The first hit of a ray on a heightfield: exact under an orthographic camera,
// fixed-point iteration along the ray under a pinhole one (it converges where
// the surface slope times the ray's tilt is below 1; a ray grazing a step's
// riser does not converge and the pixel is left off the object).
bool IntersectHeightfield(const HeightFunction& h, const Vector3d& origin, const Vector3d& dir, Vector3d* point,
                          Vector3d* normal) {
  double z = 0.0, dzdx = 0.0, dzdy = 0.0;
  if (dir.x() == 0.0 && dir.y() == 0.0) {
    if (!h(origin.x(), origin.y(), &z, &dzdx, &dzdy)) return false;
    *point = {origin.x(), origin.y(), z};
  } else {
    bool converged = false;
    for (int i = 0; i < 60 && !converged; ++i) {
      const double t = (z - origin.z()) / dir.z();
      double next;
      if (!h(origin.x() + t * dir.x(), origin.y() + t * dir.y(), &next, &dzdx, &dzdy)) return false;
      converged = std::abs(next - z) < 1e-7;
      z = next;
    }
    if (!converged) return false;
    const double t = (z - origin.z()) / dir.z();
    *point = origin + t * dir;
  }
  *normal = Vector3d(-dzdx, -dzdy, 1.0).normalized();
  return true;
}

bool IntersectSphere(double radius, const Vector3d& origin, const Vector3d& dir, Vector3d* point, Vector3d* normal) {
  const double b = origin.dot(dir), c = origin.squaredNorm() - radius * radius;
  const double disc = b * b - c;
  if (disc <= 0.0) return false;
  *point = origin + (-b - std::sqrt(disc)) * dir;
  // Orthographic rays start far away: recompute z from (x, y) for full precision.
  const double d2 = point->x() * point->x() + point->y() * point->y();
  if (d2 >= radius * radius) return false;
  point->z() = std::sqrt(radius * radius - d2);
  *normal = *point / radius;
  return true;
}

// The first of the scene's spheres the ray meets. A single sphere at the
// origin is intersected as it always was, bit for bit.
bool IntersectNearestSphere(const Scene& scene, const Vector3d& origin, const Vector3d& dir, Vector3d* point,
                            Vector3d* normal) {
  if (scene.sphere_centres_mm.empty()) return IntersectSphere(scene.sphere_radius_mm, origin, dir, point, normal);
  bool hit = false;
  double nearest = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector2d& centre : scene.sphere_centres_mm) {
    const Vector3d c(centre.x(), centre.y(), 0.0);
    Vector3d p, n;
    if (!IntersectSphere(scene.sphere_radius_mm, origin - c, dir, &p, &n)) continue;
    p += c;
    const double along = (p - origin).dot(dir);
    if (along >= nearest) continue;
    nearest = along;
    *point = p;
    *normal = n;
    hit = true;
  }
  return hit;
}

}  // namespace

double AlbedoTexture::HighWeight(double x_mm, double y_mm) const {
  switch (pattern) {
    case Pattern::kUniform: return 1.0;
    case Pattern::kChecker: {
      const long cx = static_cast<long>(std::floor(x_mm / period_mm));
      const long cy = static_cast<long>(std::floor(y_mm / period_mm));
      return ((cx + cy) & 1) ? 0.0 : 1.0;
    }
    case Pattern::kRings: {
      // Smooth rings: albedo varies continuously, as a painted object would.
      const double r = std::hypot(x_mm, y_mm);
      return 0.5 * (1.0 + std::cos(2.0 * M_PI * r / period_mm));
    }
  }
  return 1.0;
}

double AlbedoTexture::At(double x_mm, double y_mm) const {
  const double w = HighWeight(x_mm, y_mm);
  return w == 1.0 ? high : w == 0.0 ? low : low + (high - low) * w;
}

int AlbedoTexture::PaintAt(double x_mm, double y_mm) const { return HighWeight(x_mm, y_mm) < 0.5 ? 0 : 1; }

bool Material::IsValid(std::string* why) const {
  if (!paint_rho_s.empty()) {
    if (model != Brdf::Model::kBlinnPhong) return Refuse(why, "paint_rho_s needs the blinn_phong model");
    if (paint_rho_s.size() != 2) return Refuse(why, "paint_rho_s needs two values: [low paint, high paint]");
    if (!(paint_rho_s[0] >= 0 && paint_rho_s[1] >= 0)) return Refuse(why, "paint_rho_s must be >= 0");
  }
  if (rho_s_channels) {
    if (model != Brdf::Model::kBlinnPhong && model != Brdf::Model::kCookTorrance)
      return Refuse(why, "rho_s per channel needs the blinn_phong or cook_torrance model");
    if (!paint_rho_s.empty()) return Refuse(why, "rho_s per channel and paint_rho_s exclude each other");
    if (!(rho_s_channels->minCoeff() >= 0)) return Refuse(why, "rho_s must be >= 0 in every channel");
  }
  switch (model) {
    case Brdf::Model::kBlinnPhong:
      if (!(rho_s >= 0)) return Refuse(why, "rho_s must be >= 0");
      if (!(exponent >= 0)) return Refuse(why, "exponent must be >= 0");
      break;
    case Brdf::Model::kTabulated:
      if (!table || !*table) return Refuse(why, "the tabulated model needs a table: a MERL .binary or EPFL RGL .bsdf file");
      break;
    case Brdf::Model::kGgx:
      if (!(roughness > 0 && roughness <= 1)) return Refuse(why, "roughness must lie in (0, 1]");
      if (!(f0 >= 0 && f0 < 1)) return Refuse(why, "f0 must lie in [0, 1)");
      break;
    case Brdf::Model::kCookTorrance:
      if (!(rho_s >= 0)) return Refuse(why, "rho_s must be >= 0");
      if (!(roughness > 0 && roughness <= 1)) return Refuse(why, "roughness (Beckmann m) must lie in (0, 1]");
      if (!(f0 >= 0 && f0 <= 1)) return Refuse(why, "f0 must lie in [0, 1]");
      break;
    case Brdf::Model::kMirror:
      if (!(rho_s >= 0 && rho_s <= 1)) return Refuse(why, "mirror reflectance rho_s must lie in [0, 1]");
      break;
    case Brdf::Model::kLambertian: break;
  }
  return true;
}

std::unique_ptr<Brdf> Material::MakeBrdf(int channel) const {
  if (model != Brdf::Model::kTabulated) return sim::MakeBrdf(model);
  return sim::MakeBrdf(model, table, channel);
}

double Material::LobeShape() const {
  return model == Brdf::Model::kGgx || model == Brdf::Model::kCookTorrance ? roughness : exponent;
}

bool Scene::IsHeightfield() const {
  switch (shape) {
    case Shape::kBumps:
    case Shape::kConcave:
    case Shape::kSteps:
    case Shape::kDepthMap:
    case Shape::kMesh:
    case Shape::kSamplePlane: return true;
    default: return false;
  }
}

bool Scene::IsValid(std::string* why) const {
  if (!material.IsValid(why)) return false;
  if (!(albedo.low >= 0 && albedo.high <= 1 && albedo.low <= albedo.high))
    return Refuse(why, "albedo needs 0 <= low <= high <= 1");
  if (albedo.high_channels) {
    if (albedo.pattern != AlbedoTexture::Pattern::kUniform) return Refuse(why, "an albedo per channel needs the uniform pattern");
    if (!(albedo.high_channels->minCoeff() >= 0 && albedo.high_channels->maxCoeff() <= 1))
      return Refuse(why, "albedo needs 0 <= high <= 1 in every channel");
  }
  // Blinn-Phong's (e + 2) / (2 pi) lobe reflects up to 4 rho_s at normal view
  // (the half-vector Jacobian); this keeps the white furnace test true.
  if (material.model == Brdf::Model::kBlinnPhong) {
    const bool per_paint = !material.paint_rho_s.empty();
    const double low = albedo.low + 4.0 * (per_paint ? material.paint_rho_s[0] : material.rho_s);
    const double high = albedo.high + 4.0 * (per_paint ? material.paint_rho_s[1] : material.rho_s);
    if (std::max(low, high) > 1.0 + 1e-9) return Refuse(why, "blinn_phong conserves energy only if albedo + 4 rho_s <= 1");
  }
  if (IsSphere() && !(sphere_radius_mm > 0)) return Refuse(why, "radius_mm must be > 0");
  if (!sphere_centres_mm.empty() && !IsSphere()) return Refuse(why, "centres_mm places spheres: only sphere shapes take it");
  for (std::size_t i = 0; i < sphere_centres_mm.size(); ++i) {
    if (!sphere_centres_mm[i].allFinite()) return Refuse(why, "centres_mm must be finite");
    for (std::size_t j = 0; j < i; ++j)
      if ((sphere_centres_mm[i] - sphere_centres_mm[j]).norm() < 2.0 * sphere_radius_mm)
        return Refuse(why, "centres_mm: spheres " + std::to_string(j) + " and " + std::to_string(i) +
                           " overlap (centres closer than two radii)");
  }
  if (shape == Shape::kMirrorSphere && material.model != Brdf::Model::kMirror)
    return Refuse(why, "a mirror_sphere has the mirror BRDF");
  if (shape == Shape::kWhiteSphere && material.model != Brdf::Model::kLambertian)
    return Refuse(why, "a white_sphere is Lambertian");
  if (shape == Shape::kConcave && !(rim_radius_mm > 0 && bowl_radius_mm >= rim_radius_mm))
    return Refuse(why, "a bowl needs 0 < rim_radius_mm <= bowl_radius_mm");
  if (shape == Shape::kSteps && !(step_width_mm > 0 && step_height_mm >= 0))
    return Refuse(why, "steps need step_width_mm > 0 and step_height_mm >= 0");
  if (shape == Shape::kSamplePlane && !(std::abs(tilt_deg) < 89.0)) return Refuse(why, "tilt_deg must lie in (-89, 89)");
  if (shape == Shape::kDepthMap && depth_map_path.empty()) return Refuse(why, "a depth_map scene needs a path");
  if (shape == Shape::kMesh && mesh_path.empty()) return Refuse(why, "a mesh scene needs a path");
  if (shape == Shape::kMesh && !(mesh_scale > 0)) return Refuse(why, "mesh_scale must be > 0");
  if (shape == Shape::kVolume && !volume.IsValid(why)) return false;
  if ((shape == Shape::kVolume || shape == Shape::kPhantom) && !(backlight_radiance > 0))
    return Refuse(why, "backlight_radiance must be > 0");
  if (shape == Shape::kPhantom && (phantom.ellipsoids.empty() || !(phantom.half_extent_mm > 0) || !(phantom.sigma_per_mm >= 0)))
    return Refuse(why, "a phantom needs ellipsoids, half_extent_mm > 0 and sigma_per_mm >= 0");
  return true;
}

namespace {
constexpr Scene::Shape kAllShapes[] = {
    Scene::Shape::kSphere,       Scene::Shape::kBumps,       Scene::Shape::kConcave,
    Scene::Shape::kSteps,        Scene::Shape::kDepthMap,    Scene::Shape::kMesh,
    Scene::Shape::kMirrorSphere, Scene::Shape::kWhiteSphere, Scene::Shape::kSamplePlane,
    Scene::Shape::kVolume,       Scene::Shape::kPhantom};
}  // namespace

Scene::Shape Scene::ParseShape(const std::string& name) {
  for (Shape shape : kAllShapes)
    if (name == ShapeName(shape)) return shape;
  throw std::invalid_argument("unknown shape '" + name +
                              "' (expected sphere, bumps, concave, steps, depth_map, mesh, mirror_sphere, "
                              "white_sphere, sample_plane, volume or phantom)");
}

const char* Scene::ShapeName(Shape shape) {
  switch (shape) {
    case Shape::kSphere: return "sphere";
    case Shape::kBumps: return "bumps";
    case Shape::kConcave: return "concave";
    case Shape::kSteps: return "steps";
    case Shape::kDepthMap: return "depth_map";
    case Shape::kMesh: return "mesh";
    case Shape::kMirrorSphere: return "mirror_sphere";
    case Shape::kWhiteSphere: return "white_sphere";
    case Shape::kSamplePlane: return "sample_plane";
    case Shape::kVolume: return "volume";
    case Shape::kPhantom: return "phantom";
  }
  return "?";
}

std::vector<Bump> Scene::DefaultBumps(double frame_width_mm) {
  // A 3 x 3 grid alternating bumps and dimples, steep enough to cast shadows
  // under lights below about 45 degrees elevation.
  std::vector<Bump> bumps;
  const double spacing = frame_width_mm / 3.0;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      Bump bump;
      bump.x_mm = (i - 1) * spacing;
      bump.y_mm = (j - 1) * spacing;
      bump.sigma_mm = spacing * (0.14 + 0.03 * ((i + 2 * j) % 3));
      bump.amplitude_mm = ((i + j) % 2 == 0 ? 1.0 : -0.7) * 1.6 * bump.sigma_mm;
      bumps.push_back(bump);
    }
  }
  return bumps;
}

void Scene::ApplyShapeDefaults(double frame_width_mm) {
  sphere_radius_mm = 0.45 * frame_width_mm;
  bumps = shape == Shape::kBumps ? DefaultBumps(frame_width_mm) : std::vector<Bump>{};
  rim_radius_mm = 0.3 * frame_width_mm;
  bowl_radius_mm = 0.4 * frame_width_mm;
  step_width_mm = frame_width_mm / 5.0;
  step_height_mm = 0.05 * frame_width_mm;
  if (shape == Shape::kVolume) volume = DensityGrid::Blobs(0.8 * frame_width_mm, 64, 0.2);
  // Inside the field of view whatever the turntable's angle, sigma up to 0.1/mm.
  if (shape == Shape::kPhantom) phantom = Phantom::SheppLogan3d(0.4 * frame_width_mm, 0.1);
  if (shape == Shape::kMirrorSphere) {
    material.model = Brdf::Model::kMirror;
    material.rho_s = 0.9;
  }
  if (shape == Shape::kWhiteSphere) {
    material.model = Brdf::Model::kLambertian;
    albedo.pattern = AlbedoTexture::Pattern::kUniform;
    albedo.high = 0.99;
  }
}

SurfaceMaps SampleSurface(const Scene& scene, int width, int height, double pixel_pitch_mm) {
  CameraModel camera;
  camera.width = width;
  camera.height = height;
  camera.pixel_pitch_mm = pixel_pitch_mm;
  return SampleSurface(scene, camera);
}

SurfaceMaps SampleSurface(const Scene& scene, const CameraModel& camera) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const int width = camera.width, height = camera.height;
  SurfaceMaps maps;
  maps.pixel_pitch_mm = camera.pixel_pitch_mm;
  maps.height_on_pixel_grid = camera.projection == CameraModel::Projection::kOrthographic;
  maps.normals.create(height, width, CV_32FC3);
  maps.normals.setTo(cv::Scalar::all(nan));
  maps.position.create(height, width, CV_32FC3);
  maps.position.setTo(cv::Scalar::all(nan));
  maps.view.create(height, width, CV_32FC3);
  maps.view.setTo(cv::Scalar::all(nan));
  maps.brdf_params.create(height, width, CV_32FC4);
  maps.brdf_params.setTo(cv::Scalar::all(nan));
  maps.albedo.create(height, width, CV_32F);
  maps.albedo.setTo(nan);
  maps.height.create(height, width, CV_32F);
  maps.height.setTo(nan);
  maps.depth.create(height, width, CV_32F);
  maps.depth.setTo(nan);
  maps.mask = cv::Mat::zeros(height, width, CV_8U);
  if (!scene.material.paint_rho_s.empty()) maps.material = cv::Mat(height, width, CV_8U, cv::Scalar(255));

  if (scene.shape == Scene::Shape::kVolume) {
    maps.line_integrals = LineIntegrals(scene.volume, camera);
    return maps;
  }
  // No surface: what the camera sees depends on the turntable (RenderPhantomTransmission).
  if (scene.shape == Scene::Shape::kPhantom) return maps;
  cv::Mat mesh_height, mesh_normals;
  if (scene.shape == Scene::Shape::kMesh) {
    TriangleMesh mesh = LoadPly(scene.mesh_path);
    for (auto& v : mesh.vertices) v *= scene.mesh_scale;
    RasterizeOrthographic(mesh, camera, &mesh_height, &mesh_normals);
  }
  const HeightFunction heightfield = MakeHeightFunction(scene, camera.pixel_pitch_mm);
  const Material& m = scene.material;
  const float shininess = static_cast<float>(m.LobeShape());

#pragma omp parallel for schedule(dynamic, 16)
  for (int r = 0; r < height; ++r) {
    for (int c = 0; c < width; ++c) {
      Vector3d origin, dir, p, n;
      camera.Ray(c, r, &origin, &dir);
      bool hit;
      if (scene.IsSphere()) {
        hit = IntersectNearestSphere(scene, origin, dir, &p, &n);
      } else if (scene.shape == Scene::Shape::kMesh) {
        const float z = mesh_height.at<float>(r, c);
        hit = std::isfinite(z);
        if (hit) {
          p = {origin.x(), origin.y(), z};
          const cv::Vec3f& mn = mesh_normals.at<cv::Vec3f>(r, c);
          n = {mn[0], mn[1], mn[2]};
        }
      } else {
        hit = IntersectHeightfield(heightfield, origin, dir, &p, &n);
      }
      if (!hit) continue;
      const Vector3d wo = camera.ViewDirection(p);
      // A table carries its own diffuse part: the texture does not apply.
      const float rho_d = static_cast<float>(m.model == Brdf::Model::kTabulated ? scene.albedo.high
                                                                                 : scene.albedo.At(p.x(), p.y()));
      maps.normals.at<cv::Vec3f>(r, c) = cv::Vec3f(float(n.x()), float(n.y()), float(n.z()));
      maps.position.at<cv::Vec3f>(r, c) = cv::Vec3f(float(p.x()), float(p.y()), float(p.z()));
      maps.view.at<cv::Vec3f>(r, c) = cv::Vec3f(float(wo.x()), float(wo.y()), float(wo.z()));
      const int paint = scene.albedo.PaintAt(p.x(), p.y());
      const double rho_s = m.paint_rho_s.empty() ? m.rho_s : m.paint_rho_s[paint];
      if (!maps.material.empty()) maps.material.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(paint);
      maps.brdf_params.at<cv::Vec4f>(r, c) = cv::Vec4f(rho_d, float(rho_s), shininess, float(m.f0));
      maps.albedo.at<float>(r, c) = rho_d;
      maps.height.at<float>(r, c) = static_cast<float>(p.z());
      maps.depth.at<float>(r, c) = static_cast<float>(
          camera.projection == CameraModel::Projection::kPinhole ? camera.distance_mm - p.z() : -p.z());
      maps.mask.at<std::uint8_t>(r, c) = 255;
    }
  }
  return maps;
}

}  // namespace photorig::sim
