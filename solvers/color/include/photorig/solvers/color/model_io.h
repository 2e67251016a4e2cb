#pragma once
// Saving and loading a colour model (JSON or YAML, chosen by the file's
// extension) and the calibration report.

#include "photorig/solvers/color/calibration.h"
#include "photorig/solvers/color/chart.h"

#include <nlohmann/json.hpp>

#include <string>

namespace photorig::solvers::color {

nlohmann::json ModelToJson(const ColorModel& model);
// A parser of files, not a solver: throws std::invalid_argument naming
// `source` and the offending key.
ColorModel ModelFromJson(const nlohmann::json& json, const std::string& source);

// YAML for a path ending ".yaml" or ".yml", else JSON.
std::string SerializeModel(const ColorModel& model, const std::string& path_for_format);
// `text` read from `path` (its extension picks the format). Throws
// std::invalid_argument naming `path`: not JSON or YAML, or as ModelFromJson.
ColorModel ParseModel(const std::string& text, const std::string& path);

// Per-model training and held-out errors, per-patch CIEDE2000 of every model,
// the measurements and the choice. `measurements` may be empty.
nlohmann::json CalibrationReport(const CalibrationSummary& summary, const std::vector<PatchMeasurement>& measurements,
                                 const std::vector<std::string>& patch_names);
// The same for people: a model table and the chosen model's per-patch table.
std::string FormatCalibrationReport(const CalibrationSummary& summary, const std::vector<std::string>& patch_names);

}  // namespace photorig::solvers::color
