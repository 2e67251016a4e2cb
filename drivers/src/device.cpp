#include "photorig/drivers/device.h"

namespace photorig::drivers {

Status Device::DeviceError(StatusCode code, const std::string& what) const {
  return {code, kind_ + (" " + id_) + ": " + what};
}

Status Device::IllegalTransition(const char* action, const std::string& state) const {
  return DeviceError(StatusCode::kFailedPrecondition, std::string("cannot ") + action + " while " + state);
}

}  // namespace photorig::drivers
