#include "photorig/daemon/io/internal/previews.h"

#include "photorig/daemon/io/image_io.h"
#include "photorig/solvers/core/number_text.h"
#include "photorig/solvers/reflectance/fit.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <stdexcept>

namespace photorig::daemon {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string Number(double value) { return solvers::core::NumberText(value, 6); }

std::vector<Category> Named(const std::vector<std::pair<int, cv::Vec3b>>& colours, const char* (*name)(int)) {
  std::vector<Category> categories;
  for (const auto& [code, rgb] : colours) categories.push_back({code, name(code), rgb});
  return categories;
}

// Min and max of the finite values under the mask; {0, 0} when there is none.
std::pair<double, double> RangeOverMask(const cv::Mat& values, const cv::Mat& mask) {
  const cv::Mat finite = mask & (values == values);
  if (cv::countNonZero(finite) == 0) return {0.0, 0.0};
  double low = 0.0, high = 0.0;
  cv::minMaxLoc(values, &low, &high, nullptr, nullptr, finite);
  return {low, high};
}

json ScalarMapping(const std::string& unit_range, double low, double high) {
  return {{"low", low}, {"high", high}, {"scale", unit_range + " -> 0..255"}, {"unsolved", 0}};
}

}  // namespace

json LegendJson(const std::vector<Category>& categories, const cv::Mat& codes) {
  json legend = json::array();
  for (const Category& c : categories)
    legend.push_back({{"code", c.code}, {"name", c.name}, {"rgb", {c.rgb[0], c.rgb[1], c.rgb[2]}}});
  return {{"legend", legend}, {"map_size", {codes.cols, codes.rows}}, {"legend_x", codes.cols}};
}

cv::Mat CodesFromPreview(const cv::Mat& preview, cv::Size size, const std::vector<Category>& categories) {
  if (preview.type() != CV_8UC3 || preview.cols < size.width || preview.rows < size.height)
    throw std::runtime_error("not a categorical preview of a " + std::to_string(size.width) + " x " +
                             std::to_string(size.height) + " map");
  cv::Mat codes(size, CV_8U, cv::Scalar(255));
  for (int r = 0; r < size.height; ++r)
    for (int c = 0; c < size.width; ++c) {
      const cv::Vec3b bgr = preview.at<cv::Vec3b>(r, c);
      for (const Category& category : categories)
        if (bgr == cv::Vec3b(category.rgb[2], category.rgb[1], category.rgb[0])) {
          codes.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(category.code);
          break;
        }
    }
  return codes;
}

double PercentileOverMask(const cv::Mat& values, const cv::Mat& mask, double percent) {
  std::vector<float> selected;
  for (int r = 0; r < values.rows; ++r)
    for (int c = 0; c < values.cols; ++c) {
      const float v = values.at<float>(r, c);
      if (mask.at<std::uint8_t>(r, c) && std::isfinite(v)) selected.push_back(v);
    }
  if (selected.empty()) return 0.0;
  const auto at = selected.begin() + static_cast<std::ptrdiff_t>(percent / 100.0 * (selected.size() - 1));
  std::nth_element(selected.begin(), at, selected.end());
  return *at;
}

cv::Mat ToneMap(const cv::Mat& values, const cv::Mat& mask, double low, double high) {
  cv::Mat out = cv::Mat::zeros(values.size(), CV_8U);
  const double scale = high > low ? 255.0 / (high - low) : 0.0;
  for (int r = 0; r < values.rows; ++r)
    for (int c = 0; c < values.cols; ++c) {
      const float v = values.at<float>(r, c);
      if (!mask.at<std::uint8_t>(r, c) || !std::isfinite(v)) continue;
      out.at<std::uint8_t>(r, c) = high > low ? cv::saturate_cast<std::uint8_t>((v - low) * scale) : 255;
    }
  return out;
}

const std::vector<Category>& FlagCategories() {
  static const std::vector<Category> categories = Named(
      {{int(solvers::ps::PixelFlag::kSolved), {46, 139, 87}},
       {int(solvers::ps::PixelFlag::kOutsideMask), {0, 0, 0}},
       {int(solvers::ps::PixelFlag::kTooFewLights), {255, 165, 0}},
       {int(solvers::ps::PixelFlag::kIllConditioned), {186, 85, 211}},
       {int(solvers::ps::PixelFlag::kRejectedByModel), {220, 20, 60}},
       {int(solvers::ps::PixelFlag::kFilled), {135, 206, 235}}},
      [](int code) { return solvers::ps::PixelFlagName(static_cast<solvers::ps::PixelFlag>(code)); });
  return categories;
}

const std::vector<Category>& ModelCategories() {
  static const std::vector<Category> categories = Named(
      {{int(solvers::ps::PixelModel::kNone), {0, 0, 0}},
       {int(solvers::ps::PixelModel::kLambertian), {65, 105, 225}},
       {int(solvers::ps::PixelModel::kTrimmed), {0, 206, 209}},
       {int(solvers::ps::PixelModel::kBlinnPhong), {255, 215, 0}},
       {int(solvers::ps::PixelModel::kIrls), {199, 21, 133}},
       {int(solvers::ps::PixelModel::kGgx), {255, 127, 80}},
       {int(solvers::ps::PixelModel::kLowFrequency), {154, 205, 50}}},
      [](int code) { return solvers::ps::PixelModelName(static_cast<solvers::ps::PixelModel>(code)); });
  return categories;
}

