#include "photorig/daemon/io/utc_time.h"

namespace photorig::daemon {
namespace {

std::string FormatUtc(std::time_t seconds_since_epoch, const char* format) {
  std::tm utc{};
  gmtime_r(&seconds_since_epoch, &utc);
  char text[32];
  std::strftime(text, sizeof(text), format, &utc);
  return text;
}

}  // namespace

std::string UtcIso8601(std::time_t seconds_since_epoch) { return FormatUtc(seconds_since_epoch, "%Y-%m-%dT%H:%M:%SZ"); }

std::string UtcNowIso8601() { return UtcIso8601(std::time(nullptr)); }

std::string UtcNowInName() { return FormatUtc(std::time(nullptr), "%Y%m%dT%H%M%SZ"); }

}  // namespace photorig::daemon
