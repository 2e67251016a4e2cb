#pragma once
// The simulated colour camera of a rig's sim.color and the spectral
// integrals it is rendered with (sim_color.cpp).

#include "photorig/solvers/color/spectrum.h"
#include "photorig/sim/scene.h"
#include "photorig/sim/world.h"

#include <Eigen/Core>

#include <string>

namespace photorig::config {

// The simulated colour camera (sim.color), used when camera.pixel_format is a
// Bayer format: whose measured sensitivities its channels have and the
// spectrum of the dome's LEDs (a CIE illuminant).
struct SimColorConfig {
  std::string camera = "nikon-5100";  // solvers::color::CameraNames()
  solvers::color::Illuminant illuminant = solvers::color::Illuminant::kD65;
};

// Index (0..23) of a ColorChecker patch by its name, case-insensitive; -1 if none.
int ColorCheckerPatch(const std::string& name);
// Rec. 709 / sRGB luminance weights: Y = w . (R, G, B) linear.
Eigen::Vector3d LuminanceOfLinearSrgb();
// The colour camera's per-channel responses to the texture's two paints and
// to the light (sim::ColorCamera), integrated over wavelength:
//   rho_c = sum R(l) E(l) S_c(l) / sum E(l) S_g(l)
// (reflectance R, the LEDs' spectrum E = the named illuminant, the camera's
// measured sensitivity S_c), and the paints' true linear sRGB albedo (XYZ
// under E, adapted to D65 by Bradford). Without paints both are white.
sim::ColorCamera ColorSceneResponses(const SimColorConfig& color, const sim::AlbedoTexture& albedo);

}  // namespace photorig::config
