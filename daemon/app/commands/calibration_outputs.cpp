#include "calibration_outputs.h"

#include <filesystem>

namespace photorig::app {

std::string CalibrationOutputs::Directory(const std::string& run_dir, const std::string& family) const {
  if (!out.empty()) return out;
  return (std::filesystem::path(run_dir) / "results" / family).string();
}

void AddCalibrationOutputOptions(CLI::App* calibrate, CalibrationOutputs* outputs, const std::string& rig_help,
                                 const std::string& family) {
  calibrate->add_option("--rig", outputs->rig, rig_help)->check(CLI::ExistingFile);
  calibrate->add_option("--out-rig", outputs->out_rig, "new rig YAML to write");
  calibrate->add_option("--out", outputs->out, "output directory (default: RUN/results/" + family + ")");
}

}  // namespace photorig::app
