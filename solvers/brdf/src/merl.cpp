#include "photorig/solvers/brdf/merl.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>

namespace photorig::solvers::brdf {

// The file is little-endian; reading it as raw memory is only right on a
// little-endian host (every machine the project builds for).
static_assert(std::endian::native == std::endian::little);

MerlTable::MerlTable() {
  for (auto& plane : planes_) plane.assign(kCells, -1.0);
}

int MerlTable::ThetaHBin(double theta_h) {
  if (!(theta_h > 0.0)) return 0;
  const int bin = static_cast<int>(std::floor(90.0 * std::sqrt(theta_h / (M_PI / 2.0))));
  return std::clamp(bin, 0, kThetaHBins - 1);
}

int MerlTable::ThetaDBin(double theta_d) {
  const int bin = static_cast<int>(std::floor(theta_d / (M_PI / 2.0) * kThetaDBins));
  return std::clamp(bin, 0, kThetaDBins - 1);
}

int MerlTable::PhiDBin(double phi_d) {
  if (phi_d < 0.0) phi_d += M_PI;
  const int bin = static_cast<int>(std::floor(phi_d / M_PI * kPhiDBins));
  return std::clamp(bin, 0, kPhiDBins - 1);
}

HalfDiff MerlTable::CellCentre(int theta_h_bin, int theta_d_bin, int phi_d_bin) {
  const double s = (theta_h_bin + 0.5) / kThetaHBins;  // centre in the square-root mapping
  return {s * s * (M_PI / 2.0), (theta_d_bin + 0.5) / kThetaDBins * (M_PI / 2.0),
          (phi_d_bin + 0.5) / kPhiDBins * M_PI};
}

std::optional<Eigen::Vector3d> MerlTable::EvaluateCell(std::size_t cell) const {
  Eigen::Vector3d value;
  for (int c = 0; c < 3; ++c) {
    const double stored = planes_[c][cell];
    if (stored < 0.0) return std::nullopt;
    value[c] = stored * kChannelScale[c];
  }
  return value;
}

std::optional<Eigen::Vector3d> MerlTable::Evaluate(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) const {
  if (wi.z() <= 0.0 || wo.z() <= 0.0) return std::nullopt;
  const HalfDiff a = ToHalfDiff(wi, wo);
  return EvaluateCell(CellIndex(ThetaHBin(a.theta_h), ThetaDBin(a.theta_d), PhiDBin(a.phi_d)));
}

void MerlTable::SetCell(std::size_t cell, const Eigen::Vector3d& value_per_sr) {
  for (int c = 0; c < 3; ++c) planes_[c][cell] = value_per_sr[c] / kChannelScale[c];
}

void MerlTable::SetCellInvalid(std::size_t cell) {
  for (auto& plane : planes_) plane[cell] = -1.0;
}

MerlTable MerlTable::FromFunction(
    const std::function<std::optional<Eigen::Vector3d>(const DirectionPair&)>& brdf) {
  MerlTable table;
  for (int ih = 0; ih < kThetaHBins; ++ih)
    for (int id = 0; id < kThetaDBins; ++id)
      for (int ip = 0; ip < kPhiDBins; ++ip) {
        const DirectionPair dirs = FromHalfDiff(CellCentre(ih, id, ip));
        if (dirs.wi.z() <= 0.0 || dirs.wo.z() <= 0.0) continue;
        if (const std::optional<Eigen::Vector3d> value = brdf(dirs)) table.SetCell(CellIndex(ih, id, ip), *value);
      }
  return table;
}

MerlReadSummary ReadMerl(const std::string& path, MerlTable* table) {
  SolveTimer timer;
  MerlReadSummary summary;
  summary.path = path;
  const std::string where = "MERL BRDF '" + path + "': ";
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) {
    summary.End(Termination::kInvalidInput, where + "cannot open the file");
    return summary;
  }
  const auto size = static_cast<std::size_t>(in.tellg());
  if (size != MerlTable::kFileBytes) {
    summary.End(Termination::kInvalidInput, where + std::to_string(size) + " bytes, a MERL table has " +
                                                std::to_string(MerlTable::kFileBytes) +
                                                " (a 12-byte header and 3 x 1458000 doubles)");
    return summary;
  }
  in.seekg(0);
  std::int32_t dims[3];
  in.read(reinterpret_cast<char*>(dims), sizeof dims);
  if (dims[0] != MerlTable::kThetaHBins || dims[1] != MerlTable::kThetaDBins || dims[2] != MerlTable::kPhiDBins) {
    summary.End(Termination::kInvalidInput, where + "header is " + std::to_string(dims[0]) + " x " +
                                                std::to_string(dims[1]) + " x " + std::to_string(dims[2]) +
                                                ", not 90 x 90 x 180");
    return summary;
  }
  MerlTable read;
  for (int c = 0; c < 3; ++c)
    in.read(reinterpret_cast<char*>(read.plane(c).data()),
            static_cast<std::streamsize>(MerlTable::kCells * sizeof(double)));
  if (!in) {
    summary.End(Termination::kInvalidInput, where + "read failed");
    return summary;
  }
  timer.SetupDone(&summary);
  for (int c = 0; c < 3; ++c)
    for (std::size_t i = 0; i < MerlTable::kCells; ++i) {
      const double v = read.plane(c)[i];
      if (!std::isfinite(v)) {
        summary.End(Termination::kInvalidInput, where + "cell " + std::to_string(i) + " of the " + "RGB"[c] +
                                                    " plane is " + (std::isnan(v) ? "NaN" : "infinite"));
        return summary;
      }
      if (v < 0.0 && c == 0) ++summary.invalid_cells;
    }
  *table = std::move(read);
  summary.termination = Termination::kSuccess;
  timer.Finish(&summary);
  return summary;
}

Summary WriteMerl(const std::string& path, const MerlTable& table) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return Ended(Termination::kInvalidInput, "cannot open '" + path + "' for writing");
  const std::int32_t dims[3] = {MerlTable::kThetaHBins, MerlTable::kThetaDBins, MerlTable::kPhiDBins};
  out.write(reinterpret_cast<const char*>(dims), sizeof dims);
  for (int c = 0; c < 3; ++c)
    out.write(reinterpret_cast<const char*>(table.plane(c).data()),
              static_cast<std::streamsize>(MerlTable::kCells * sizeof(double)));
  out.close();
  if (!out) return Ended(Termination::kFailure, "writing MERL BRDF '" + path + "' failed");
  return Ended(Termination::kSuccess, "");
}

}  // namespace photorig::solvers::brdf
