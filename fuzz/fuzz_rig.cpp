// Rig YAML (LoadRigConfig): the contract is a RigConfig or a ConfigError
// naming file:line:column and key.
#include "fuzz_support.h"
#include "photorig/config/rig.h"
#include "photorig/config/yaml_node.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = photorig::fuzz::WorkDir() / "rig.yaml";
  photorig::fuzz::WriteBytes(path, data, size);
  try {
    photorig::config::LoadRigConfig(path.string());
  } catch (const photorig::config::ConfigError&) {
  }
  return 0;
}
