#pragma once
// 8-bit views of a photometric-stereo result for people. Each scalar view is
// mapped from its own data's range over the solved pixels (a 16-bit albedo of
// 27,000 DN and a 0..1 confidence both fill 0..255), categorical maps get a
// palette and a legend, and every mapping is returned as JSON (report.json
// "previews") so a person or a test can read a value back from a grey level:
//   normals.png     RGB = (n + 1) / 2 * 255
//   albedo.png      0 .. the 99.5th percentile over the solved pixels -> 0 .. 255 (brighter clips at 255)
//   depth.png       min .. max over the solved pixels -> 0 .. 255 (nearer is brighter)
//   confidence.png  min .. max over the solved pixels -> 0 .. 255
//   flags.png, model.png   colour, one palette colour per code, the legend drawn to the right of the map
//   mask.png        255 where a normal was solved
// Unsolved pixels are 0 (black) in every view.

#include "photorig/solvers/ps/stack.h"

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace photorig::daemon {

// The percentile of the albedo that maps to 255: high enough that only
// specular speckles clip, low enough that they do not darken the rest.
inline constexpr double kAlbedoPreviewPercentile = 99.5;

// The value below which `percent` % of the finite values under `mask` lie:
// sorted values v_0 <= ... <= v_{n-1}, v_floor(percent / 100 * (n - 1)).
// 0 when there is none.
double PercentileOverMask(const cv::Mat& values, const cv::Mat& mask, double percent);

// low .. high -> 0 .. 255, clipped; 0 outside `mask` and for non-finite
// values. A flat range (high <= low) maps every masked pixel to 255.
cv::Mat ToneMap(const cv::Mat& values, const cv::Mat& mask, double low, double high);

struct Category {
  int code;
  std::string name;
  cv::Vec3b rgb;
};
// The flags' and models' palettes (PixelFlag, PixelModel codes with their names).
const std::vector<Category>& FlagCategories();
const std::vector<Category>& ModelCategories();
// The reflectance fit's flags (solvers/reflectance PixelFlag): results/svbrdf/flags.png.
const std::vector<Category>& ReflectanceFlagCategories();

// A colour image: the map's pixels in columns 0 .. codes.cols - 1 (rows
// 0 .. codes.rows - 1), each its category's colour (codes not listed: white);
// to its right a legend panel with a swatch and the name of every category.
cv::Mat CategoricalPreview(const cv::Mat& codes, const std::vector<Category>& categories);
// How to read a CategoricalPreview back (report.json "previews"): "legend"
// (code, name, RGB of each category), "map_size" and "legend_x".
nlohmann::json LegendJson(const std::vector<Category>& categories, const cv::Mat& codes);
// The codes of a CategoricalPreview (as read, BGR) over its map's `size`;
// a colour of no category reads as 255.
cv::Mat CodesFromPreview(const cv::Mat& preview, cv::Size size, const std::vector<Category>& categories);

// Writes every view above into `directory` (depth.png only when `depth` is
// not empty) and returns {file name: its mapping}.
nlohmann::json WritePhotometricStereoPreviews(const solvers::ps::NormalMap& map, const cv::Mat& solved, const cv::Mat& depth,
                                              const std::string& directory);

}  // namespace photorig::daemon
