#pragma once
// Each driver's device makers, which device_factory.cpp's tables name by the
// driver names rig files use. The settings they read were parsed and checked
// by LoadRigConfig (photorig/config/driver_options.h).
//
// Cameras (camera_makers.cpp):
//
//   camera:
//     driver: aravis
//     options:
//       device: "192.168.1.20"      # Aravis id, serial number or IP address; absent = the only camera
//       buffer_count: 4
//       packet_resend: true
//       packet_socket: false
//       timeout_margin_ms: 200
//       link_bandwidth_mbps: 1000
//       reconnect_attempts: 3
//       reconnect_delay_ms: 250
//       sim_gige:                   # simulated rigs only: start a GigE Vision camera rendering the sim World
//         address: 127.0.0.1
//         serial: SIMGV0
//         lost_packet_ratio: 0.0
//         trigger_poll_hz: 500
//
//   camera:
//     driver: v4l2
//     options: {device: /dev/video0, buffer_count: 4}
//
// Light controllers (hardware_makers.cpp): modbus-tcp and modbus-rtu (with
// `host: sim` or `device: sim` the process also serves a simulated controller
// bound to the World), gpio, usb-relay. Motion: the axes of a
// `motion: {driver: modbus-tcp}` section, one drive per axis on the shared
// `link:`, each at its axis entry's base_address.

#include "photorig/daemon/capture/device_context.h"
#include "photorig/drivers/camera.h"
#include "photorig/drivers/light_controller.h"

#include <memory>

namespace photorig::daemon {

using LightMaker = std::unique_ptr<drivers::LightController> (*)(const DeviceContext& context);
using CameraMaker = std::unique_ptr<drivers::Camera> (*)(const DeviceContext& context);

std::unique_ptr<drivers::LightController> MakeModbusLights(const DeviceContext& context);
#if PHOTORIG_HAVE_DRIVERS_GPIO
std::unique_ptr<drivers::LightController> MakeGpioLights(const DeviceContext& context);
#endif
#if PHOTORIG_HAVE_DRIVERS_USBRELAY
std::unique_ptr<drivers::LightController> MakeUsbRelayLights(const DeviceContext& context);
#endif
#if PHOTORIG_HAVE_DRIVERS_ARAVIS
std::unique_ptr<drivers::Camera> MakeAravisCamera(const DeviceContext& context);
#endif
#if PHOTORIG_HAVE_DRIVERS_V4L2
std::unique_ptr<drivers::Camera> MakeV4l2Camera(const DeviceContext& context);
#endif

MotionRig MakeModbusMotion(const config::MotionConfig& motion);

}  // namespace photorig::daemon
