#pragma once
// A simulated scan's phantom as JSON: ground_truth/phantom.json of a
// simulated tomography run, written at capture and read by the solve.

#include "photorig/sim/phantom.h"

#include <nlohmann/json.hpp>

namespace photorig::daemon {

nlohmann::json PhantomToJson(const sim::Phantom& phantom);
sim::Phantom PhantomFromJson(const nlohmann::json& json);  // throws nlohmann::json's errors

}  // namespace photorig::daemon
