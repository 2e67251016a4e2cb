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

namespace {

// A continuous bin coordinate: cell k's centre at k. Within 1e-9 of a centre
// it is snapped onto it, so a configuration at a cell centre (a round trip
// through FromHalfDiff and ToHalfDiff) reads the stored value bit for bit.
double Snapped(double u) {
  const double nearest = std::round(u);
  return std::abs(u - nearest) < 1e-6 ? nearest : u;
}

// The two cells bracketing coordinate `u` on a clamped axis of `bins` cells
// and the weight of the upper one (constant beyond the outer centres).
void Bracket(double u, int bins, int* lower, int* upper, double* t) {
  u = std::clamp(u, 0.0, bins - 1.0);
  *lower = std::min(static_cast<int>(std::floor(u)), bins - 1);
  *upper = std::min(*lower + 1, bins - 1);
  *t = u - *lower;
}

}  // namespace

std::optional<Eigen::Vector3d> MerlTable::Evaluate(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) const {
  // A NaN compares false below: without this it reached a cell index far outside the table.
  if (!wi.allFinite() || !wo.allFinite()) return std::nullopt;
  if (wi.z() <= 0.0 || wo.z() <= 0.0) return std::nullopt;
  const HalfDiff a = ToHalfDiff(wi, wo);
  // The cell the configuration falls in must be measured; its measured
  // neighbours then share the interpolation (an unmeasured one's weight goes
  // to the others).
  if (!EvaluateCell(CellIndex(ThetaHBin(a.theta_h), ThetaDBin(a.theta_d), PhiDBin(a.phi_d)))) return std::nullopt;
  // Trilinear in bin coordinates: theta_h in its square-root mapping (the
  // cells are uniform there), theta_d linear, phi_d periodic over pi.
  const double u_h = Snapped(90.0 * std::sqrt(std::max(a.theta_h, 0.0) / (M_PI / 2.0)) - 0.5);
  const double u_d = Snapped(a.theta_d / (M_PI / 2.0) * kThetaDBins - 0.5);
  const double phi_d = a.phi_d < 0.0 ? a.phi_d + M_PI : a.phi_d;
  const double u_p = Snapped(phi_d / M_PI * kPhiDBins - 0.5);
  int h[2], d[2];
  double th, td;
  Bracket(u_h, kThetaHBins, &h[0], &h[1], &th);
  Bracket(u_d, kThetaDBins, &d[0], &d[1], &td);
  const int p_floor = static_cast<int>(std::floor(u_p));
  const double tp = u_p - p_floor;
  const int p[2] = {(p_floor % kPhiDBins + kPhiDBins) % kPhiDBins, ((p_floor + 1) % kPhiDBins + kPhiDBins) % kPhiDBins};
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double weight_sum = 0.0;
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j)
      for (int k = 0; k < 2; ++k) {
        const double w = (i ? th : 1.0 - th) * (j ? td : 1.0 - td) * (k ? tp : 1.0 - tp);
        if (w == 0.0) continue;
        if (const std::optional<Eigen::Vector3d> v = EvaluateCell(CellIndex(h[i], d[j], p[k]))) {
          sum += w * *v;
          weight_sum += w;
        }
      }
  return sum / weight_sum;
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

