#include "photorig/daemon/pipelines/color_stack.h"

#include "photorig/daemon/io/image_io.h"

#include "photorig/solvers/color/apply.h"
#include "photorig/solvers/color/region_demosaic.h"
#include "photorig/config/rig.h"
#include "photorig/config/sim.h"
#include "photorig/config/yaml_node.h"
#include "photorig/daemon/capture/run_store.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <tuple>

namespace photorig::daemon {
namespace fs = std::filesystem;
namespace {

cv::Mat ToFloatRgb(const cv::Mat& frame_rgb) {
  cv::Mat out;
  frame_rgb.convertTo(out, CV_32F);
  return out;
}

}  // namespace

cv::Mat DemosaicToRgb(const cv::Mat& raw, const std::string& pattern, solvers::color::DemosaicMethod method) {
  cv::Mat bgr;
  const solvers::core::Summary demosaiced = solvers::color::Demosaic(raw, pattern, &bgr, method);
  if (!demosaiced.IsSolutionUsable()) throw std::invalid_argument("demosaicing: " + demosaiced.message);
  cv::cvtColor(bgr, bgr, cv::COLOR_BGR2RGB);
  return bgr;
}

nlohmann::json ToJson(const ColorProvenance& p) {
  nlohmann::json out = {{"mosaic", p.mosaic},
                        {"demosaic", p.demosaic},
                        {"color_space", p.color_space},
                        {"light_colors", p.light_colors}};
  if (!p.color_model_path.empty())
    out["color_model"] = {{"path", p.color_model_path}, {"hash", p.color_model_hash}, {"model", p.color_model_kind}};
  else
    out["color_model"] = nullptr;
  return out;
}

void ApplyColorModelInPlace(const solvers::color::ColorModel& model, cv::Mat* rgb) {
  CV_Assert(rgb->type() == CV_32FC3);
  const cv::Mat clipped = *rgb == std::numeric_limits<float>::infinity();  // per channel
  cv::Mat any_clipped;
  cv::transform(clipped, any_clipped, cv::Matx13f(1, 1, 1));
  cv::Mat finite = rgb->clone();
  finite.setTo(0.0f, clipped);
  cv::Mat bgr, xyz;
  cv::cvtColor(finite, bgr, cv::COLOR_RGB2BGR);
  // The model's own exposure normalisation is undone, so it acts on DN and
  // returns the same scale (exact for an exposure-invariant model).
  solvers::color::ApplyOptions apply;
  apply.exposure_ratio = model.input_scale;
  solvers::core::Summary summary = solvers::color::CameraToXyz(model, bgr, cv::Mat(), apply, &xyz);
  if (!summary.IsSolutionUsable()) throw std::runtime_error("colour model: " + summary.message);
  summary = solvers::color::XyzToLinearSrgbBgr(xyz, model.white_xyz, &bgr);
  if (!summary.IsSolutionUsable()) throw std::runtime_error("colour model: " + summary.message);
  cv::cvtColor(bgr, *rgb, cv::COLOR_BGR2RGB);
  rgb->setTo(cv::Scalar::all(std::numeric_limits<float>::infinity()), any_clipped != 0);
}

namespace {

// The region labels after solvers::color::RegionEdgeVote over the run's lit frames,
// dark subtracted (the mean of the raw darks), with a floor of four times the
// raw read noise (the darks' temporal spread; 1 DN with one dark or none).
cv::Mat SettleRegionEdges(const std::string& run_directory, const RunManifest& manifest, const cv::Mat& regions,
                          double saturation_dn, int* moved) {
  std::vector<cv::Mat> darks;
  for (const FrameRecord& record : manifest.frames) {
    if (record.kind != config::CaptureStep::Kind::kDark) continue;
    darks.emplace_back();
    LoadFrame(run_directory, record).convertTo(darks.back(), CV_32F);
  }
  cv::Mat dark;
  solvers::color::RegionEdgeVote::Options options;
  if (!darks.empty()) {
    dark = cv::Mat::zeros(darks.front().size(), CV_32F);
    for (const cv::Mat& d : darks) dark += d;
    dark /= static_cast<double>(darks.size());
  }
  if (darks.size() >= 2) {
    double squares = 0.0;
    for (const cv::Mat& d : darks) squares += cv::norm(d - dark, cv::NORM_L2SQR);
    const double sigma = std::sqrt(squares / (static_cast<double>(dark.total()) * (darks.size() - 1)));
    options.floor_dn = std::max(4.0 * sigma, 1.0);
  }
  solvers::color::RegionEdgeVote vote(manifest.mosaic, regions, options);
  if (!vote.status().IsSolutionUsable()) throw std::invalid_argument("region edges: " + vote.status().message);
  for (const FrameRecord& record : manifest.frames) {
    if (record.kind != config::CaptureStep::Kind::kLight || record.led < 0) continue;
    const cv::Mat frame = LoadFrame(run_directory, record);
    cv::Mat raw;
    frame.convertTo(raw, CV_32F);
    if (!dark.empty()) raw -= dark;
    const solvers::core::Summary added = vote.Add(raw, frame >= saturation_dn);
    if (!added.IsSolutionUsable()) throw std::runtime_error(run_directory + "/" + record.file + ": " + added.message);
  }
  return vote.Regions(moved);
}

}  // namespace

ColorImageStack LoadRunColorStack(const std::string& run_directory, const ColorStackOptions& options) {
  const RunManifest manifest = LoadRunManifest(run_directory);
  if (manifest.mosaic == "mono")
    throw std::invalid_argument(run_directory + ": a monochrome run (manifest camera.mosaic is \"mono\")");
  ColorImageStack out;
  out.provenance.mosaic = manifest.mosaic;
  const bool bayer = IsBayerPattern(manifest.mosaic);
  const bool within_regions = bayer && !options.demosaic_regions.empty();
  out.provenance.demosaic = !bayer ? "none" : within_regions ? "bilinear within materials" : DemosaicMethodName(options.demosaic);
  if (bayer) {
    out.bayer_run_directory = run_directory;
    out.loaded_with = options;
  }
  const std::string model_path = !options.color_model_path.empty() ? options.color_model_path : manifest.color_model_path;
  std::optional<config::LoadedColorModel> model;
  if (!model_path.empty()) model = config::LoadColorModelFile(model_path);

  const double top_code = static_cast<double>((1u << manifest.bit_depth) - 1u);
  const double saturation = manifest.saturation_dn > 0.0 ? std::min(manifest.saturation_dn, top_code) : top_code;
  // Regions given: their edges are first settled by the raw sites (one read
  // of the frames), then every frame is demosaiced within them.
  cv::Mat regions;
  if (within_regions) {
    if (options.demosaic_regions.type() != CV_8U || options.demosaic_regions.size() != cv::Size(manifest.width, manifest.height))
      throw std::invalid_argument(run_directory + ": the demosaic's region map must be CV_8U and " +
                                  std::to_string(manifest.width) + " x " +
                                  std::to_string(manifest.height) + " like the frames");
    regions = options.settle_region_edges ? SettleRegionEdges(run_directory, manifest, options.demosaic_regions,
                                                              saturation, &out.region_edges_moved)
                                          : options.demosaic_regions;
    out.loaded_with.demosaic_regions = regions;
  }
  // Frame -> camera RGB (float) and where a raw sample it drew on was clipped.
  auto to_rgb = [&](const cv::Mat& raw, cv::Mat* clipped) {
    if (clipped) {
      cv::Mat at_top = raw >= saturation;
      if (within_regions) {
        // Demosaicing the clipped sites' indicator within the same regions
        // marks every pixel whose channels drew on one.
        cv::Mat reached;
        const solvers::core::Summary marked = solvers::color::DemosaicWithinRegions(at_top, manifest.mosaic, regions, &reached);
        if (!marked.IsSolutionUsable()) throw std::invalid_argument("demosaicing: " + marked.message);
        cv::Mat any;
        cv::transform(reached, any, cv::Matx13f(1, 1, 1));
        *clipped = any > 0;
      } else if (bayer) {
        cv::dilate(at_top, at_top, cv::Mat::ones(3, 3, CV_8U));  // the demosaic reaches one pixel out
        *clipped = at_top;
      } else {
        cv::Mat any;
        cv::transform(at_top, any, cv::Matx13f(1, 1, 1));
        *clipped = any != 0;
      }
    }
    if (!within_regions) return ToFloatRgb(bayer ? DemosaicToRgb(raw, manifest.mosaic, options.demosaic) : raw);
    cv::Mat bgr, rgb;
    const solvers::core::Summary demosaiced = solvers::color::DemosaicWithinRegions(raw, manifest.mosaic, regions, &bgr);
    if (!demosaiced.IsSolutionUsable()) throw std::invalid_argument("demosaicing: " + demosaiced.message);
    cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
    return rgb;
  };

  std::vector<cv::Mat> darks;
  for (const FrameRecord& record : manifest.frames)
    if (record.kind == config::CaptureStep::Kind::kDark) darks.push_back(to_rgb(LoadFrame(run_directory, record), nullptr));
  cv::Mat mean_dark;
  if (!darks.empty()) {
    mean_dark = cv::Mat::zeros(darks.front().size(), CV_32FC3);
    for (const cv::Mat& dark : darks) mean_dark += dark;
    mean_dark /= static_cast<double>(darks.size());
  }
  for (const FrameRecord& record : manifest.frames) {
    if (record.kind != config::CaptureStep::Kind::kLight || record.led < 0) continue;
    if (record.led >= static_cast<int>(manifest.lights.size()))
      throw std::runtime_error(run_directory + "/manifest.json: frame " + record.file + " names LED index " +
                               std::to_string(record.led) + " outside the rig's " +
                               std::to_string(manifest.lights.size()) + " LEDs");
    cv::Mat clipped;
    cv::Mat rgb = to_rgb(LoadFrame(run_directory, record), &clipped);
    if (!mean_dark.empty()) rgb -= mean_dark;
    if (model) ApplyColorModelInPlace(model->model, &rgb);
    rgb.setTo(cv::Scalar::all(std::numeric_limits<float>::infinity()), clipped);
    out.images.push_back(rgb);
    const config::LedConfig& led = manifest.lights[record.led];
    out.light_directions.push_back(led.direction);
    const double scale = led.intensity * record.level * manifest.dn_per_radiance_per_us * record.exposure_us *
                         std::pow(10.0, record.gain_db / 20.0);
    out.light_scales.push_back(scale * led.rgb_intensity);
  }
  out.provenance.light_colors = "rig lights' rgb_intensity";
  // Channel noise: the darks' temporal spread after the same processing (one
  // dark: its robust spatial spread), including the subtracted mean's.
  if (!darks.empty()) {
    std::vector<cv::Mat> residuals;
    for (const cv::Mat& dark : darks) {
      const cv::Mat reference = darks.size() >= 2 ? mean_dark : cv::Mat(dark.size(), CV_32FC3, cv::mean(dark));
      cv::Mat residual = dark - reference;
      if (model) ApplyColorModelInPlace(model->model, &residual);
      residuals.push_back(residual);
    }
    const double n = static_cast<double>(darks.size());
    const double temporal = darks.size() >= 2 ? std::sqrt(n / (n - 1.0)) : 1.0;
    for (int c = 0; c < 3; ++c) {
      std::vector<float> values;
      for (const cv::Mat& residual : residuals) {
        cv::Mat channel;
        cv::extractChannel(residual, channel, c);
        values.insert(values.end(), channel.begin<float>(), channel.end<float>());
      }
      auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
      std::nth_element(values.begin(), middle, values.end());
      const float median = *middle;
      for (float& v : values) v = std::abs(v - median);
      std::nth_element(values.begin(), middle, values.end());
      out.read_sigma[c] = 1.4826 * *middle * temporal * std::sqrt(1.0 + 1.0 / n);
    }
  }
  if (model) {
    out.provenance.color_space = "linear-srgb";
    out.provenance.color_model_path = fs::absolute(model->path).lexically_normal().string();
    out.provenance.color_model_hash = model->content_hash;
    out.provenance.color_model_kind = model->model.spec.Name();
  } else {
    out.provenance.color_space = "camera-rgb";
  }
  return out;
}

}  // namespace photorig::daemon
