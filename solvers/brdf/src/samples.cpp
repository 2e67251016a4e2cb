#include "photorig/solvers/brdf/samples.h"

#include <cstdlib>
#include <fstream>
#include <sstream>

namespace photorig::solvers::brdf {

namespace {
constexpr const char* kHeader = "wi_x,wi_y,wi_z,wo_x,wo_y,wo_z,f_r,f_g,f_b,sigma_r,sigma_g,sigma_b";
}

Summary WriteSamplesCsv(const std::string& path, const std::vector<BrdfSample>& samples) {
  std::ofstream out(path, std::ios::trunc);
  if (!out) return Ended(Termination::kInvalidInput, "cannot open '" + path + "' for writing");
  out << kHeader << "\n";
  out.precision(17);
  for (const BrdfSample& b : samples)
    for (const Eigen::Vector3d* v : {&b.wi, &b.wo, &b.value, &b.sigma})
      for (int c = 0; c < 3; ++c) out << (*v)[c] << ((v == &b.sigma && c == 2) ? "\n" : ",");
  out.close();
  if (!out) return Ended(Termination::kFailure, "writing samples '" + path + "' failed");
  return Ended(Termination::kSuccess, "");
}

Summary ReadSamplesCsv(const std::string& path, std::vector<BrdfSample>* samples) {
  std::ifstream in(path);
  if (!in) return Ended(Termination::kInvalidInput, "samples '" + path + "': cannot open the file");
  std::string line;
  if (!std::getline(in, line) || line.rfind(kHeader, 0) != 0)
    return Ended(Termination::kInvalidInput, "samples '" + path + "': the first line is not the header " + kHeader);
  std::vector<BrdfSample> read;
  for (int number = 2; std::getline(in, line); ++number) {
    if (line.empty()) continue;
    std::istringstream fields(line);
    double v[12];
    int n = 0;
    for (std::string cell; n < 12 && std::getline(fields, cell, ',');) {
      char* end = nullptr;
      v[n] = std::strtod(cell.c_str(), &end);
      if (end == cell.c_str() || *end != '\0') break;
      ++n;
    }
    std::string rest;
    if (n != 12 || std::getline(fields, rest))
      return Ended(Termination::kInvalidInput,
                   "samples '" + path + "':" + std::to_string(number) + ": not 12 comma-separated numbers");
    BrdfSample s;
    s.wi = {v[0], v[1], v[2]};
    s.wo = {v[3], v[4], v[5]};
    s.value = {v[6], v[7], v[8]};
    s.sigma = {v[9], v[10], v[11]};
    read.push_back(s);
  }
  *samples = std::move(read);
  return Ended(Termination::kSuccess, "");
}

}  // namespace photorig::solvers::brdf
