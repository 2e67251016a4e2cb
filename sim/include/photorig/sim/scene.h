#pragma once
// Scenes the simulated rig can put under its camera, and the ground truth they
// imply. Units: millimetres in the object's frame, which coincides with the
// camera frame (x right, y up, z towards the camera).

#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace photorig::sim {

struct AlbedoTexture {
  enum class Pattern { kUniform, kChecker, kRings };
  Pattern pattern = Pattern::kChecker;
  double low = 0.35;       // albedo of the dark squares / rings
  double high = 0.85;      // albedo of the bright squares / rings (and of kUniform)
  double period_mm = 6.0;  // checker square size or ring spacing

  double At(double x_mm, double y_mm) const;
};

// A Gaussian bump (amplitude > 0) or dimple (amplitude < 0) on a flat base.
struct Bump {
  double x_mm = 0.0, y_mm = 0.0;
  double amplitude_mm = 1.0;
  double sigma_mm = 2.0;
};

struct Scene {
  enum class Shape { kSphere, kBumps };
  Shape shape = Shape::kSphere;
  double sphere_radius_mm = 18.0;  // kSphere: centred on the optical axis
  std::vector<Bump> bumps;         // kBumps: heightfield z = sum of bumps over the whole frame
  AlbedoTexture albedo;
  bool cast_shadows = true;        // kBumps only; a sphere has attached shadows only

  static Scene::Shape ParseShape(const std::string& name);  // throws std::invalid_argument
  static const char* ShapeName(Shape shape);
  // A fixed pattern of bumps and dimples sized to a frame of the given width.
  static std::vector<Bump> DefaultBumps(double frame_width_mm);
};

// Per-pixel geometry seen through an orthographic camera: both the ground truth
// written beside every capture and the input of the renderer.
struct SurfaceMaps {
  cv::Mat normals;  // CV_32FC3 (x, y, z); NaN off the object
  cv::Mat albedo;   // CV_32F; NaN off the object
  cv::Mat height;   // CV_32F z in mm; NaN off the object
  cv::Mat mask;     // CV_8U, 255 on the object
  double pixel_pitch_mm = 0.1;
};

// Samples the analytic surface at pixel centres (one sample per pixel, so the
// rendered radiance and the ground-truth normal describe the same point).
SurfaceMaps SampleSurface(const Scene& scene, int width, int height, double pixel_pitch_mm);

}  // namespace photorig::sim
