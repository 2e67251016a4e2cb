// A run's manifest.json, parsed in memory as LoadRunManifest parses the file:
// the JSON reader, RunManifestFromJson's checks of every field, the capture
// verdict a solve asks of it, and the manifest written back. The parser
// fuzz_run_store reaches through a run folder on disk, without the folder:
// thousands of inputs a second rather than a hundred. Seeds (fuzz/corpus/
// fuzz_manifest/): a two-frame run's manifest and a 49-frame dome run's. The
// contract is a manifest or a std::exception (LoadRunManifest turns each into
// a runtime_error naming the file).
#include "photorig/daemon/capture/run_store.h"

#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <exception>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const char* text = reinterpret_cast<const char*>(data);
  try {
    const photorig::daemon::RunManifest manifest = photorig::daemon::RunManifestFromJson(nlohmann::json::parse(text, text + size));
    photorig::daemon::CaptureVerdictOf(manifest);
    photorig::daemon::ToJson(manifest).dump();
  } catch (const std::exception&) {
  }
  return 0;
}
