#pragma once
// How a result was made, written the same way by every solve that
// `photorig solve --from` repeats (photometric stereo, BRDF, tomography) as
// report.json's "provenance", and copied into the NeXus file's NXprocess:
//
//   {"program": "photorig", "version": "0.1.0", "date": "2026-11-29T12:00:00Z",
//    "options": {"stage": "photometric_stereo",
//                "request": {the stage's request in its recipe keys},
//                "loading": {how the frames were read: demosaic, colour model, mask, ...}},
//    "inputs": {"run": "/abs/run", "manifest_fnv1a64": "...", "frames": 49,
//               "frames_crc32_fnv1a64": "..."}}
//
// The request is written in the recipe's own keys, so reading it back goes
// through the recipe's parser (config/solve_requests.h) and its checks.

#include "photorig/config/solve_requests.h"

#include <nlohmann/json.hpp>

#include <string>

namespace photorig::daemon {

struct Provenance {
  std::string program = "photorig";
  std::string version;     // the build's version (CMake's PROJECT_VERSION)
  std::string date;        // UTC, ISO 8601, when the solve ran
  nlohmann::json options;  // {"stage", "request", "loading"}
  nlohmann::json inputs;   // RunInputs of the run solved

  std::string stage() const { return options.value("stage", ""); }
  nlohmann::json ToJson() const;
};

// The requests in their recipe keys: what Parse...Request reads back to the same request.
nlohmann::json RequestJson(const config::PhotometricStereoRequest& request);
nlohmann::json RequestJson(const config::TomographyRequest& request);
nlohmann::json RequestJson(const config::BrdfRequest& request);

// The run's identity as a solve reads it: its absolute path, the FNV-1a 64
// hash of manifest.json's bytes, and of the frames' CRC-32s in order (each
// frame is checked against its CRC as it loads). A folder without a manifest
// (a DiLiGenT or projection folder) gives only {"folder": path}.
nlohmann::json RunInputs(const std::string& directory);

// The provenance of a solve of `stage` (a SolveStageName) from `directory`, now.
Provenance MakeProvenance(const std::string& stage, const std::string& directory, nlohmann::json request,
                          nlohmann::json loading);

// Reads a "provenance" object. Throws std::invalid_argument naming `source`
// and what is missing (a result solved before provenance was recorded).
Provenance ProvenanceFromJson(const nlohmann::json& json, const std::string& source);

}  // namespace photorig::daemon
