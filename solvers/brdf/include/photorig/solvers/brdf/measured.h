#pragma once
// A measured BRDF table of either file format (MERL .binary, EPFL RGL .bsdf)
// behind one evaluation, and the samples a fit draws from it, so that a table
// is fitted by the same SelectModel as a gonioreflectometer's samples.

#include "photorig/solvers/brdf/half_diff.h"
#include "photorig/solvers/brdf/merl.h"
#include "photorig/solvers/brdf/samples.h"
#include "photorig/solvers/core/summary.h"

#include <Eigen/Core>

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace photorig::solvers::brdf {

// f_r in 1/sr per channel, or nothing (below the horizon, an unmeasured cell).
using MeasuredBrdf = std::function<std::optional<Eigen::Vector3d>(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo)>;

// A MERL table as a MeasuredBrdf (ReadMeasured's for a .binary): its
// trilinear Evaluate, and the table itself for a caller that reads the cells
// directly (FitTable, through MeasuredBrdf::target<MerlBrdf>()).
struct MerlBrdf {
  std::shared_ptr<const MerlTable> table;
  std::optional<Eigen::Vector3d> operator()(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) const {
    return table->Evaluate(wi, wo);
  }
};

enum class TableFormat { kMerl, kRgl };
const char* TableFormatName(TableFormat format);  // "merl", "rgl"
// By the file's extension: .binary is MERL, .bsdf RGL.
std::optional<TableFormat> TableFormatOf(const std::string& path);

// Reads a table of either format (ReadMerl, ReadRgl). An extension that is
// neither, or a file its reader refuses, ends kInvalidInput naming the file.
core::Summary ReadMeasured(const std::string& path, MeasuredBrdf* brdf);

// Configurations uniform in (theta_h, theta_d, phi_d) at cell centres, theta_h
// in the square-root spacing MERL uses (dense near the specular peak), phi_d
// over [0, pi) (reciprocity), both directions within max_theta_deg of the
// normal: measured tables are least reliable at grazing angles (an RGL file
// holds nothing beyond its last incident elevation, 85 deg in the ones
// written here, and clamps to it).
struct TableSampling {
  int theta_h_steps = 16;
  int theta_d_steps = 16;
  int phi_d_steps = 16;
  double max_theta_deg = 80.0;

  bool IsValid(std::string* why) const;
};

// The table's value at each configuration above the horizon where it has one;
// sigma is 0 (a table carries no deviations: fit it with the log loss).
std::vector<BrdfSample> SampleMeasured(const MeasuredBrdf& brdf, const TableSampling& sampling);

}  // namespace photorig::solvers::brdf
