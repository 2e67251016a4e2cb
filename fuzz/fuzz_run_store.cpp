// A stored run, read as `photorig` and the daemon read one. The input
// replaces one file of a valid two-frame run: the first byte picks
// manifest.json, journal.jsonl or a frame PNG, the rest is its content. Each
// input goes to the readers of the file it replaced: a manifest to
// LoadRunManifest and LoadFrame of each frame it lists, then VerifyRun; a
// journal to RunWriter::Reopen (which repairs it); a frame to LoadFrame and
// VerifyRun. The contract is a result or a std::runtime_error naming the file.
#include "fuzz_support.h"
#include "photorig/daemon/capture/run_store.h"

#include <algorithm>
#include <array>
#include <utility>
#include <vector>
#include <stdexcept>

namespace {

namespace fs = std::filesystem;
using namespace photorig::daemon;

constexpr std::array<const char*, 3> kFiles = {"manifest.json", "journal.jsonl", "frames/0001_led00.png"};

photorig::drivers::Frame MakeFrame(std::uint64_t id) {
  photorig::drivers::Frame frame;
  frame.width = 8;
  frame.height = 4;
  frame.bit_depth = 12;
  frame.frame_id = id;
  frame.exposure_us = 1000;
  for (int i = 0; i < frame.width * frame.height; ++i)
    frame.pixels.push_back(static_cast<std::uint16_t>((i * 37 + id) % 4096));
  return frame;
}

photorig::config::CaptureStep Step(int index, int led) {
  photorig::config::CaptureStep step;
  step.index = index;
  step.kind = led < 0 ? photorig::config::CaptureStep::Kind::kDark : photorig::config::CaptureStep::Kind::kLight;
  step.led = led;
  step.label = led < 0 ? "0000_dark" : "0001_led00";
  step.pattern = std::make_shared<const photorig::drivers::LightPattern>(
      led < 0 ? photorig::drivers::LightPattern::AllOff(1) : photorig::drivers::LightPattern::Single(1, 0, 0.5));
  return step;
}

// A finished run of a dark frame and one lit frame.
fs::path WriteValidRun(const fs::path& dir) {
  RunManifest header;
  header.run_id = "fuzz";
  header.width = 8;
  header.height = 4;
  header.bit_depth = 12;
  header.lights.resize(1);
  RunWriter writer(dir.string(), header);
  writer.WriteFrame(Step(0, -1), MakeFrame(1));
  writer.WriteFrame(Step(1, 0), MakeFrame(2));
  writer.Finish({CaptureStatus::kComplete, "", 2, 2, 0, 0});
  if (!VerifyRun(dir.string()).empty()) std::abort();  // the harness's own check
  for (std::size_t i = 0; i < kFiles.size(); ++i)
    photorig::fuzz::WriteSeed(fs::path(kFiles[i]).filename().string(), static_cast<std::uint8_t>(i),
                              photorig::fuzz::ReadBytes(dir / kFiles[i]));
  return dir;
}

// Every file of the valid run, the fuzzed ones first in kFiles' order.
std::vector<std::pair<fs::path, std::string>> ReadFiles(const fs::path& run) {
  std::vector<std::pair<fs::path, std::string>> files;
  for (const char* name : kFiles) files.emplace_back(run / name, std::string());
  for (const auto& entry : fs::recursive_directory_iterator(run))
    if (entry.is_regular_file() &&
        std::find_if(files.begin(), files.end(), [&](const auto& f) { return f.first == entry.path(); }) == files.end())
      files.emplace_back(entry.path(), std::string());
  for (auto& [path, bytes] : files) bytes = photorig::fuzz::ReadBytes(path);
  return files;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const fs::path run = WriteValidRun(photorig::fuzz::WorkDir() / "run");
  static const std::vector<std::pair<fs::path, std::string>> originals = ReadFiles(run);
  if (size == 0) return 0;
  const std::size_t which = data[0] % kFiles.size();
  photorig::fuzz::WriteBytes(run / kFiles[which], data + 1, size - 1);
  if (which == 1) {
    try {
      RecoveryReport report;
      RunWriter::Reopen(run.string(), &report);
    } catch (const std::runtime_error&) {
    }
  } else {
    try {
      const RunManifest manifest = LoadRunManifest(run.string());
      for (const FrameRecord& frame : manifest.frames) LoadFrame(run.string(), frame);
    } catch (const std::runtime_error&) {
    }
    try {
      VerifyRun(run.string());
    } catch (const std::runtime_error&) {
    }
  }
  // Put the run back as it was: Reopen rewrites the journal and removes the
  // frames a journal does not vouch for; the readers change nothing.
  if (which == 1) {
    fs::remove_all(run);
    fs::create_directories(run / "frames");
    for (const auto& [path, bytes] : originals) photorig::fuzz::WriteText(path, bytes);
  } else {
    photorig::fuzz::WriteText(run / kFiles[which], originals[which].second);
  }
  return 0;
}
