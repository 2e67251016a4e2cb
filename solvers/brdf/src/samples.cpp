#include "photorig/solvers/brdf/samples.h"

#include <cstdlib>
#include <fstream>
#include <sstream>

namespace photorig::solvers::brdf {

namespace {
constexpr const char* kValueColumns = "wi_x,wi_y,wi_z,wo_x,wo_y,wo_z,f_r,f_g,f_b,sigma_r,sigma_g,sigma_b";
constexpr const char* kOriginColumns = ",light_arm_deg,camera_arm_deg,sample_rotation_deg,exposure_us,frames";
constexpr int kValueCount = 12, kOriginCount = 5;

// Parses one cell as a number; false for anything else, an empty cell included.
bool Number(const std::string& cell, double* value) {
  char* end = nullptr;
  *value = std::strtod(cell.c_str(), &end);
  return end != cell.c_str() && *end == '\0';
}
}  // namespace

core::Summary WriteSamplesCsv(const std::string& path, const std::vector<BrdfSample>& samples) {
  std::ofstream out(path, std::ios::trunc);
  if (!out) return core::Ended(core::Termination::kInvalidInput, "cannot open '" + path + "' for writing");
  out << kValueColumns << kOriginColumns << "\n";
  out.precision(17);
  for (const BrdfSample& b : samples) {
    const char* separator = "";
    for (const Eigen::Vector3d* v : {&b.wi, &b.wo, &b.value, &b.sigma})
      for (int c = 0; c < 3; ++c, separator = ",") out << separator << (*v)[c];
    if (const auto& o = b.origin) {
      out << "," << o->light_arm_deg << "," << o->camera_arm_deg << "," << o->sample_rotation_deg << ","
          << o->exposure_us << "," << o->frames << "\n";
    } else {
      out << ",,,,,\n";
    }
  }
  out.close();
  if (!out) return core::Ended(core::Termination::kFailure, "writing samples '" + path + "' failed");
  return core::Ended(core::Termination::kSuccess, "");
}

core::Summary ReadSamplesCsv(const std::string& path, std::vector<BrdfSample>* samples) {
  std::ifstream in(path);
  if (!in) return core::Ended(core::Termination::kInvalidInput, "samples '" + path + "': cannot open the file");
  const std::string with_origin = std::string(kValueColumns) + kOriginColumns;
  std::string line;
  if (!std::getline(in, line))
    return core::Ended(core::Termination::kInvalidInput, "samples '" + path + "': the file is empty (expected the header " +
                                                 with_origin + ")");
  if (!line.empty() && line.back() == '\r') line.pop_back();
  const bool has_origin = line == with_origin;
  if (!has_origin && line != kValueColumns)
    return core::Ended(core::Termination::kInvalidInput, "samples '" + path + "': the first line is not the header " + with_origin);
  const std::size_t columns = kValueCount + (has_origin ? kOriginCount : 0);
  std::vector<BrdfSample> read;
  for (int number = 2; std::getline(in, line); ++number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    std::vector<std::string> cells;
    std::istringstream fields(line);
    for (std::string cell; std::getline(fields, cell, ',');) cells.push_back(cell);
    if (!line.empty() && line.back() == ',') cells.emplace_back();  // getline drops a trailing empty cell
    const std::string where = "samples '" + path + "':" + std::to_string(number) + ": ";
    if (cells.size() != columns)
      return core::Ended(core::Termination::kInvalidInput,
                   where + std::to_string(cells.size()) + " cells, not " + std::to_string(columns));
    double v[kValueCount + kOriginCount] = {};
    for (int i = 0; i < kValueCount; ++i)
      if (!Number(cells[i], &v[i]))
        return core::Ended(core::Termination::kInvalidInput, where + "cell " + std::to_string(i + 1) + " is not a number");
    BrdfSample s;
    s.wi = {v[0], v[1], v[2]};
    s.wo = {v[3], v[4], v[5]};
    s.value = {v[6], v[7], v[8]};
    s.sigma = {v[9], v[10], v[11]};
    if (has_origin) {
      int empty = 0;
      for (int i = kValueCount; i < kValueCount + kOriginCount; ++i) {
        if (cells[i].empty()) {
          ++empty;
        } else if (!Number(cells[i], &v[i])) {
          return core::Ended(core::Termination::kInvalidInput, where + "cell " + std::to_string(i + 1) + " is not a number");
        }
      }
      if (empty != 0 && empty != kOriginCount)
        return core::Ended(core::Termination::kInvalidInput, where + "the origin (pose, exposure, frames) is given in part: "
                                                         "give all five cells or leave all five empty");
      if (empty == 0) s.origin = SampleOrigin{v[12], v[13], v[14], v[15], static_cast<int>(v[16])};
    }
    read.push_back(s);
  }
  *samples = std::move(read);
  return core::Ended(core::Termination::kSuccess, "");
}

}  // namespace photorig::solvers::brdf
