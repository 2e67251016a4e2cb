#pragma once
// The hardware cameras, built from the settings LoadRigConfig parsed
// (photorig/config/driver_options.h):
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

#include "photorig/daemon/device_factory.h"

#include <memory>

namespace photorig::daemon {

#if PHOTORIG_HAVE_DRIVERS_ARAVIS
std::unique_ptr<drivers::Camera> MakeAravisCamera(const DeviceContext& context);
#endif
#if PHOTORIG_HAVE_DRIVERS_V4L2
std::unique_ptr<drivers::Camera> MakeV4l2Camera(const DeviceContext& context);
#endif

}  // namespace photorig::daemon
