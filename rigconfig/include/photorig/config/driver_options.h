#pragma once
// The settings of each driver a rig may name, parsed from its `options:` map
// (or `output:`, `link:`) when the rig is loaded, so a mistake in them is
// reported with every other configuration error, before any device exists.
// Register maps and semantics: docs/lights-and-motion.md, docs/cameras.md.
//
// A driver whose module was left out of the build (PHOTORIG_SKIP_MODULES) is
// still known by name: a rig naming it fails to load, saying so.

#include "photorig/config/modules.h"
#include "photorig/drivers/light_safety.h"
#include "photorig/drivers/modbus/modbus_lights.h"
#include "photorig/drivers/modbus/modbus_link.h"
#include "photorig/sim/gonio.h"
#include "photorig/sim/modbus/server.h"

#if PHOTORIG_HAVE_DRIVERS_ARAVIS
#include "photorig/drivers/aravis/aravis_camera.h"
#endif
#if PHOTORIG_HAVE_DRIVERS_GPIO
#include "photorig/drivers/gpio/gpio_lights.h"
#endif
#if PHOTORIG_HAVE_DRIVERS_V4L2
#include "photorig/drivers/v4l2/v4l2_camera.h"
#endif
#if PHOTORIG_HAVE_SIM_GIGE
#include "photorig/sim/gige/gige_camera.h"
#endif

#include <optional>
#include <string>
#include <vector>

namespace photorig::config {

// lights: {driver: modbus-tcp | modbus-rtu, options: {host, port | device, baud, parity, data_bits, stop_bits,
//          unit_id, response_timeout_ms, byte_timeout_ms, retries, retry_backoff_ms, verify, map, safety, sim_faults}}
struct ModbusLightsOptions {
  drivers::ModbusLinkOptions link;
  drivers::ModbusLightMap map;  // absent = a coil per LED from 0, no intensity registers
  bool verify = true;           // read the pattern back after every write
  // `host: sim` (RTU: `device: sim`): this process serves a simulated
  // controller bound to the rig's World; `link` then carries only the
  // timeouts and retries, the server decides the address.
  bool simulated = false;
  int sim_port = 0;  // TCP port of the served controller; 0 = any free one
  sim::ModbusServerFaults sim_faults;
};

#if PHOTORIG_HAVE_DRIVERS_GPIO
// lights: {driver: gpio, options: {chip, active_low, lines: [offset | {chip, offset, active_low}] (one per LED),
//                                  heartbeat: {chip, offset, active_low}}}
struct GpioLightsOptions {
  std::vector<drivers::GpioLine> lines;
  // Toggled while the process lives, for an external watchdog that powers the LEDs (gpio_lights.h).
  std::optional<drivers::GpioLine> heartbeat;
};
#endif

// lights: {driver: usb-relay, options: {serial}}
struct UsbRelayOptions {
  std::string serial;  // "" = the only board found
};

#if PHOTORIG_HAVE_DRIVERS_ARAVIS
// camera: {driver: aravis, options: {device, buffer_count, packet_resend, packet_socket, timeout_margin_ms,
//          link_bandwidth_mbps, reconnect_attempts, reconnect_delay_ms, sim_gige: {address, serial, lost_packet_ratio, trigger_poll_hz}}}
struct AravisOptions {
  drivers::AravisCameraOptions camera;
#if PHOTORIG_HAVE_SIM_GIGE
  // Simulated rigs only: start a GigE Vision camera rendering the rig's World.
  std::optional<sim::GigeFakeCameraOptions> sim_gige;
#endif
};
#endif

}  // namespace photorig::config
