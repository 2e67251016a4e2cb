#pragma once
// Input and output types shared by the photometric-stereo solvers.
//
// Conventions (as in DiLiGenT): camera coordinates with x to the right, y up,
// z towards the camera. Image row 0 is the top of the picture, so y grows as
// the row index falls.

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace photorig::solvers::ps {

// Noise of one sample in input units: variance = read_sigma^2 + shot_gain * (I - D).
// For a linear camera, shot_gain = 1 / (electrons per DN) and read_sigma is the
// dark-frame noise (including that of the subtracted dark). Zero means unknown
// or noise-free; methods that test residuals against the noise then fall back
// to the residuals themselves.
struct NoiseModel {
  double read_sigma = 0.0;
  double shot_gain = 0.0;
  double Variance(double signal) const { return read_sigma * read_sigma + shot_gain * (signal > 0.0 ? signal : 0.0); }
  bool IsKnown() const { return read_sigma > 0.0 || shot_gain > 0.0; }
};

// One frame per light. Values are linear sensor values (e.g. DN); the solver
// subtracts `dark` and divides by `light_scales`, so callers never pre-process
// the frames (which would cost one more pass over the whole stack).
struct PhotometricStack {
  std::vector<cv::Mat> images;                    // K frames, CV_32F, continuous, same size
  cv::Mat dark;                                   // optional CV_32F, subtracted from every frame
  std::vector<Eigen::Vector3d> light_directions;  // K unit vectors towards the lights
  // Per frame: sensor reading per unit radiance times the light's irradiance
  // at the sample. Then b = (I - D) / s = rho / pi * (n . w) and albedo =
  // pi * |x| as in the derivation; with 1.0 everywhere the albedo is relative.
  std::vector<double> light_scales;
  cv::Mat mask;  // optional CV_8U; zero = do not solve
  NoiseModel noise;
  // Unit vector towards the camera in the frame of the light directions, the
  // same for every pixel (an orthographic camera): (0, 0, 1) in camera
  // coordinates, another where the lights are given in a frame the camera is
  // tilted in. The Blinn-Phong fits take their half vectors from it.
  Eigen::Vector3d view_direction{0.0, 0.0, 1.0};

  int width() const { return images.empty() ? 0 : images.front().cols; }
  int height() const { return images.empty() ? 0 : images.front().rows; }
  int light_count() const { return static_cast<int>(images.size()); }

  // Shapes, types and counts agree; directions are unit length; scales > 0.
  bool IsValid(std::string* why) const;
};

// Why a pixel has (or has no) normal. Stored per pixel in NormalMap::flags.
enum class PixelFlag : std::uint8_t {
  kSolved = 0,
  kOutsideMask = 1,     // masked out by the caller
  kTooFewLights = 2,    // fewer than 3 usable (unshadowed, unsaturated) samples
  kIllConditioned = 3,  // the usable lights are (nearly) coplanar
  kRejectedByModel = 4,  // a solver judged its own estimate untrustworthy
  // One of the three above, whose normal was then interpolated from its
  // solved neighbours (FillUnresolvedNormals): a prior, not a measurement.
  kFilled = 5
};
// Whether a pixel with this flag carries a normal (solved or filled).
inline bool HasNormal(PixelFlag flag) { return flag == PixelFlag::kSolved || flag == PixelFlag::kFilled; }
const char* PixelFlagName(PixelFlag flag);

// The reflectance model a pixel was explained with (NormalMap::model).
enum class PixelModel : std::uint8_t {
  kNone = 0,        // no normal (see flags)
  kLambertian = 1,  // least squares on the unshadowed, unsaturated samples
  kTrimmed = 2,     // Lambertian with its worst samples left out (`auto`'s trimming)
  kBlinnPhong = 3,  // diffuse + normalised Blinn-Phong lobe
  kIrls = 4,        // Lambertian with outlying samples down-weighted (IRLS, the `robust` method)
  kGgx = 5,         // diffuse + GGX lobe (`auto`'s step 6, where the lobe is not Blinn-Phong)
  kLowFrequency = 6  // a reflectance with no lobe shape (`auto`'s step 7, where no model above explains the pixel)
};
const char* PixelModelName(PixelModel model);

struct NormalMap {
  cv::Mat normals;        // CV_32FC3 (x, y, z); NaN where !HasNormal(flags)
  cv::Mat albedo;         // CV_32F diffuse albedo; NaN where flags != kSolved
  cv::Mat flags;          // CV_8U PixelFlag
  cv::Mat usable_lights;  // CV_16U count of samples that entered the fit
  cv::Mat model;          // CV_8U PixelModel
  // CV_32F in [0, 1]: how well the chosen model explains the pixel, from the
  // ratio of its residual variance to the noise variance (1 = at the noise
  // level, 0.5 = twice the noise variance); 0 where unsolved, and where the
  // fit is exactly determined (3 usable samples for a Lambertian normal), so
  // that no residual tests it.
  cv::Mat confidence;
  cv::Mat specular;       // CV_32FC2 (rho_s, exponent) where model == kBlinnPhong, (rho_s, roughness) where kGgx,
                          // (pi (a1 + a2), 0) where kLowFrequency (its rise towards the mirror direction), else 0
};

}  // namespace photorig::solvers::ps
