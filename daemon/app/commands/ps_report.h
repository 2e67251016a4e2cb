#pragma once
// Prints the short summary of a photometric-stereo result.

#include "photorig/daemon/ps_pipeline.h"

namespace photorig::app {
void PrintPhotometricStereoSummary(const daemon::PhotometricStereoResult& result);
}
