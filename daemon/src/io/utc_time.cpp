#include "photorig/daemon/io/utc_time.h"

namespace photorig::daemon {

std::string UtcIso8601(std::time_t seconds_since_epoch) {
  std::tm utc{};
  gmtime_r(&seconds_since_epoch, &utc);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

std::string UtcNowIso8601() { return UtcIso8601(std::time(nullptr)); }

}  // namespace photorig::daemon
