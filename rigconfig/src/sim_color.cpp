// The simulated colour camera's responses: spectral integrals done once per
// paint, so the renderer multiplies by three numbers per pixel.

#include "photorig/config/sim_color.h"

#include "photorig/solvers/color/chart.h"
#include "photorig/solvers/color/colorimetry.h"
#include "photorig/solvers/color/spectrum.h"

#include <algorithm>
#include <cctype>
#include <optional>
#include <stdexcept>

namespace photorig::config {
namespace {

std::string Lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(), [](unsigned char c) { return std::tolower(c); });
  return text;
}

}  // namespace

int ColorCheckerPatch(const std::string& name) {
  const auto& names = solvers::color::ColorChecker24Names();
  for (std::size_t p = 0; p < names.size(); ++p)
    if (Lower(names[p]) == Lower(name)) return static_cast<int>(p);
  return -1;
}

Eigen::Vector3d LuminanceOfLinearSrgb() { return solvers::color::LinearSrgbToXyzD65().row(1).transpose(); }

sim::ColorCamera ColorSceneResponses(const SimColorConfig& config, const sim::AlbedoTexture& albedo) {
  // The camera sensitivities' common range; the truth uses the CIE observer's own grid.
  const std::vector<double> camera_grid = solvers::color::WavelengthGrid(400.0, 680.0, 5.0);
  const std::optional<solvers::color::ChartCaptureSpectra> spectra =
      solvers::color::ChartCaptureSpectraFor(config.camera, config.illuminant, camera_grid);
  if (!spectra) throw std::invalid_argument("sim.color.camera: unknown camera '" + config.camera + "'");
  const solvers::color::ChartCaptureSpectra& s = *spectra;
  auto response = [&s](const std::vector<double>* reflectance) {
    Eigen::Vector3d rgb = Eigen::Vector3d::Zero();
    double white_green = 0.0;
    for (std::size_t i = 0; i < s.wavelength_nm.size(); ++i) {
      const double r = reflectance ? (*reflectance)[i] : 1.0;
      for (int c = 0; c < 3; ++c) rgb[c] += r * s.illuminant[i] * s.camera_sensitivity[c][i];
      white_green += s.illuminant[i] * s.camera_sensitivity[1][i];
    }
    return Eigen::Vector3d(rgb / white_green);
  };
  sim::ColorCamera camera;
  camera.light_rgb = response(nullptr);
  if (albedo.paints.size() != 2) {
    // No paints: a spectrally flat (grey) texture, each channel seeing the
    // texture's albedo times its response to the light.
    camera.low_rgb = albedo.low * camera.light_rgb;
    camera.high_rgb = albedo.high * camera.light_rgb;
    camera.truth_low_srgb = Eigen::Vector3d::Constant(albedo.low);
    camera.truth_high_srgb = Eigen::Vector3d::Constant(albedo.high);
    return camera;
  }

  const std::vector<double> truth_grid = solvers::color::WavelengthGrid(380.0, 730.0, 5.0);
  const Eigen::Matrix3d to_srgb =
      solvers::color::XyzD65ToLinearSrgb() *
      solvers::color::BradfordAdaptation(solvers::color::WhitePointXyz(config.illuminant, truth_grid),
                                solvers::color::WhitePointXyz(solvers::color::Illuminant::kD65, truth_grid));
  std::array<Eigen::Vector3d, 2> rgb, truth;
  for (int m = 0; m < 2; ++m) {
    const int patch = ColorCheckerPatch(albedo.paints[static_cast<std::size_t>(m)]);
    rgb[m] = response(&s.patch_reflectance.at(static_cast<std::size_t>(patch)));
    truth[m] = to_srgb * solvers::color::ReflectanceToXyz(solvers::color::ColorChecker24Reflectance(), static_cast<std::size_t>(patch),
                                                 config.illuminant, truth_grid);
  }
  // The texture's low squares are the darker paint (its numbers become the paints' luminance).
  const int low = truth[0].dot(LuminanceOfLinearSrgb()) <= truth[1].dot(LuminanceOfLinearSrgb()) ? 0 : 1;
  camera.low_rgb = rgb[low];
  camera.high_rgb = rgb[1 - low];
  camera.truth_low_srgb = truth[low];
  camera.truth_high_srgb = truth[1 - low];
  return camera;
}

}  // namespace photorig::config
