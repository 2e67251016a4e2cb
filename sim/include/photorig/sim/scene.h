#pragma once
// Scenes the simulated rig can put under its camera, and the ground truth they
// imply. Units: millimetres in the object's frame, which coincides with the
// camera frame (x right, y up, z towards the camera).

#include "photorig/sim/brdf.h"
#include "photorig/sim/camera_model.h"
#include "photorig/sim/mesh.h"
#include "photorig/sim/phantom.h"
#include "photorig/sim/volume.h"

#include <opencv2/core.hpp>

#include <Eigen/Core>

#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace photorig::sim {

// A scalar texture over the object's (x, y); used for the diffuse albedo.
struct AlbedoTexture {
  enum class Pattern { kUniform, kChecker, kRings };
  Pattern pattern = Pattern::kChecker;
  double low = 0.35;       // albedo of the dark squares / rings
  double high = 0.85;      // albedo of the bright squares / rings (and of kUniform)
  double period_mm = 6.0;  // checker square size or ring spacing
  // For a colour camera: the paints of the low and high squares / rings, by
  // ColorChecker patch name ("red", "blue", ...). The world's builder turns
  // them into camera responses (sim::ColorCamera) and sets low and high to
  // their luminance Y, which is what a monochrome camera sees.
  std::vector<std::string> paints;
  // A uniform texture's albedo per camera channel (R, G, B), for a colour
  // camera (sim::ColorCamera scales it by the channel's response to the
  // light); `high` holds their mean, what a grey camera sees. Unset: grey.
  std::optional<Eigen::Vector3d> high_channels;

  double At(double x_mm, double y_mm) const;
  // Which paint covers the point: 0 low, 1 high (the nearer, in rings).
  int PaintAt(double x_mm, double y_mm) const;

 private:
  double HighWeight(double x_mm, double y_mm) const;  // 0 = low, 1 = high
};

// The reflectance of the whole object: a model and its parameters. rho_d
// comes from the scene's albedo texture, so every model can be textured.
struct Material {
  Brdf::Model model = Brdf::Model::kLambertian;
  double rho_s = 0.1;       // blinn_phong specular weight; cook_torrance k_s; mirror reflectance
  double exponent = 50.0;   // blinn_phong
  double roughness = 0.3;   // ggx a, cook_torrance Beckmann m (width of the microfacet distribution)
  double f0 = 0.04;         // ggx and cook_torrance Fresnel at normal incidence
  // rho_s per camera channel (R, G, B) for a colour camera; rho_s holds
  // their mean, what a grey camera sees. Unset: one rho_s for all.
  std::optional<Eigen::Vector3d> rho_s_channels;
  std::shared_ptr<const solvers::brdf::MeasuredBrdf> table;  // tabulated (required for it)
  // blinn_phong: rho_s of the texture's low and high paint (AlbedoTexture::PaintAt)
  // in place of rho_s, so one paint can be matte (0) and the other glossy: an
  // object of two materials. Empty: rho_s everywhere.
  std::vector<double> paint_rho_s;

  bool IsValid(std::string* why) const;
  // `channel`: the table channel a colour camera's channel sees (0 R, 1 G,
  // 2 B), -1 for their mean; only the tabulated model has channels.
  std::unique_ptr<Brdf> MakeBrdf(int channel = -1) const;
  // BrdfParams::shininess: roughness for ggx and cook_torrance, else exponent.
  double LobeShape() const;
};

// A Gaussian bump (amplitude > 0) or dimple (amplitude < 0) on a flat base.
struct Bump {
  double x_mm = 0.0, y_mm = 0.0;
  double amplitude_mm = 1.0;
  double sigma_mm = 2.0;
};

