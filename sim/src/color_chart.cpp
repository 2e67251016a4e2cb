#include "photorig/sim/color_chart.h"

#include "photorig/solvers/core/summary.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

namespace photorig::sim {
using solvers::core::Refuse;

namespace {

// Trapezoid weights on a possibly uneven grid.
std::vector<double> TrapezoidWeights(const std::vector<double>& w) {
  std::vector<double> weights(w.size(), 0.0);
  for (std::size_t i = 0; i + 1 < w.size(); ++i) {
    const double half = 0.5 * (w[i + 1] - w[i]);
    weights[i] += half;
    weights[i + 1] += half;
  }
  return weights;
}

std::array<double, 3> CameraSignal(const ChartSpectra& spectra, const std::vector<double>& weights,
                                   const std::vector<double>* reflectance, double flat_reflectance) {
  std::array<double, 3> rgb{};
  for (std::size_t i = 0; i < weights.size(); ++i) {
    const double r = reflectance ? (*reflectance)[i] : flat_reflectance;
    for (int c = 0; c < 3; ++c) rgb[c] += weights[i] * r * spectra.illuminant[i] * spectra.camera_sensitivity[c][i];
  }
  return rgb;
}

}  // namespace

bool ChartSpectra::IsValid(std::string* why) const {
  const std::size_t n = wavelength_nm.size();
  if (n < 2) return Refuse(why, "need at least two wavelengths");
  if (!std::is_sorted(wavelength_nm.begin(), wavelength_nm.end())) return Refuse(why, "wavelengths must ascend");
  if (patch_reflectance.size() != 24) return Refuse(why, "need 24 patch reflectances");
  for (const auto& r : patch_reflectance)
    if (r.size() != n) return Refuse(why, "a patch reflectance has the wrong number of samples");
  if (illuminant.size() != n) return Refuse(why, "illuminant has the wrong number of samples");
  for (const auto& s : camera_sensitivity)
    if (s.size() != n) return Refuse(why, "a camera sensitivity has the wrong number of samples");
  return true;
}

cv::Rect ChartGeometry::PatchRect(int patch) const {
  const int row = patch / 6, column = patch % 6;
  const int origin = margin_px + border_px;
  return {offset_px.x + origin + column * (patch_px + gap_px), offset_px.y + origin + row * (patch_px + gap_px),
          patch_px, patch_px};
}

std::array<cv::Point2f, 4> ChartGeometry::GridCorners() const {
  const float half_gap = 0.5f * static_cast<float>(gap_px);
  const float left = static_cast<float>(offset_px.x + margin_px + border_px) - half_gap;
  const float top = static_cast<float>(offset_px.y + margin_px + border_px) - half_gap;
  const float right = left + 6.0f * static_cast<float>(patch_px + gap_px);
  const float bottom = top + 4.0f * static_cast<float>(patch_px + gap_px);
  return {cv::Point2f(left, top), cv::Point2f(right, top), cv::Point2f(right, bottom), cv::Point2f(left, bottom)};
}

ChartGeometry ChartGeometry::PlacedIn(const cv::Rect2d& grid_box, cv::Size frame) {
  const int cell = static_cast<int>(std::lround(grid_box.width / 6.0));
  if (std::abs(6.0 * cell - grid_box.width) > 2.0 || std::abs(4.0 * cell - grid_box.height) > 2.0)
    throw std::invalid_argument("a simulated chart has square cells: its box needs w = 6 c and h = 4 c (got " +
                                std::to_string(grid_box.width) + " x " + std::to_string(grid_box.height) + ")");
  if (cell < 12) throw std::invalid_argument("chart cells of " + std::to_string(cell) + " px are too small to measure");
  ChartGeometry g;
  g.gap_px = 2 * std::max(1, cell / 14);  // even, so the grid corners fall on whole pixels
  g.patch_px = cell - g.gap_px;
  g.border_px = g.gap_px;
  g.margin_px = 0;
  g.offset_px = cv::Point(static_cast<int>(std::lround(grid_box.x)) + g.gap_px / 2 - g.border_px,
                          static_cast<int>(std::lround(grid_box.y)) + g.gap_px / 2 - g.border_px);
  g.frame_px = frame;
  if (g.offset_px.x < 0 || g.offset_px.y < 0 || g.offset_px.x + g.chart_width() > frame.width ||
      g.offset_px.y + g.chart_height() > frame.height)
    throw std::invalid_argument("the chart does not fit in the " + std::to_string(frame.width) + " x " +
                                std::to_string(frame.height) + " frame");
  return g;
}

cv::Mat BayerMosaic(const cv::Mat& bgr, const std::string& pattern) {
  if (bgr.channels() != 3) throw std::invalid_argument("a Bayer mosaic needs a 3-channel image");
  // Channel index (B = 0, G = 1, R = 2) of the filter at (row % 2, column % 2).
  auto channel = [](char c) { return c == 'B' ? 0 : c == 'G' ? 1 : 2; };
  if (pattern != "RGGB" && pattern != "BGGR" && pattern != "GRBG" && pattern != "GBRG")
    throw std::invalid_argument("unknown Bayer pattern '" + pattern + "' (expected RGGB, BGGR, GRBG or GBRG)");
  const int filter[2][2] = {{channel(pattern[0]), channel(pattern[1])}, {channel(pattern[2]), channel(pattern[3])}};
  cv::Mat mosaic(bgr.size(), CV_MAKETYPE(bgr.depth(), 1));
  const std::size_t bytes = bgr.elemSize1();
  for (int y = 0; y < bgr.rows; ++y) {
    const std::uint8_t* in = bgr.ptr<std::uint8_t>(y);
    std::uint8_t* out = mosaic.ptr<std::uint8_t>(y);
    for (int x = 0; x < bgr.cols; ++x)
      std::memcpy(out + x * bytes, in + (3 * x + filter[y % 2][x % 2]) * bytes, bytes);
  }
  return mosaic;
}

double ExposureForWhite(const SensorModel& sensor, double fraction) {
  return fraction * sensor.full_well_e / sensor.response_e_per_us;
}

ChartRender RenderColorChart(const ChartSpectra& spectra, const ChartGeometry& geometry, const SensorModel& sensor,
                             double exposure_us, double gain_db, std::uint64_t seed) {
  const std::vector<double> weights = TrapezoidWeights(spectra.wavelength_nm);
  const std::array<double, 3> white = CameraSignal(spectra, weights, nullptr, 1.0);
  const double scale = 1.0 / std::max({white[0], white[1], white[2]});

  auto signal_of = [&](const std::vector<double>* reflectance, double flat) {
    const std::array<double, 3> rgb = CameraSignal(spectra, weights, reflectance, flat);
    return cv::Vec3f(static_cast<float>(rgb[0] * scale), static_cast<float>(rgb[1] * scale),
                     static_cast<float>(rgb[2] * scale));
  };

  ChartRender render;
  for (int c = 0; c < 3; ++c) render.white_signal[c] = white[c] * scale;
  render.signal = cv::Mat(geometry.height(), geometry.width(), CV_32FC3, signal_of(nullptr, geometry.background_reflectance));
  const int body = geometry.margin_px;
  render.signal(cv::Rect(geometry.offset_px.x + body, geometry.offset_px.y + body, geometry.chart_width() - 2 * body,
                         geometry.chart_height() - 2 * body))
      .setTo(signal_of(nullptr, geometry.body_reflectance));
  for (int patch = 0; patch < 24; ++patch)
    render.signal(geometry.PatchRect(patch)).setTo(signal_of(&spectra.patch_reflectance[patch], 0.0));

  std::vector<cv::Mat> planes;
  cv::split(render.signal, planes);
  const cv::Mat off = cv::Mat::zeros(render.signal.size(), CV_32F);
  auto expose = [&](const std::vector<cv::Mat>& channels, std::uint64_t first_frame) {
    std::vector<cv::Mat> bgr(3);
    for (int c = 0; c < 3; ++c) {
      const std::vector<std::uint16_t> pixels =
          ExposeFrame(sensor, channels[c], exposure_us, gain_db, seed, first_frame + static_cast<std::uint64_t>(c));
      bgr[2 - c] = cv::Mat(render.signal.size(), CV_16U, const_cast<std::uint16_t*>(pixels.data())).clone();
    }
    cv::Mat merged;
    cv::merge(bgr, merged);
    return merged;
  };
  render.raw = expose(planes, 0);
  render.dark = expose({off, off, off}, 3);
  const double gain = std::pow(10.0, gain_db / 20.0);
  // Read noise is added after the full-well clip, so clipped pixels scatter around the clip level.
  const double full_well_dn = (sensor.full_well_e - 3.0 * sensor.read_noise_e) / sensor.e_per_dn * gain;
  render.clip_level_dn = std::min(sensor.max_dn(), std::floor(full_well_dn + sensor.black_level_dn));
  return render;
}

}  // namespace photorig::sim
