#pragma once
// Prints the short summary of a photometric-stereo report.json.

#include <nlohmann/json.hpp>

namespace photorig::app {
void PrintPhotometricStereoSummary(const nlohmann::json& report);
}
