// Recipe YAML (LoadRecipeText) against a fixed simulated dome: a Recipe or a
// ConfigError naming file:line:column and key.
#include "fuzz_support.h"
#include "photorig/config/recipe.h"
#include "photorig/config/rig.h"
#include "photorig/config/yaml_node.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const photorig::config::RigConfig rig =
      photorig::config::LoadRigConfig(photorig::fuzz::SourcePath("config/rigs/sim-dome.yaml"));
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    photorig::config::LoadRecipeText(text, "fuzz.yaml", rig);
  } catch (const photorig::config::ConfigError&) {
  }
  return 0;
}
