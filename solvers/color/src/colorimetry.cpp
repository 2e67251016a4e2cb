#include "photorig/solvers/color/colorimetry.h"

#include "embedded_tables.h"

#include <Eigen/LU>

#include <cmath>
#include <numbers>
#include <optional>

namespace photorig::solvers::color {
namespace {

// One of the compiled-in matrices this file is built on.
Eigen::Matrix3d CompiledMatrix(const std::string& name) {
  const std::optional<Eigen::Matrix3d> matrix = NamedMatrix(name);
  if (!matrix) internal::BrokenTable("rgb_xyz_matrices has no 3x3 matrix " + name);
  return *matrix;
}

// Sum of reflectance x illuminant x CMF over the grid, and the Y of the white.
Eigen::Vector3d IntegrateXyz(const SampledSpectra* reflectance, std::size_t channel, Illuminant illuminant,
                             const std::vector<double>& grid_nm) {
  const SampledSpectra& cmf = Cie1931Observer();
  const SampledSpectra& spd = IlluminantSpd(illuminant);
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
  double white_y = 0.0;
  for (const double wavelength : grid_nm) {
    const double s = spd.At(0, wavelength);
    const double r = reflectance ? reflectance->At(channel, wavelength) : 1.0;
    const Eigen::Vector3d bar(cmf.At(0, wavelength), cmf.At(1, wavelength), cmf.At(2, wavelength));
    xyz += r * s * bar;
    white_y += s * bar.y();
  }
  return xyz / white_y;
}

double LabF(double t) {
  constexpr double kEpsilon = 216.0 / 24389.0;
  constexpr double kKappa = 24389.0 / 27.0;
  return t > kEpsilon ? std::cbrt(t) : (kKappa * t + 16.0) / 116.0;
}

double LabFInverse(double f) {
  constexpr double kEpsilon = 216.0 / 24389.0;
  constexpr double kKappa = 24389.0 / 27.0;
  const double cube = f * f * f;
  return cube > kEpsilon ? cube : (116.0 * f - 16.0) / kKappa;
}

double Degrees(double radians) { return radians * 180.0 / std::numbers::pi; }
double Radians(double degrees) { return degrees * std::numbers::pi / 180.0; }

}  // namespace

Eigen::Vector3d ReflectanceToXyz(const SampledSpectra& reflectance, std::size_t channel, Illuminant illuminant,
                                 const std::vector<double>& grid_nm) {
  return IntegrateXyz(&reflectance, channel, illuminant, grid_nm);
}

Eigen::Vector3d WhitePointXyz(Illuminant illuminant, const std::vector<double>& grid_nm) {
  return IntegrateXyz(nullptr, 0, illuminant, grid_nm);
}

Eigen::Vector3d XyzToXyy(const Eigen::Vector3d& xyz) {
  const double sum = xyz.sum();
  if (sum <= 0.0) return Eigen::Vector3d::Zero();
  return {xyz.x() / sum, xyz.y() / sum, xyz.y()};
}

Eigen::Vector3d XyyToXyz(const Eigen::Vector3d& xyy) {
  if (xyy.y() <= 0.0) return Eigen::Vector3d::Zero();
  const double scale = xyy.z() / xyy.y();
  return {xyy.x() * scale, xyy.z(), (1.0 - xyy.x() - xyy.y()) * scale};
}

Eigen::Vector3d XyzToLab(const Eigen::Vector3d& xyz, const Eigen::Vector3d& white_xyz) {
  const double fx = LabF(xyz.x() / white_xyz.x());
  const double fy = LabF(xyz.y() / white_xyz.y());
  const double fz = LabF(xyz.z() / white_xyz.z());
  return {116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)};
}

Eigen::Vector3d LabToXyz(const Eigen::Vector3d& lab, const Eigen::Vector3d& white_xyz) {
  const double fy = (lab.x() + 16.0) / 116.0;
  const double fx = fy + lab.y() / 500.0;
  const double fz = fy - lab.z() / 200.0;
  return {LabFInverse(fx) * white_xyz.x(), LabFInverse(fy) * white_xyz.y(), LabFInverse(fz) * white_xyz.z()};
}

Eigen::Matrix3d BradfordAdaptation(const Eigen::Vector3d& source_white, const Eigen::Vector3d& destination_white) {
  static const Eigen::Matrix3d ma = CompiledMatrix("bradford_ma");
  static const Eigen::Matrix3d ma_inverse = ma.inverse();
  const Eigen::Vector3d gain = (ma * destination_white).cwiseQuotient(ma * source_white);
  return ma_inverse * gain.asDiagonal() * ma;
}

