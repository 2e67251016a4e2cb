#pragma once
// Sampled spectra and the reference tables compiled into the library
// (data/*.csv: CIE 1931 2 deg observer, CIE illuminants, BabelColor ColorChecker
// reflectances, measured camera sensitivities). Wavelengths in nm.

#include "photorig/solvers/core/names.h"

#include <Eigen/Core>

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace photorig::solvers::color {

// One or more functions of wavelength sampled at common wavelengths (ascending).
struct SampledSpectra {
  std::vector<double> wavelength_nm;
  std::vector<std::vector<double>> channels;  // channels[c][i] at wavelength_nm[i]

  // Linear interpolation; 0 outside the sampled range (a sensor or a light that
  // was not measured there is taken as not responding / not emitting).
  double At(std::size_t channel, double wavelength_nm) const;
  SampledSpectra Resampled(const std::vector<double>& grid_nm) const;
};

// An evenly spaced grid [first_nm, last_nm] with step_nm.
std::vector<double> WavelengthGrid(double first_nm, double last_nm, double step_nm);

enum class Illuminant { kD50, kD65, kA };
inline constexpr core::NameTable<Illuminant, 3> kIlluminantNames = {
    {{Illuminant::kD50, "D50"}, {Illuminant::kD65, "D65"}, {Illuminant::kA, "A"}}};
inline std::optional<Illuminant> ParseIlluminant(std::string_view name) { return core::ParseName(kIlluminantNames, name); }
inline const char* IlluminantName(Illuminant illuminant) { return core::NameOf(kIlluminantNames, illuminant); }

const SampledSpectra& Cie1931Observer();                 // xbar, ybar, zbar; 360-830 nm, 1 nm
const SampledSpectra& IlluminantSpd(Illuminant illuminant);  // 1 channel; 300-780 nm, 5 nm
const SampledSpectra& ColorChecker24Reflectance();       // 24 channels (patch order); 380-730 nm, 10 nm
// ColorChecker24 L*a*b* (ICC D50) published by X-Rite for charts made after November 2014.
const std::array<Eigen::Vector3d, 24>& ColorChecker24ReferenceLab();
const std::array<std::string, 24>& ColorChecker24Names();

// Cameras whose measured RGB sensitivities are compiled in.
std::vector<std::string> CameraNames();                  // short names: "nikon-5100", ...
// r, g, b of a camera of CameraNames(); null for any other name.
const SampledSpectra* CameraSensitivity(const std::string& name);
// Its make, model and source; nullopt for a name not in CameraNames().
std::optional<std::string> CameraDescription(const std::string& name);

// A named 3x3 matrix from data/rgb_xyz_matrices.csv (out = M * in); nullopt
// for a name the table lacks.
std::optional<Eigen::Matrix3d> NamedMatrix(const std::string& name);

}  // namespace photorig::solvers::color
