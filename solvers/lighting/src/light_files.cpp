#include "photorig/solvers/lighting/light_files.h"

#include <fstream>
#include <iomanip>
#include <sstream>
#include <stdexcept>

namespace photorig::solvers::lighting {
namespace {

[[noreturn]] void Fail(const std::string& path, int line, const std::string& what) {
  throw std::runtime_error(path + ":" + std::to_string(line) + ": " + what);
}

std::ifstream OpenForReading(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open for reading");
  return in;
}

// True for blank lines and '#' comments, which both formats tolerate in practice.
bool Skippable(const std::string& line) {
  const auto first = line.find_first_not_of(" \t\r");
  return first == std::string::npos || line[first] == '#';
}

void WriteOrThrow(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::trunc);
  out << text;
  out.flush();
  if (!out) throw std::runtime_error(path + ": write failed");
}

}  // namespace

std::vector<LightPosition> ReadLpFile(const std::string& path) {
  std::ifstream in = OpenForReading(path);
  std::string line;
  int line_number = 0;
  long expected = -1;
  std::vector<LightPosition> lights;
  while (std::getline(in, line)) {
    ++line_number;
    if (Skippable(line)) continue;
    std::istringstream fields(line);
    if (expected < 0) {
      std::string extra;
      if (!(fields >> expected) || expected <= 0 || (fields >> extra)) {
        Fail(path, line_number, "expected the light count as the first line");
      }
      continue;
    }
    LightPosition light;
    std::string extra;
    if (!(fields >> light.image >> light.direction.x() >> light.direction.y() >> light.direction.z()) ||
        (fields >> extra)) {
      Fail(path, line_number, "expected 'image x y z'");
    }
    if (!(light.direction.norm() > 0.0)) Fail(path, line_number, "zero light direction");
    if (static_cast<long>(lights.size()) == expected) Fail(path, line_number, "more lights than the count says");
    lights.push_back(light);
  }
  if (expected < 0) Fail(path, line_number, "empty file");
  if (static_cast<long>(lights.size()) != expected) {
    Fail(path, line_number,
         "count says " + std::to_string(expected) + " lights, file has " + std::to_string(lights.size()));
  }
  return lights;
}

void WriteLpFile(const std::string& path, const std::vector<LightPosition>& lights) {
  std::ostringstream out;
  out << lights.size() << "\n" << std::setprecision(9);
  for (const auto& light : lights) {
    out << light.image << " " << light.direction.x() << " " << light.direction.y() << " " << light.direction.z()
        << "\n";
  }
  WriteOrThrow(path, out.str());
}

std::vector<Eigen::Vector3d> ReadTriplesFile(const std::string& path) {
  std::ifstream in = OpenForReading(path);
  std::string line;
  int line_number = 0;
  std::vector<Eigen::Vector3d> rows;
  while (std::getline(in, line)) {
    ++line_number;
    if (Skippable(line)) continue;
    std::istringstream fields(line);
    Eigen::Vector3d row;
    std::string extra;
    if (!(fields >> row.x() >> row.y() >> row.z()) || (fields >> extra)) {
      Fail(path, line_number, "expected three numbers");
    }
    rows.push_back(row);
  }
  if (rows.empty()) Fail(path, line_number, "no rows");
  return rows;
}

void WriteTriplesFile(const std::string& path, const std::vector<Eigen::Vector3d>& rows) {
  std::ostringstream out;
  out << std::setprecision(9);
  for (const auto& row : rows) out << row.x() << " " << row.y() << " " << row.z() << "\n";
  WriteOrThrow(path, out.str());
}

}  // namespace photorig::solvers::lighting