const Eigen::Matrix3d& XyzD65ToLinearSrgb() {
  static const Eigen::Matrix3d m = CompiledMatrix("srgb_xyz_to_rgb_npm");
  return m;
}

const Eigen::Matrix3d& LinearSrgbToXyzD65() {
  static const Eigen::Matrix3d m = CompiledMatrix("srgb_rgb_to_xyz_npm");
  return m;
}

double SrgbEncode(double linear) {
  if (linear < 0.0) return -SrgbEncode(-linear);
  return linear <= 0.0031308 ? 12.92 * linear : 1.055 * std::pow(linear, 1.0 / 2.4) - 0.055;
}

double SrgbDecode(double encoded) {
  if (encoded < 0.0) return -SrgbDecode(-encoded);
  return encoded <= 0.04045 ? encoded / 12.92 : std::pow((encoded + 0.055) / 1.055, 2.4);
}

double Ciede2000(const Eigen::Vector3d& lab1, const Eigen::Vector3d& lab2, double k_l, double k_c, double k_h) {
  const double c1 = std::hypot(lab1.y(), lab1.z());
  const double c2 = std::hypot(lab2.y(), lab2.z());
  const double c_mean = 0.5 * (c1 + c2);
  const double c_mean7 = std::pow(c_mean, 7.0);
  const double g = 0.5 * (1.0 - std::sqrt(c_mean7 / (c_mean7 + std::pow(25.0, 7.0))));
  const double a1 = (1.0 + g) * lab1.y();
  const double a2 = (1.0 + g) * lab2.y();
  const double c1p = std::hypot(a1, lab1.z());
  const double c2p = std::hypot(a2, lab2.z());
  auto hue = [](double b, double a) {
    if (a == 0.0 && b == 0.0) return 0.0;
    const double h = Degrees(std::atan2(b, a));
    return h < 0.0 ? h + 360.0 : h;
  };
  const double h1p = hue(lab1.z(), a1);
  const double h2p = hue(lab2.z(), a2);

  const double delta_l = lab2.x() - lab1.x();
  const double delta_c = c2p - c1p;
  double delta_h_angle = 0.0;
  if (c1p * c2p != 0.0) {
    delta_h_angle = h2p - h1p;
    if (delta_h_angle > 180.0) delta_h_angle -= 360.0;
    if (delta_h_angle < -180.0) delta_h_angle += 360.0;
  }
  const double delta_h = 2.0 * std::sqrt(c1p * c2p) * std::sin(Radians(delta_h_angle / 2.0));

  const double l_mean = 0.5 * (lab1.x() + lab2.x());
  const double cp_mean = 0.5 * (c1p + c2p);
  double h_mean = h1p + h2p;
  if (c1p * c2p != 0.0) {
    if (std::abs(h1p - h2p) <= 180.0) {
      h_mean = 0.5 * (h1p + h2p);
    } else {
      h_mean = (h1p + h2p < 360.0) ? 0.5 * (h1p + h2p + 360.0) : 0.5 * (h1p + h2p - 360.0);
    }
  }
  const double t = 1.0 - 0.17 * std::cos(Radians(h_mean - 30.0)) + 0.24 * std::cos(Radians(2.0 * h_mean)) +
                   0.32 * std::cos(Radians(3.0 * h_mean + 6.0)) - 0.20 * std::cos(Radians(4.0 * h_mean - 63.0));
  const double delta_theta = 30.0 * std::exp(-std::pow((h_mean - 275.0) / 25.0, 2.0));
  const double cp_mean7 = std::pow(cp_mean, 7.0);
  const double r_c = 2.0 * std::sqrt(cp_mean7 / (cp_mean7 + std::pow(25.0, 7.0)));
  const double l50 = (l_mean - 50.0) * (l_mean - 50.0);
  const double s_l = 1.0 + 0.015 * l50 / std::sqrt(20.0 + l50);
  const double s_c = 1.0 + 0.045 * cp_mean;
  const double s_h = 1.0 + 0.015 * cp_mean * t;
  const double r_t = -std::sin(Radians(2.0 * delta_theta)) * r_c;

  const double tl = delta_l / (k_l * s_l);
  const double tc = delta_c / (k_c * s_c);
  const double th = delta_h / (k_h * s_h);
  return std::sqrt(tl * tl + tc * tc + th * th + r_t * tc * th);
}

}  // namespace photorig::solvers::color