struct Scene {
  enum class Shape {
    kSphere,        // sphere_radius_mm, centred on the optical axis (or at sphere_centres_mm)
    kBumps,         // heightfield: sum of `bumps`
    kConcave,       // heightfield: a spherical bowl of radius bowl_radius_mm cut to rim_radius_mm
    kSteps,         // heightfield: tilted terraces with a vertical drop between them
    kDepthMap,      // heightfield from a 16-bit PNG or float TIFF (depth_map_path)
    kMesh,          // PLY triangle mesh (mesh_path), rasterised orthographically
    kMirrorSphere,  // chrome sphere: a sphere with the mirror BRDF
    kWhiteSphere,   // diffuse white sphere: a sphere, Lambertian, uniform albedo
    kSamplePlane,   // flat material sample, disc of sphere_radius_mm, tilted by tilt_deg about y
    kVolume,        // absorbing medium in front of a backlight
    kPhantom,       // tomography phantom on a gonioreflectometer's turntable, backlit (sim/gonio.h)
  };
  Shape shape = Shape::kSphere;
  double sphere_radius_mm = 18.0;
  // Sphere shapes: one sphere per centre (x, y), each with its equator on the
  // sample plane z = 0, so several calibration balls share one frame; a pixel
  // sees the nearest. Empty: one sphere at the origin.
  std::vector<Eigen::Vector2d> sphere_centres_mm;
  std::vector<Bump> bumps;
  double bowl_radius_mm = 15.0, rim_radius_mm = 12.0;
  double step_width_mm = 8.0, step_height_mm = 2.0, step_slope = 0.15;  // slope: dz/dx of each tread
  std::string depth_map_path;
  double depth_scale_mm = 0.01;   // mm per stored unit (PNG) or per TIFF value
  double depth_pitch_mm = 0.0;    // size of a depth-map pixel; 0 = the camera's pixel pitch
  std::string mesh_path;
  double mesh_scale = 1.0;        // PLY units to mm
  double tilt_deg = 0.0;
  DensityGrid volume;
  Phantom phantom;                // kPhantom: the 3D Shepp-Logan head unless a recipe says otherwise
  double backlight_radiance = 1.0;
  AlbedoTexture albedo;
  Material material;
  bool cast_shadows = true;       // heightfields and meshes; a sphere has attached shadows only
  // > 0: add one bounce of inter-reflection with this many hemisphere samples
  // per pixel (orthographic views of heightfields; see RenderOneBounce).
  int interreflection_samples = 0;

  bool IsValid(std::string* why) const;
  bool IsHeightfield() const;     // cast shadows apply
  bool IsSphere() const { return shape == Shape::kSphere || shape == Shape::kMirrorSphere || shape == Shape::kWhiteSphere; }

  static Scene::Shape ParseShape(const std::string& name);  // throws std::invalid_argument
  static const char* ShapeName(Shape shape);
  // A fixed pattern of bumps and dimples sized to a frame of the given width.
  static std::vector<Bump> DefaultBumps(double frame_width_mm);
  // Fills the shape's parameters with defaults sized to the frame, and the
  // material the shape implies (mirror_sphere, white_sphere).
  void ApplyShapeDefaults(double frame_width_mm);
};

// Per-pixel geometry and reflectance parameters seen through the camera: both
// the ground truth written beside every capture and the input of the renderer.
struct SurfaceMaps {
  cv::Mat normals;      // CV_32FC3 (x, y, z); NaN off the object
  cv::Mat albedo;       // CV_32F diffuse albedo rho_d; NaN off the object
  cv::Mat height;       // CV_32F z of the surface point in mm; NaN off the object
  cv::Mat depth;        // CV_32F distance along the optical axis from the camera (pinhole), or -z (orthographic)
  cv::Mat position;     // CV_32FC3 surface point in mm
  cv::Mat view;         // CV_32FC3 unit direction towards the camera (w_o)
  cv::Mat brdf_params;  // CV_32FC4 (rho_d, rho_s, shininess, f0), see BrdfParams
  cv::Mat mask;         // CV_8U, 255 on the object
  // CV_8U which paint's material a pixel shows (0 low, 1 high; 255 off the
  // object), where the scene gives each paint its own lobe (Material::paint_rho_s);
  // empty otherwise (one material).
  cv::Mat material;
  cv::Mat line_integrals;  // CV_32F tau per pixel; volume scenes only
  double pixel_pitch_mm = 0.1;
  bool height_on_pixel_grid = true;  // orthographic: `height` is a regular heightfield grid
};

// Samples the surface at pixel centres (one sample per pixel, so the rendered
// radiance and the ground-truth normal describe the same point). Throws
// std::runtime_error when a depth map or mesh cannot be read.
SurfaceMaps SampleSurface(const Scene& scene, const CameraModel& camera);
// The orthographic form kept for callers that only know a pitch.
SurfaceMaps SampleSurface(const Scene& scene, int width, int height, double pixel_pitch_mm);

}  // namespace photorig::sim
