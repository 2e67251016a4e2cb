#include "photorig/solvers/tomography/nrrd.h"

#include <bit>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>

namespace photorig::solvers::tomography {

namespace {

std::uint32_t SwapBytes(std::uint32_t v) {
  return (v >> 24) | ((v >> 8) & 0xff00u) | ((v << 8) & 0xff0000u) | (v << 24);
}

}  // namespace

solvers::core::Summary WriteNrrd(const std::string& path, const VolumeGrid& grid, const Eigen::VectorXf& sigma) {
  solvers::core::SolveTimer timer;
  std::string why;
  if (!grid.IsValid(&why)) return solvers::core::Ended(solvers::core::Termination::kInvalidInput, why);
  if (sigma.size() != grid.voxels())
    return solvers::core::Ended(solvers::core::Termination::kInvalidInput, "the volume does not match the grid");
  std::ofstream out(path, std::ios::binary);
  if (!out) return solvers::core::Ended(solvers::core::Termination::kInvalidInput, "cannot write " + path);
  const Eigen::Vector3d min = grid.VoxelCentre(0, 0, 0);
  out << "NRRD0004\n"
      << "# photorig tomography: extinction coefficient sigma in 1/mm, voxel centres in mm\n"
      << "type: float\n"
      << "dimension: 3\n"
      << "sizes: " << grid.nx << ' ' << grid.ny << ' ' << grid.nz << '\n'
      << "spacings: " << grid.voxel_mm << ' ' << grid.voxel_mm << ' ' << grid.voxel_mm << '\n'
      << "axis mins: " << min.x() << ' ' << min.y() << ' ' << min.z() << '\n'
      << "units: \"mm\" \"mm\" \"mm\"\n"
      << "endian: little\n"
      << "encoding: raw\n\n";
  for (std::int64_t i = 0; i < sigma.size(); ++i) {
    std::uint32_t bits = std::bit_cast<std::uint32_t>(sigma[i]);
    if constexpr (std::endian::native == std::endian::big) bits = SwapBytes(bits);
    out.write(reinterpret_cast<const char*>(&bits), sizeof bits);
  }
  // The last buffer reaches the file only here: a full disk shows at the flush.
  out.flush();
  if (!out) return solvers::core::Ended(solvers::core::Termination::kInvalidInput, "writing " + path + " failed: " + std::strerror(errno));
  return timer.Succeeded();
}

solvers::core::Summary ReadNrrd(const std::string& path, VolumeGrid* grid, Eigen::VectorXf* sigma) {
  solvers::core::SolveTimer timer;
  std::ifstream in(path, std::ios::binary);
  auto fail = [&path](const std::string& why) {
    return solvers::core::Ended(solvers::core::Termination::kInvalidInput, path + ": " + why);
  };
  if (!in) return fail("cannot open");
  std::string line;
  if (!std::getline(in, line) || line.rfind("NRRD000", 0) != 0) return fail("not a NRRD file");
  VolumeGrid read;
  read.nx = read.ny = read.nz = 0;
  bool little = true, have_sizes = false;
  while (std::getline(in, line) && !line.empty()) {
    if (line[0] == '#') continue;
    const auto colon = line.find(": ");
    if (colon == std::string::npos) continue;  // key:=value pairs and the like
    const std::string key = line.substr(0, colon);
    std::istringstream value(line.substr(colon + 2));
    std::string word;
    if (key == "type") {
      value >> word;
      if (word != "float") return fail("type " + word + "; only float is read");
    } else if (key == "dimension") {
      int d = 0;
      value >> d;
      if (d != 3) return fail("dimension " + std::to_string(d) + "; only 3 is read");
    } else if (key == "sizes") {
      have_sizes = static_cast<bool>(value >> read.nx >> read.ny >> read.nz);
    } else if (key == "spacings") {
      value >> read.voxel_mm;
    } else if (key == "endian") {
      value >> word;
      little = word == "little";
    } else if (key == "encoding") {
      value >> word;
      if (word != "raw") return fail("encoding " + word + "; only raw is read");
    }
  }
  std::string why;
  if (!have_sizes || !read.IsValid(&why)) return fail("bad header: " + (have_sizes ? why : "no sizes"));
  Eigen::VectorXf data(read.voxels());
  for (std::int64_t i = 0; i < data.size(); ++i) {
    std::uint32_t bits = 0;
    if (!in.read(reinterpret_cast<char*>(&bits), sizeof bits)) return fail("the data end early");
    if (little != (std::endian::native == std::endian::little)) bits = SwapBytes(bits);
    data[i] = std::bit_cast<float>(bits);
  }
  *grid = read;
  *sigma = std::move(data);
  return timer.Succeeded();
}

}  // namespace photorig::solvers::tomography
