#pragma once
// A stored run opened from Python: its manifest, and its frames read on
// demand (run_store.h's LoadFrame, which checks each frame's checksum).

#include "photorig/daemon/capture/run_store.h"

#include <opencv2/core.hpp>
#include <pybind11/pybind11.h>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace photorig::python {

class Run {
 public:
  // Throws as LoadRunManifest does (ValueError / RuntimeError in Python).
  explicit Run(std::string directory);

  const std::string& directory() const { return directory_; }
  const daemon::RunManifest& manifest() const { return manifest_; }

  // The records of the frames of `kind` (CaptureStepKindName), or all of them.
  std::vector<const daemon::FrameRecord*> Select(const std::optional<std::string>& kind) const;
  // Decodes the frames on every core; each checked against its record.
  std::vector<cv::Mat> Load(const std::vector<const daemon::FrameRecord*>& records) const;

 private:
  std::string directory_;
  daemon::RunManifest manifest_;
};

// A solver's `run` argument: a Run, or its directory as a str or path.
std::string RunDirectory(const pybind11::object& run);

// A solver's `out`, else where the CLI writes without --out: RUN/results/<family>.
inline std::string ResultsFolder(const std::string& run_directory, const std::optional<std::string>& out,
                                 const char* family) {
  return out.value_or((std::filesystem::path(run_directory) / "results" / family).string());
}

inline daemon::FailedCapture FailedCapturePolicy(bool accept_failed_capture) {
  return accept_failed_capture ? daemon::FailedCapture::kAccept : daemon::FailedCapture::kRefuse;
}

}  // namespace photorig::python
