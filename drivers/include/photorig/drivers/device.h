#pragma once
// What the device interfaces (Camera, LightController, TriggerOutput, Motion)
// have in common: the id the rig names the device by, which every message
// about it starts with ("camera sim-cam0: ..."), and no copies, since each
// owns one piece of hardware.

#include "photorig/drivers/status.h"

#include <string>

namespace photorig::drivers {

class Device {
 public:
  Device(const Device&) = delete;
  Device& operator=(const Device&) = delete;

  const std::string& id() const { return id_; }

 protected:
  // `kind` names the interface in messages: "camera", "light controller", ...
  Device(const char* kind, std::string id) : kind_(kind), id_(std::move(id)) {}
  ~Device() = default;  // owned and deleted through the interfaces, whose destructors are virtual

  // `what` as said of this device: "<kind> <id>: <what>".
  Status DeviceError(StatusCode code, const std::string& what) const;
  // A call the device's state, `state`, does not allow: kFailedPrecondition.
  Status IllegalTransition(const char* action, const std::string& state) const;

 private:
  const char* kind_;
  std::string id_;
};

}  // namespace photorig::drivers
