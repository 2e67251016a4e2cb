#pragma once
// Where `calibrate lights` and `calibrate leds` put what they make from a
// run's frames: their files in --out (default RUN/results/<family>) and,
// given --rig and --out-rig, a copy of that rig with the calibrated values
// (an existing file is never overwritten).

#include <CLI/CLI.hpp>

#include <string>

namespace photorig::app {

struct CalibrationOutputs {
  std::string rig, out_rig, out;

  // The rig the new one is copied from: none unless --out-rig asks for one.
  std::string BaseRig() const { return out_rig.empty() ? "" : rig; }
  // --out, else RUN/results/<family>.
  std::string Directory(const std::string& run_dir, const std::string& family) const;
};

// --rig (what it is for in `rig_help`), --out-rig and --out.
void AddCalibrationOutputOptions(CLI::App* calibrate, CalibrationOutputs* outputs, const std::string& rig_help,
                                 const std::string& family);

}  // namespace photorig::app
