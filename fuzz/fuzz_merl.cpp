// MERL .binary tables: the first byte's lowest bit picks how the rest becomes
// the file. 0: the bytes are the file (every size but 34,992,012 is refused
// before anything else is read). 1: the bytes overlay the start of a file of
// the right size, zeros elsewhere, so the header and cell checks and the
// evaluation of what was read are reached. The contract is a kSuccess table
// that evaluates to finite values, or kInvalidInput naming the file; ReadMerl
// never throws.
#include "fuzz_support.h"
#include "photorig/solvers/brdf/merl.h"

#include <cmath>
#include <cstring>
#include <vector>

namespace {

namespace brdf = photorig::solvers::brdf;

// A full-size file of zeros made once; each input is written over its start
// and the zeros put back afterwards (rewriting 35 MB per input would dominate).
const std::filesystem::path& ZeroFile() {
  static const std::filesystem::path path = [] {
    const auto p = photorig::fuzz::WorkDir() / "zeros.binary";
    const std::vector<std::uint8_t> zeros(brdf::MerlTable::kFileBytes, 0);
    photorig::fuzz::WriteBytes(p, zeros.data(), zeros.size());
    return p;
  }();
  return path;
}

void Overwrite(const std::filesystem::path& path, const std::uint8_t* data, std::size_t size) {
  std::fstream f(path, std::ios::binary | std::ios::in | std::ios::out);
  f.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  if (!f) std::abort();  // the harness's own failure
}

void WriteSeeds() {
  // A valid header followed by a few cells: 0.5, an unmeasured -1, 2.
  std::string overlay(12, '\0');
  const std::int32_t dims[3] = {90, 90, 180};
  std::memcpy(overlay.data(), dims, sizeof dims);
  for (double v : {0.5, -1.0, 2.0}) overlay.append(reinterpret_cast<const char*>(&v), sizeof v);
  photorig::fuzz::WriteSeed("header_and_cells", 1, overlay);
  photorig::fuzz::WriteSeed("short_file", 0, overlay);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bool seeded = (WriteSeeds(), true);
  (void)seeded;
  if (size == 0) return 0;
  const std::uint8_t* body = data + 1;
  const std::size_t body_size = std::min(size - 1, brdf::MerlTable::kFileBytes);
  std::filesystem::path path;
  if (data[0] & 1) {
    path = ZeroFile();
    Overwrite(path, body, body_size);
  } else {
    path = photorig::fuzz::WorkDir() / "table.binary";
    photorig::fuzz::WriteBytes(path, body, body_size);
  }
  brdf::MerlTable table;
  const brdf::MerlReadSummary summary = brdf::ReadMerl(path.string(), &table);
  if (summary.IsSolutionUsable()) {
    for (const Eigen::Vector3d& wo : {Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0.6, 0, 0.8), Eigen::Vector3d(0, -0.8, 0.6)}) {
      const auto value = table.Evaluate(Eigen::Vector3d(0.0, 0.6, 0.8), wo);
      if (value && !value->allFinite()) std::abort();  // finite cells must give finite values
    }
  } else if (summary.message.find(path.string()) == std::string::npos) {
    std::abort();  // a refusal must name the file
  }
  if (data[0] & 1) {
    const std::vector<std::uint8_t> zeros(body_size, 0);
    Overwrite(path, zeros.data(), zeros.size());
  }
  return 0;
}
