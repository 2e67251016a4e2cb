// Light files: the first byte's lowest bit picks an RTI .lp file (ReadLpFile)
// or a DiLiGenT triples file (ReadTriplesFile), the rest is the file. The
// contract is the lights or a std::runtime_error naming file:line.
#include "fuzz_support.h"
#include "photorig/solvers/lighting/light_files.h"

#include <stdexcept>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const auto path = photorig::fuzz::WorkDir() / "lights.txt";
  photorig::fuzz::WriteBytes(path, data + 1, size - 1);
  try {
    if (data[0] & 1)
      photorig::solvers::lighting::ReadTriplesFile(path.string());
    else
      photorig::solvers::lighting::ReadLpFile(path.string());
  } catch (const std::runtime_error&) {
  }
  return 0;
}
