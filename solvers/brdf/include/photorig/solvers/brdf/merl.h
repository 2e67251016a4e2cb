#pragma once
// MERL's measured-BRDF table (Matusik et al. 2003, the `.binary` files of the
// MERL database): an isotropic BRDF tabulated in half/difference angles.
//
// File: three int32 (90, 90, 180), then three planes R, G, B of
// 90 * 90 * 180 = 1,458,000 little-endian doubles each: 34,992,012 bytes.
// Cell index = phi_d + 180 * theta_d + 16200 * theta_h, with
//   theta_h bin = floor(90 * sqrt(theta_h / (pi/2)))  (dense near the specular peak)
//   theta_d bin = floor(theta_d / (pi/2) * 90)
//   phi_d   bin = floor(phi_d / pi * 180) after folding phi_d < 0 by adding pi
//                 (reciprocity: phi_d and phi_d + pi are the same configuration)
// every bin clamped to its range. A stored value times the channel's scale
// (R 1/1500, G 1.15/1500, B 1.66/1500) is the BRDF in 1/sr; a stored value
// below 0 (the files use -1) marks a cell that was not measured.

#include "photorig/solvers/brdf/half_diff.h"
#include "photorig/solvers/core/summary.h"

#include <Eigen/Core>

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <istream>
#include <optional>
#include <string>
#include <vector>

namespace photorig::solvers::brdf {

class MerlTable {
 public:
  static constexpr int kThetaHBins = 90, kThetaDBins = 90, kPhiDBins = 180;
  static constexpr std::size_t kCells = std::size_t{kThetaHBins} * kThetaDBins * kPhiDBins;  // 1,458,000
  static constexpr std::size_t kFileBytes = 3 * sizeof(std::int32_t) + 3 * kCells * sizeof(double);
  static constexpr std::array<double, 3> kChannelScale = {1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0};

  // Every cell invalid (-1).
  MerlTable();

  static int ThetaHBin(double theta_h);
  static int ThetaDBin(double theta_d);
  static int PhiDBin(double phi_d);  // folds phi_d < 0 by reciprocity
  static std::size_t CellIndex(int theta_h_bin, int theta_d_bin, int phi_d_bin) {
    return static_cast<std::size_t>(phi_d_bin) + std::size_t{kPhiDBins} * theta_d_bin +
           std::size_t{kPhiDBins} * kThetaDBins * theta_h_bin;
  }
  // The angles at the centre of a cell (theta_h at the centre of its square-root bin).
  static HalfDiff CellCentre(int theta_h_bin, int theta_d_bin, int phi_d_bin);

  // The BRDF in 1/sr per channel (R, G, B), trilinear between the centres of
  // the eight cells around the configuration (in bin coordinates: theta_h in
  // its square-root mapping; phi_d periodic over pi; constant beyond the outer
  // centres), unmeasured neighbours left out and the weights renormalised. At
  // a cell centre it is the stored value bit for bit. Empty below the horizon
  // (w_i.z <= 0 or w_o.z <= 0), for a direction that is not finite, and when
  // the cell the configuration falls in is not measured.
  std::optional<Eigen::Vector3d> Evaluate(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) const;
  // One cell's stored value in 1/sr; empty when not measured.
  std::optional<Eigen::Vector3d> EvaluateCell(std::size_t cell) const;

  // Stores a BRDF value in 1/sr (divided by the channel scales, as the file holds it).
  void SetCell(std::size_t cell, const Eigen::Vector3d& value_per_sr);
  void SetCellInvalid(std::size_t cell);

  // A table of `brdf` (1/sr per channel) sampled at every cell centre; cells
  // whose centre lies below the horizon, or where `brdf` gives nothing (a
  // measured table converted), stay invalid.
  static MerlTable FromFunction(const std::function<std::optional<Eigen::Vector3d>(const DirectionPair&)>& brdf);

  // The values as stored in the file, one plane per channel.
  const std::vector<double>& plane(int channel) const { return planes_[channel]; }
  std::vector<double>& plane(int channel) { return planes_[channel]; }

 private:
  std::array<std::vector<double>, 3> planes_;
};

struct MerlReadSummary : core::Summary {
  std::string path;
  std::size_t invalid_cells = 0;  // cells marked as not measured (negative)
};

// Reads a MERL .binary. A missing file, a size other than 34,992,012 bytes, a
// header other than (90, 90, 180) or a NaN / infinite cell ends kInvalidInput
// with the file and what is wrong; `table` is then untouched.
MerlReadSummary ReadMerl(const std::string& path, MerlTable* table);

// ReadMerl's checks on `size` bytes from `in`, for a table of
// dims[0] x dims[1] x dims[2] cells per channel: the size, the header, then
// every cell finite; `where` begins each message. On success `planes` holds
// the three channels' cells. ReadMerl passes MERL's (90, 90, 180); the fuzz
// target (fuzz/fuzz_merl.cpp) a small shape, so that each input is a whole
// table of a few hundred bytes rather than 35 MB.
MerlReadSummary ReadMerlCells(std::istream& in, std::size_t size, const std::array<std::int32_t, 3>& dims,
                              const std::string& where, std::array<std::vector<double>, 3>* planes);

// Writes `table` as a MERL .binary (byte for byte what ReadMerl read). A
// NaN or infinite cell ends kInvalidInput naming it, before the file is opened.
core::Summary WriteMerl(const std::string& path, const MerlTable& table);

}  // namespace photorig::solvers::brdf
