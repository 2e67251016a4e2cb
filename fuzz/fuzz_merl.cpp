// MERL .binary tables, read by ReadMerl's own checks (ReadMerlCells: size,
// header, every cell finite) for a table of 2 x 3 x 4 cells per channel, so
// that an input is a whole table of 588 bytes, not 35 MB. A table read is then
// evaluated: its cells are written around three configurations of a full
// table (the 3 x 3 x 3 cells about each one's cell, cycling through the cells
// read) and each must evaluate to finite values. The contract is kSuccess or
// kInvalidInput naming the file; neither throws.
#include "fuzz_support.h"
#include "photorig/solvers/brdf/merl.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <sstream>
#include <vector>

namespace {

namespace brdf = photorig::solvers::brdf;

constexpr std::array<std::int32_t, 3> kDims = {2, 3, 4};
constexpr std::size_t kCells = 2 * 3 * 4;
const std::array<Eigen::Vector3d, 3> kWi = {Eigen::Vector3d(0.0, 0.6, 0.8), Eigen::Vector3d(0.0, 0.6, 0.8),
                                            Eigen::Vector3d(0.8, 0.0, 0.6)};
const std::array<Eigen::Vector3d, 3> kWo = {Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0.6, 0, 0.8),
                                            Eigen::Vector3d(0, -0.8, 0.6)};

// The cells an evaluation at (wi, wo) may read: the 3 x 3 x 3 about its own cell.
std::vector<std::size_t> Neighbourhood(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) {
  const brdf::HalfDiff a = brdf::ToHalfDiff(wi, wo);
  const int h = brdf::MerlTable::ThetaHBin(a.theta_h), d = brdf::MerlTable::ThetaDBin(a.theta_d),
            p = brdf::MerlTable::PhiDBin(a.phi_d);
  std::vector<std::size_t> cells;
  for (int i = std::max(h - 1, 0); i <= std::min(h + 1, brdf::MerlTable::kThetaHBins - 1); ++i)
    for (int j = std::max(d - 1, 0); j <= std::min(d + 1, brdf::MerlTable::kThetaDBins - 1); ++j)
      for (int k = p - 1; k <= p + 1; ++k)  // periodic in phi_d
        cells.push_back(brdf::MerlTable::CellIndex(i, j, (k + brdf::MerlTable::kPhiDBins) % brdf::MerlTable::kPhiDBins));
  return cells;
}

// A valid table: 0.5, unmeasured -1 and 2 among its cells.
void WriteSeeds() {
  std::string file(sizeof kDims, '\0');
  std::memcpy(file.data(), kDims.data(), sizeof kDims);
  for (std::size_t i = 0; i < 3 * kCells; ++i) {
    const double v = i % 3 == 0 ? 0.5 : i % 3 == 1 ? -1.0 : 2.0;
    file.append(reinterpret_cast<const char*>(&v), sizeof v);
  }
  photorig::fuzz::WriteSeed("table", file);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bool seeded = (WriteSeeds(), true);
  static brdf::MerlTable table;  // every cell unmeasured between inputs
  (void)seeded;
  const std::string where = "MERL BRDF 'fuzz.binary': ";
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  std::array<std::vector<double>, 3> planes;
  const brdf::MerlReadSummary summary = brdf::ReadMerlCells(in, size, kDims, where, &planes);
  if (!summary.IsSolutionUsable()) {
    if (summary.message.rfind(where, 0) != 0) std::abort();  // a refusal must name the file
    return 0;
  }
  for (std::size_t n = 0; n < kWi.size(); ++n) {
    const std::vector<std::size_t> cells = Neighbourhood(kWi[n], kWo[n]);
    for (std::size_t i = 0; i < cells.size(); ++i)
      for (int c = 0; c < 3; ++c) table.plane(c)[cells[i]] = planes[c][i % kCells];
    const auto value = table.Evaluate(kWi[n], kWo[n]);
    if (value && !value->allFinite()) std::abort();  // finite cells must give finite values
    for (std::size_t cell : cells) table.SetCellInvalid(cell);
  }
  return 0;
}
