// A colour model file (ParseModel), JSON or YAML: the first byte's lowest bit
// picks the format, the rest is the text. The contract is a ColorModel or a
// std::invalid_argument naming the file and key.
#include "fuzz_support.h"
#include "photorig/solvers/color/model_io.h"

#include <stdexcept>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bool seeded = [] {
    photorig::solvers::color::ColorModel model;
    model.coefficients = Eigen::MatrixXd::Identity(model.spec.TermCount(), 3);
    photorig::fuzz::WriteSeed("model.json", 0, photorig::solvers::color::SerializeModel(model, "model.json"));
    photorig::fuzz::WriteSeed("model.yaml", 1, photorig::solvers::color::SerializeModel(model, "model.yaml"));
    return true;
  }();
  if (size == 0 || !seeded) return 0;
  const std::string path = (data[0] & 1) ? "model.yaml" : "model.json";
  const std::string text(reinterpret_cast<const char*>(data + 1), size - 1);
  try {
    photorig::solvers::color::ParseModel(text, path);
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
