// EPFL RGL .bsdf tensor files: the first byte's lowest bit picks the reader,
// the rest is the file. 0: ReadRgl (the container, then the fields checked as
// an isotropic RGB material and evaluated at a few directions: the values must
// be finite). 1: ReadTensorFile alone, and what it read written and read back,
// which must give the same fields. The contract is success or kInvalidInput
// naming the file; neither reader throws.
#include "fuzz_support.h"
#include "photorig/solvers/brdf/models.h"
#include "photorig/solvers/brdf/rgl.h"
#include "photorig/solvers/brdf/tensor_file.h"

#include <fstream>
#include <iterator>

namespace {

namespace brdf = photorig::solvers::brdf;

std::string FileBytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// The smallest valid material (2 incident elevations, 2 x 2 tables) and a
// slightly larger one, tabulated from GGX.
void WriteSeeds() {
  brdf::ModelParams ggx;
  ggx.model = brdf::Model::kGgx;
  ggx.diffuse = {0.3, 0.2, 0.1};
  ggx.specular = {0.9, 0.7, 0.5};
  ggx.shape = 0.3;
  for (int n : {2, 4}) {
    brdf::RglTabulation tab;
    tab.theta_i_count = n;
    tab.sample_resolution = n;
    tab.ndf_resolution = n;
    tab.description = "seed";
    brdf::TensorFile file;
    brdf::TabulateRgl([&](const brdf::DirectionPair& d) { return brdf::Evaluate(ggx, d.wi, d.wo); }, tab, &file);
    const auto path = photorig::fuzz::WorkDir() / "seed.bsdf";
    if (!brdf::WriteTensorFile(path.string(), file).IsSolutionUsable()) std::abort();
    const std::string bytes = FileBytes(path);
    photorig::fuzz::WriteSeed("ggx_" + std::to_string(n) + ".bsdf", 0, bytes);
    photorig::fuzz::WriteSeed("ggx_" + std::to_string(n) + "_container.bsdf", 1, bytes);
  }
}

bool SameFields(const brdf::TensorFile& a, const brdf::TensorFile& b) {
  if (a.fields.size() != b.fields.size()) return false;
  for (std::size_t i = 0; i < a.fields.size(); ++i)
    if (a.fields[i].name != b.fields[i].name || a.fields[i].type != b.fields[i].type ||
        a.fields[i].shape != b.fields[i].shape || a.fields[i].bytes != b.fields[i].bytes)
      return false;
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bool seeded = (WriteSeeds(), true);
  (void)seeded;
  if (size == 0) return 0;
  const auto path = photorig::fuzz::WorkDir() / "material.bsdf";
  photorig::fuzz::WriteBytes(path, data + 1, size - 1);
  photorig::solvers::core::Summary summary;
  if (data[0] & 1) {
    brdf::TensorFile file;
    summary = brdf::ReadTensorFile(path.string(), &file);
    if (summary.IsSolutionUsable()) {
      const auto copy = photorig::fuzz::WorkDir() / "copy.bsdf";
      brdf::TensorFile again;
      if (!brdf::WriteTensorFile(copy.string(), file).IsSolutionUsable() ||
          !brdf::ReadTensorFile(copy.string(), &again).IsSolutionUsable() || !SameFields(file, again))
        std::abort();  // what was read must survive writing and reading back
    }
  } else {
    brdf::RglBrdf rgl;
    summary = brdf::ReadRgl(path.string(), &rgl);
    if (summary.IsSolutionUsable()) {
      const Eigen::Vector3d wi(0.0, 0.6, 0.8);
      for (const Eigen::Vector3d& wo : {Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(-0.6, 0, 0.8), Eigen::Vector3d(0, -0.6, 0.8),
                                        Eigen::Vector3d(0.99, 0, 0.1411)}) {
        const auto value = rgl.Evaluate(wi, wo);
        if (!value || !value->allFinite()) std::abort();  // a checked table must give finite values
      }
    }
  }
  if (!summary.IsSolutionUsable() && summary.message.find(path.string()) == std::string::npos) std::abort();
  return 0;
}
