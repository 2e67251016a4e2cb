#pragma once
// Saving and loading a colour model (JSON or YAML, chosen by the file's
// extension) and the calibration report.

#include "photorig/solvers/color/calibration.h"
#include "photorig/solvers/color/chart.h"

#include <nlohmann/json.hpp>

#include <string>

namespace photorig::solvers::color {

nlohmann::json ModelToJson(const ColorModel& model);
// Throws std::invalid_argument naming `source` and the offending key.
ColorModel ModelFromJson(const nlohmann::json& json, const std::string& source);

// ".json", ".yaml" or ".yml". Throws std::runtime_error naming the file.
std::string SerializeModel(const ColorModel& model, const std::string& path_for_format);
ColorModel ParseModel(const std::string& text, const std::string& path);

// Per-model training and held-out errors, per-patch CIEDE2000 of every model,
// the measurements and the choice. `measurements` may be empty.
nlohmann::json CalibrationReport(const CalibrationSummary& summary, const std::vector<PatchMeasurement>& measurements,
                                 const std::vector<std::string>& patch_names);
// The same for people: a model table and the chosen model's per-patch table.
std::string FormatCalibrationReport(const CalibrationSummary& summary, const std::vector<std::string>& patch_names);

}  // namespace photorig::solvers::color
