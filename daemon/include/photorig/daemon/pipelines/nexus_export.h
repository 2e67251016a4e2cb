#pragma once
// A run and its solves as one NeXus file (HDF5): the instrument (lights,
// camera, arms or turntable, the rig file verbatim), the sample, the frames as
// one compressed stack with darks and flats marked, and one NXprocess per
// solve with the program, its version, the exact options, the input checksums
// and its outputs. The layout is in docs/nexus.md.

#include "photorig/daemon/io/nexus.h"
#include "photorig/solvers/core/summary.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace photorig::daemon {

struct NexusExportOptions {
  NexusWriterOptions writer;  // the frame stack's compression
  // Solves read from results/<name>/ and written as NXprocess <name>; a
  // folder without report.json is skipped. Default: every solve photorig
  // exports (photometric stereo, BRDF, tomography).
  std::vector<std::string> results = {"ps", "brdf", "tomography"};

  bool IsValid(std::string* why) const;
};

struct NexusExportSummary : solvers::core::Summary {
  std::string path;                    // the file written
  int frames = 0;
  std::vector<std::string> processes;  // the NXprocess groups written, by results folder
  std::vector<std::string> warnings;   // what could not be included, and why
  std::uint64_t file_bytes = 0;
  std::uint64_t frame_bytes = 0;       // the run's frame files, for comparison

  // {"out", "frames", "processes", "warnings", "file_bytes", "frame_bytes", "total_ms"}
  nlohmann::json ToJson() const;
  // "wrote FILE: 49 frames, solves: ps, 9.6 MB (the frames' PNGs 14.5 MB), 650 ms"
  std::string Line() const;
};

// Writes `run_directory` as the NeXus file `path` (written beside itself and
// renamed into place whole, nexus.h). kInvalidInput names the run and what is wrong
// (no manifest, an unreadable frame); kFailure an HDF5 write that failed.
NexusExportSummary ExportNexus(const std::string& run_directory, const std::string& path,
                               const NexusExportOptions& options = {});

}  // namespace photorig::daemon
