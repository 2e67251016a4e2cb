#pragma once
// Times as every file photorig writes states them: UTC, ISO 8601 to the
// second ("2026-11-29T14:05:00Z"); in the names of the folders it makes, the
// same without separators ("20261129T140500Z").

#include <ctime>
#include <string>

namespace photorig::daemon {

std::string UtcIso8601(std::time_t seconds_since_epoch);
std::string UtcNowIso8601();
std::string UtcNowInName();

}  // namespace photorig::daemon
