#pragma once
// A stored run opened from Python: its manifest, and its frames read on
// demand (run_store.h's LoadFrame, which checks each frame's checksum).

#include "photorig/daemon/capture/run_store.h"

#include <opencv2/core.hpp>

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

}  // namespace photorig::python
