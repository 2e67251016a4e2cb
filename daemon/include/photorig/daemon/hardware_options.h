#pragma once
// The hardware light controllers and the Modbus gonioreflectometer drives,
// built from the settings LoadRigConfig parsed (photorig/config/driver_options.h).

#include "photorig/daemon/device_factory.h"

#include <memory>

namespace photorig::daemon {

// modbus-tcp, modbus-rtu; with `host: sim` (`device: sim`) the process also
// serves a simulated controller bound to the World.
std::unique_ptr<drivers::LightController> MakeModbusLights(const DeviceContext& context);
#if PHOTORIG_HAVE_DRIVERS_GPIO
std::unique_ptr<drivers::LightController> MakeGpioLights(const DeviceContext& context);
#endif
#if PHOTORIG_HAVE_DRIVERS_USBRELAY
std::unique_ptr<drivers::LightController> MakeUsbRelayLights(const DeviceContext& context);
#endif

// The axes of a `motion: {driver: modbus-tcp}` section: one drive per axis on
// the shared `link:`, each at its axis entry's base_address.
MotionRig MakeModbusMotion(const MotionConfig& motion);

}  // namespace photorig::daemon
