#include "photorig/solvers/brdf/measured.h"

#include "photorig/solvers/brdf/merl.h"
#include "photorig/solvers/brdf/rgl.h"

#include <cmath>
#include <memory>

namespace photorig::solvers::brdf {

const char* TableFormatName(TableFormat format) { return format == TableFormat::kMerl ? "merl" : "rgl"; }

std::optional<TableFormat> TableFormatOf(const std::string& path) {
  auto ends_with = [&](const std::string& ext) {
    return path.size() >= ext.size() && path.compare(path.size() - ext.size(), ext.size(), ext) == 0;
  };
  if (ends_with(".binary")) return TableFormat::kMerl;
  if (ends_with(".bsdf")) return TableFormat::kRgl;
  return std::nullopt;
}

core::Summary ReadMeasured(const std::string& path, MeasuredBrdf* brdf) {
  const std::optional<TableFormat> format = TableFormatOf(path);
  if (!format)
    return core::Ended(core::Termination::kInvalidInput,
                 "'" + path + "': not a measured-BRDF file (MERL .binary or EPFL RGL .bsdf, by extension)");
  if (*format == TableFormat::kMerl) {
    auto table = std::make_shared<MerlTable>();
    const core::Summary read = ReadMerl(path, table.get());
    if (!read.IsSolutionUsable()) return read;
    *brdf = MerlBrdf{table};
    return read;
  }
  auto rgl = std::make_shared<RglBrdf>();
  const core::Summary read = ReadRgl(path, rgl.get());
  if (!read.IsSolutionUsable()) return read;
  *brdf = [rgl](const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) { return rgl->Evaluate(wi, wo); };
  return read;
}

bool TableSampling::IsValid(std::string* why) const {
  for (int steps : {theta_h_steps, theta_d_steps, phi_d_steps})
    if (steps < 1 || steps > 1000) return core::Refuse(why, "every step count must lie in [1, 1000]");
  if (!(max_theta_deg > 0.0 && max_theta_deg <= 90.0)) return core::Refuse(why, "max_theta_deg must lie in (0, 90]");
  return true;
}

std::vector<BrdfSample> SampleMeasured(const MeasuredBrdf& brdf, const TableSampling& sampling) {
  std::vector<BrdfSample> samples;
  const double min_cos = std::cos(sampling.max_theta_deg * M_PI / 180.0);
  for (int h = 0; h < sampling.theta_h_steps; ++h)
    for (int d = 0; d < sampling.theta_d_steps; ++d)
      for (int p = 0; p < sampling.phi_d_steps; ++p) {
        const double s = (h + 0.5) / sampling.theta_h_steps;
        const HalfDiff angles{s * s * (M_PI / 2.0), (d + 0.5) / sampling.theta_d_steps * (M_PI / 2.0),
                              (p + 0.5) / sampling.phi_d_steps * M_PI};
        const DirectionPair dirs = FromHalfDiff(angles);
        if (dirs.wi.z() <= 0.0 || dirs.wo.z() <= 0.0 || dirs.wi.z() < min_cos || dirs.wo.z() < min_cos) continue;
        const std::optional<Eigen::Vector3d> value = brdf(dirs.wi, dirs.wo);
        if (!value) continue;
        BrdfSample sample;
        sample.wi = dirs.wi;
        sample.wo = dirs.wo;
        sample.value = *value;
        samples.push_back(sample);
      }
  return samples;
}

}  // namespace photorig::solvers::brdf
