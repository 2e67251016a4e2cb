#pragma once
// Parsing of the `options:` maps of the hardware light drivers (modbus-tcp,
// modbus-rtu, gpio, usb-relay), the generic `options.safety` limits, and the
// gonioreflectometer motion description. Every error is a ConfigError naming
// file:line:column and the dotted key. Register maps and semantics:
// docs/lights-and-motion.md.

#include "photorig/daemon/device_factory.h"
#include "photorig/daemon/yaml_node.h"
#include "photorig/drivers/light_safety.h"
#include "photorig/drivers/modbus/modbus_lights.h"
#include "photorig/drivers/motion/goniometer.h"
#include "photorig/drivers/motion/modbus_drive.h"

#include <memory>
#include <string>
#include <vector>

namespace photorig::daemon {

// `rtu` selects the serial keys (device, baud, parity, ...) instead of host/port.
drivers::ModbusLinkOptions ParseModbusLink(const YamlNode& options, bool rtu);
// options.map; absent = a coil per LED from 0 and no intensity registers.
drivers::ModbusLightMap ParseModbusLightMap(const YamlNode& options, int channels);
// options.safety: {max_on_ms, max_duty, duty_window_ms, watchdog_ms, channels: {<index>: {max_on_ms, max_duty}}}
drivers::LightSafetyOptions ParseLightSafety(const YamlNode& safety, int channels);

std::unique_ptr<drivers::LightController> MakeModbusLights(const DeviceContext& context, bool rtu);
std::unique_ptr<drivers::LightController> MakeGpioLights(const DeviceContext& context);
std::unique_ptr<drivers::LightController> MakeUsbRelayLights(const DeviceContext& context);
// Puts any controller behind the SafeLightController with the rig's limits.
std::unique_ptr<drivers::LightController> WithSafety(std::unique_ptr<drivers::LightController> lights,
                                                     const DeviceContext& context);

// The axes of a `motion: {driver: modbus-tcp}` section (rig_config.h): one
// drive per axis on the shared `link:`, each at its axis entry's base_address.
MotionRig MakeModbusMotion(const MotionConfig& motion);

}  // namespace photorig::daemon
