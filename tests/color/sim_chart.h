#pragma once
// The simulated chart capture the colour tests share: the BabelColor chart
// under an illuminant, photographed by a compiled-in camera over 400-680 nm.

#include "photorig/solvers/color/chart.h"
#include "photorig/sim/color_chart.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace photorig::solvers::color::testing {

inline sim::ChartSpectra SimSpectra(const std::string& camera, Illuminant illuminant) {
  const ChartCaptureSpectra s = ChartCaptureSpectraFor(camera, illuminant, WavelengthGrid(400.0, 680.0, 5.0)).value();
  return {s.wavelength_nm, s.patch_reflectance, s.illuminant, s.camera_sensitivity};
}

// White at `white_fraction` of full well; seed keys the noise.
inline sim::ChartRender RenderChart(const std::string& camera, Illuminant illuminant, double white_fraction = 0.8,
                                    std::uint64_t seed = 7, const sim::ChartGeometry& geometry = {}) {
  const sim::SensorModel sensor;
  return sim::RenderColorChart(SimSpectra(camera, illuminant), geometry, sensor,
                               sim::ExposureForWhite(sensor, white_fraction), 0.0, seed);
}

inline MeasureOptions SimMeasureOptions(const sim::ChartRender& render) {
  MeasureOptions options;
  options.clip_level = render.clip_level_dn;
  return options;
}

// MeasurePatches that must succeed.
inline std::vector<PatchMeasurement> Measured(const cv::Mat& image_bgr, const cv::Mat& dark_bgr,
                                              const ChartLocation& location, const MeasureOptions& options) {
  std::vector<PatchMeasurement> patches;
  const solvers::core::Summary summary = MeasurePatches(image_bgr, dark_bgr, location, options, &patches);
  EXPECT_EQ(summary.termination, solvers::core::Termination::kSuccess) << summary.message;
  return patches;
}

}  // namespace photorig::solvers::color::testing