const std::vector<Category>& ReflectanceFlagCategories() {
  namespace refl = solvers::reflectance;
  static const std::vector<Category> categories = Named(
      {{int(refl::PixelFlag::kFitted), {46, 139, 87}},
       {int(refl::PixelFlag::kOutsideMask), {0, 0, 0}},
       {int(refl::PixelFlag::kNoNormal), {186, 85, 211}},
       {int(refl::PixelFlag::kTooFewSamples), {255, 165, 0}},
       {int(refl::PixelFlag::kPoorFit), {220, 20, 60}},
       {int(refl::PixelFlag::kMixed), {30, 144, 255}}},
      [](int code) { return refl::PixelFlagName(static_cast<refl::PixelFlag>(code)); });
  return categories;
}

cv::Mat CategoricalPreview(const cv::Mat& codes, const std::vector<Category>& categories) {
  constexpr int kRow = 16, kSwatch = 12, kMargin = 6;
  constexpr double kFontScale = 0.4;
  int text_width = 0;
  for (const Category& c : categories) {
    int baseline = 0;
    text_width = std::max(text_width, cv::getTextSize(c.name, cv::FONT_HERSHEY_SIMPLEX, kFontScale, 1, &baseline).width);
  }
  const int panel_width = 3 * kMargin + kSwatch + text_width;
  const int height = std::max(codes.rows, 2 * kMargin + kRow * static_cast<int>(categories.size()));
  const cv::Scalar panel(48, 48, 48);
  cv::Mat out(height, codes.cols + panel_width, CV_8UC3, panel);

  std::array<cv::Vec3b, 256> lookup;
  lookup.fill(cv::Vec3b(255, 255, 255));
  for (const Category& c : categories) lookup[c.code & 0xff] = cv::Vec3b(c.rgb[2], c.rgb[1], c.rgb[0]);  // BGR
  for (int r = 0; r < codes.rows; ++r)
    for (int c = 0; c < codes.cols; ++c) out.at<cv::Vec3b>(r, c) = lookup[codes.at<std::uint8_t>(r, c)];

  for (std::size_t k = 0; k < categories.size(); ++k) {
    const Category& c = categories[k];
    const int top = kMargin + kRow * static_cast<int>(k);
    const cv::Point swatch(codes.cols + kMargin, top);
    // A grey outline keeps a black swatch visible on the dark panel.
    cv::rectangle(out, cv::Rect(swatch.x - 1, swatch.y - 1, kSwatch + 2, kSwatch + 2), cv::Scalar(160, 160, 160));
    cv::rectangle(out, cv::Rect(swatch.x, swatch.y, kSwatch, kSwatch), cv::Scalar(c.rgb[2], c.rgb[1], c.rgb[0]),
                  cv::FILLED);
    cv::putText(out, c.name, cv::Point(swatch.x + kSwatch + kMargin, top + kSwatch - 1), cv::FONT_HERSHEY_SIMPLEX,
                kFontScale, cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  }
  return out;
}

json WritePhotometricStereoPreviews(const solvers::ps::NormalMap& map, const cv::Mat& solved, const cv::Mat& depth,
                                    const std::string& directory) {
  const fs::path out(directory);
  json previews;
  WriteImage((out / "normals.png").string(), NormalsToBgr8(map.normals));
  previews["normals.png"] = {{"scale", "RGB = (n + 1) / 2 * 255, n = (x, y, z)"}, {"unsolved", 0}};

  const double albedo_top = PercentileOverMask(map.albedo, solved, kAlbedoPreviewPercentile);
  WriteImage((out / "albedo.png").string(), ToneMap(map.albedo, solved, 0.0, albedo_top));
  previews["albedo.png"] = ScalarMapping("0.." + Number(albedo_top), 0.0, albedo_top);
  previews["albedo.png"]["percentile"] = kAlbedoPreviewPercentile;

  if (!depth.empty()) {
    const auto [low, high] = RangeOverMask(depth, solved);
    WriteImage((out / "depth.png").string(), ToneMap(depth, solved, low, high));
    previews["depth.png"] = ScalarMapping(Number(low) + ".." + Number(high), low, high);
  }
  const auto [low, high] = RangeOverMask(map.confidence, solved);
  WriteImage((out / "confidence.png").string(), ToneMap(map.confidence, solved, low, high));
  previews["confidence.png"] = ScalarMapping(Number(low) + ".." + Number(high), low, high);

  WriteImage((out / "mask.png").string(), solved);
  previews["mask.png"] = {{"scale", "255 where a normal was solved, else 0"}};
  WriteImage((out / "flags.png").string(), CategoricalPreview(map.flags, FlagCategories()));
  previews["flags.png"] = LegendJson(FlagCategories(), map.flags);
  WriteImage((out / "model.png").string(), CategoricalPreview(map.model, ModelCategories()));
  previews["model.png"] = LegendJson(ModelCategories(), map.model);
  return previews;
}

}  // namespace photorig::daemon
