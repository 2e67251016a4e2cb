#pragma once
// The short summaries of solver results that several commands print, and
// their JSON form (docs/cli.md).

#include "photorig/daemon/light_calibration.h"
#include "photorig/daemon/ps_pipeline.h"

#include <nlohmann/json.hpp>

namespace photorig::app {
void PrintPhotometricStereoSummary(const daemon::PhotometricStereoResult& result);
nlohmann::json LightCalibrationJson(const daemon::LightCalibrationSummary& summary);
}