MerlReadSummary ReadMerlCells(std::istream& in, std::size_t size, const std::array<std::int32_t, 3>& dims,
                              const std::string& where, std::array<std::vector<double>, 3>* planes) {
  MerlReadSummary summary;
  const std::size_t cells = static_cast<std::size_t>(dims[0]) * dims[1] * dims[2];
  const std::size_t expected_bytes = sizeof dims + 3 * cells * sizeof(double);
  if (size != expected_bytes) {
    summary.End(core::Termination::kInvalidInput, where + std::to_string(size) + " bytes, a MERL table has " +
                                                std::to_string(expected_bytes) + " (a 12-byte header and 3 x " +
                                                std::to_string(cells) + " doubles)");
    return summary;
  }
  std::int32_t header[3] = {0, 0, 0};
  in.read(reinterpret_cast<char*>(header), sizeof header);
  if (!in || header[0] != dims[0] || header[1] != dims[1] || header[2] != dims[2]) {
    summary.End(core::Termination::kInvalidInput, where + "header is " + std::to_string(header[0]) + " x " +
                                                std::to_string(header[1]) + " x " + std::to_string(header[2]) +
                                                ", not " + std::to_string(dims[0]) + " x " + std::to_string(dims[1]) +
                                                " x " + std::to_string(dims[2]));
    return summary;
  }
  std::array<std::vector<double>, 3> read;
  for (std::vector<double>& plane : read) {
    plane.resize(cells);
    in.read(reinterpret_cast<char*>(plane.data()), static_cast<std::streamsize>(cells * sizeof(double)));
  }
  if (!in) {
    summary.End(core::Termination::kInvalidInput, where + "read failed");
    return summary;
  }
  for (int c = 0; c < 3; ++c)
    for (std::size_t i = 0; i < cells; ++i) {
      const double v = read[c][i];
      if (!std::isfinite(v)) {
        summary.End(core::Termination::kInvalidInput, where + "cell " + std::to_string(i) + " of the " + "RGB"[c] +
                                                    " plane is " + (std::isnan(v) ? "NaN" : "infinite"));
        return summary;
      }
      if (v < 0.0 && c == 0) ++summary.invalid_cells;
    }
  *planes = std::move(read);
  summary.termination = core::Termination::kSuccess;
  return summary;
}

MerlReadSummary ReadMerl(const std::string& path, MerlTable* table) {
  core::SolveTimer timer;
  const std::string where = "MERL BRDF '" + path + "': ";
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  MerlReadSummary summary;
  std::array<std::vector<double>, 3> planes;
  if (!in)
    summary.End(core::Termination::kInvalidInput, where + "cannot open the file");
  else {
    const auto size = static_cast<std::size_t>(in.tellg());
    in.seekg(0);
    summary = ReadMerlCells(in, size, {MerlTable::kThetaHBins, MerlTable::kThetaDBins, MerlTable::kPhiDBins}, where,
                            &planes);
  }
  summary.path = path;
  if (summary.IsSolutionUsable())
    for (int c = 0; c < 3; ++c) table->plane(c) = std::move(planes[c]);
  timer.Finish(&summary);
  return summary;
}

core::Summary WriteMerl(const std::string& path, const MerlTable& table) {
  // ReadMerl refuses a table that is not finite: it is never written.
  for (int c = 0; c < 3; ++c)
    for (std::size_t i = 0; i < MerlTable::kCells; ++i)
      if (const double v = table.plane(c)[i]; !std::isfinite(v)) {
        const std::size_t per_h = std::size_t{MerlTable::kThetaDBins} * MerlTable::kPhiDBins;
        return core::Ended(core::Termination::kInvalidInput,
                     "MERL BRDF '" + path + "' not written: cell " + std::to_string(i) + " of the " + "RGB"[c] +
                         " plane (theta_h bin " + std::to_string(i / per_h) + ", theta_d bin " +
                         std::to_string(i % per_h / MerlTable::kPhiDBins) + ", phi_d bin " +
                         std::to_string(i % MerlTable::kPhiDBins) + ") is " + (std::isnan(v) ? "NaN" : "infinite") +
                         ", which no reader accepts");
      }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return core::Ended(core::Termination::kInvalidInput, "cannot open '" + path + "' for writing");
  const std::int32_t dims[3] = {MerlTable::kThetaHBins, MerlTable::kThetaDBins, MerlTable::kPhiDBins};
  out.write(reinterpret_cast<const char*>(dims), sizeof dims);
  for (int c = 0; c < 3; ++c)
    out.write(reinterpret_cast<const char*>(table.plane(c).data()),
              static_cast<std::streamsize>(MerlTable::kCells * sizeof(double)));
  out.close();
  if (!out) return core::Ended(core::Termination::kFailure, "writing MERL BRDF '" + path + "' failed");
  return core::Ended(core::Termination::kSuccess, "");
}

}  // namespace photorig::solvers::brdf
