#pragma once
// Colorimetry: spectra -> CIE XYZ, XYZ <-> xyY <-> CIELAB, Bradford chromatic
// adaptation, XYZ <-> linear sRGB, the sRGB transfer function and CIEDE2000.
// XYZ is relative: the perfect reflecting diffuser under the illuminant has Y = 1.

#include "photorig/solvers/color/spectrum.h"

#include <Eigen/Core>

namespace photorig::solvers::color {

// XYZ of a reflectance under an illuminant, summed on `grid_nm` with the CIE
// 1931 2 deg observer; normalised so a perfect white has Y = 1.
Eigen::Vector3d ReflectanceToXyz(const SampledSpectra& reflectance, std::size_t channel, Illuminant illuminant,
                                 const std::vector<double>& grid_nm);
// XYZ of the perfect white under the illuminant, summed on the same grid (Y = 1).
Eigen::Vector3d WhitePointXyz(Illuminant illuminant, const std::vector<double>& grid_nm);

Eigen::Vector3d XyzToXyy(const Eigen::Vector3d& xyz);  // black maps to (0, 0, 0)
Eigen::Vector3d XyyToXyz(const Eigen::Vector3d& xyy);
Eigen::Vector3d XyzToLab(const Eigen::Vector3d& xyz, const Eigen::Vector3d& white_xyz);
Eigen::Vector3d LabToXyz(const Eigen::Vector3d& lab, const Eigen::Vector3d& white_xyz);

// Bradford von Kries transform taking colours seen under `source_white` to
// corresponding colours under `destination_white`.
Eigen::Matrix3d BradfordAdaptation(const Eigen::Vector3d& source_white, const Eigen::Vector3d& destination_white);

// IEC 61966-2-1 sRGB (D65) from the primaries, full precision.
const Eigen::Matrix3d& XyzD65ToLinearSrgb();
const Eigen::Matrix3d& LinearSrgbToXyzD65();
double SrgbEncode(double linear);   // transfer function; negative input mirrors
double SrgbDecode(double encoded);

// CIEDE2000 (CIE 142-2001) with parametric factors kL = kC = kH = 1 by default.
double Ciede2000(const Eigen::Vector3d& lab1, const Eigen::Vector3d& lab2, double k_l = 1.0, double k_c = 1.0,
                 double k_h = 1.0);

}  // namespace photorig::solvers::color
