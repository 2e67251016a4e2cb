#pragma once
// The simulated chart measurement the colour benchmarks start from.

#include "photorig/solvers/color/calibration.h"
#include "photorig/sim/color_chart.h"

#include <string>

namespace photorig::solvers::color::bench {

inline ChartCalibration SimulatedChart(const std::string& camera, Illuminant illuminant, const CalibrationOptions& options,
                                       sim::ChartRender* render_out = nullptr) {
  const ChartCaptureSpectra s = ChartCaptureSpectraFor(camera, illuminant, WavelengthGrid(400.0, 680.0, 5.0)).value();
  const sim::SensorModel sensor;
  const sim::ChartGeometry geometry;
  sim::ChartRender render = sim::RenderColorChart({s.wavelength_nm, s.patch_reflectance, s.illuminant, s.camera_sensitivity},
                                                  geometry, sensor, sim::ExposureForWhite(sensor, 0.8), 0.0, 7);
  LocateOptions locate;
  locate.use_detector = false;
  locate.fixed_corners = geometry.GridCorners();
  MeasureOptions measure;
  measure.clip_level = render.clip_level_dn;
  ChartCalibration result = CalibrateChartImage(render.raw, render.dark, illuminant, locate, measure, options);
  if (render_out) *render_out = std::move(render);
  return result;
}

inline CalibrationInput InputOf(const ChartCalibration& chart) {
  CalibrationInput input;
  input.reference_xyz = chart.reference.xyz;
  input.white_xyz = chart.reference.white_xyz;
  for (const auto& patch : chart.patches) {
    input.camera_rgb.push_back(patch.rgb);
    input.usable.push_back(patch.flag == PatchFlag::kOk);
  }
  return input;
}

}  // namespace photorig::solvers::color::bench
