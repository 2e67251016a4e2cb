#pragma once
// Light-set interchange: the RTI light-position file (.lp: a count, then one
// "image x y z" line per light) and DiLiGenT's light_directions.txt /
// light_intensities.txt (one "x y z" or "r g b" line per light).
// Readers throw std::runtime_error naming file:line on malformed input.

#include <Eigen/Core>

#include <string>
#include <vector>

namespace photorig::solvers::lighting {

struct LightPosition {
  std::string image;
  Eigen::Vector3d direction{0, 0, 1};
};

std::vector<LightPosition> ReadLpFile(const std::string& path);
void WriteLpFile(const std::string& path, const std::vector<LightPosition>& lights);

// Reads N lines of three numbers (DiLiGenT directions or intensities).
std::vector<Eigen::Vector3d> ReadTriplesFile(const std::string& path);
void WriteTriplesFile(const std::string& path, const std::vector<Eigen::Vector3d>& rows);

}  // namespace photorig::solvers::lighting
