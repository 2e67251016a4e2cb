#pragma once
// A pinhole lens in the JSON files photorig writes (run manifests, solve
// reports, `calibrate camera --json`), under the keys of a rig's
// camera.pinhole: fx_px, fy_px, cx_px, cy_px, distortion, distance_mm.

#include "photorig/solvers/camera/camera.h"

#include <nlohmann/json.hpp>

namespace photorig::daemon {

nlohmann::json PinholeLensJson(const solvers::camera::PinholeLens& lens);
// Throws nlohmann's exceptions for a missing key or a value of the wrong type.
solvers::camera::PinholeLens PinholeLensFromJson(const nlohmann::json& lens);

}  // namespace photorig::daemon
