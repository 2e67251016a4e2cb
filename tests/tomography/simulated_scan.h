#pragma once
// The scan config/recipes/tomography.yaml takes, made in memory: 64 x 8
// pixels of 0.5 mm, views over 180 degrees of the 3D Shepp-Logan phantom
// (25.6 mm across, sigma up to 0.1/mm), four flats and four darks. A cone
// beam puts the source 60 mm before the axis and the detector 20 mm behind
// it: its rays climb or fall by up to about two slices across the volume.
// The rotation axis sits cor_offset_mm off the detector's centre, which the
// stored geometry does not know (it says 0, as a rig's nominal centre would).

#include "photorig/daemon/pipelines/tomography_pipeline.h"
#include "photorig/sim/phantom.h"

namespace photorig::daemon {

inline TomographyInput SimulatedScan(int views = 64, solvers::tomography::Beam beam = solvers::tomography::Beam::kParallel,
                                     double cor_offset_mm = 0.0, double span_deg = 180.0) {
  TomographyInput input;
  input.source = "simulated scan";
  input.geometry.detector_cols = 64;
  input.geometry.detector_rows = 8;
  input.geometry.pixel_mm = 0.5;
  input.geometry.angles_rad = solvers::tomography::EvenAngles(views, span_deg);
  input.geometry.cor_offset_mm = cor_offset_mm;
  input.geometry.beam = beam;
  input.geometry.source_to_axis_mm = 60.0;
  input.geometry.axis_to_detector_mm = 20.0;
  input.phantom = std::make_shared<const sim::Phantom>(sim::Phantom::SheppLogan3d(12.8, 0.1));
  sim::TomographyScanOptions options;
  options.flats = 4;
  options.darks = 4;
  options.supersample = 2;
  const sim::TomographyScan scan = sim::ScanPhantom(*input.phantom, input.geometry, options);
  input.projections = scan.projections;
  input.flats = scan.flats;
  input.darks = scan.darks;
  input.geometry.cor_offset_mm = 0.0;
  return input;
}

}  // namespace photorig::daemon
