#include "photorig/daemon/camera_options.h"

#include "photorig/drivers/aravis_camera.h"
#include "photorig/drivers/v4l2_camera.h"
#include "photorig/sim/gige_camera.h"

namespace photorig::daemon {

std::unique_ptr<drivers::Camera> MakeAravisCamera(const DeviceContext& context) {
  const CameraConfig& camera = context.rig.camera;
  drivers::AravisCameraOptions options;
  std::optional<sim::GigeFakeCameraOptions> fake;
  if (camera.options) {
    const YamlNode& node = *camera.options;
    node.ExpectKeys({"device", "buffer_count", "packet_resend", "timeout_margin_ms", "link_bandwidth_mbps",
                     "reconnect_attempts", "reconnect_delay_ms", "sim_gige"});
    options.device = node.String("device", options.device);
    options.buffer_count = node.Int("buffer_count", options.buffer_count);
    options.packet_resend = node.Bool("packet_resend", options.packet_resend);
    options.timeout_margin_ms = node.Int("timeout_margin_ms", options.timeout_margin_ms);
    options.link_bandwidth_mbps = node.Double("link_bandwidth_mbps", options.link_bandwidth_mbps);
    options.reconnect_attempts = node.Int("reconnect_attempts", options.reconnect_attempts);
    options.reconnect_delay_ms = node.Int("reconnect_delay_ms", options.reconnect_delay_ms);
    std::string why;
    if (!options.IsValid(&why)) node.Fail(why);
    if (auto sim_node = node.Find("sim_gige")) {
      if (!context.world) sim_node->Fail("sim_gige needs the rig's sim: section (it renders the simulated World)");
      sim_node->ExpectKeys({"address", "serial", "lost_packet_ratio", "trigger_poll_hz"});
      sim::GigeFakeCameraOptions f;
      f.address = sim_node->String("address", f.address);
      f.serial = sim_node->String("serial", f.serial);
      f.lost_packet_ratio = sim_node->Double("lost_packet_ratio", f.lost_packet_ratio);
      f.trigger_poll_hz = sim_node->Double("trigger_poll_hz", f.trigger_poll_hz);
      if (!f.IsValid(&why)) sim_node->Fail(why);
      if (options.device.empty()) options.device = f.serial;
      fake = f;
    }
  }
  if (fake) return std::make_unique<sim::AravisCameraOnGigeFake>(camera.id, options, context.world, *fake);
  return std::make_unique<drivers::AravisCamera>(camera.id, options);
}

std::unique_ptr<drivers::Camera> MakeV4l2Camera(const DeviceContext& context) {
  const CameraConfig& camera = context.rig.camera;
  drivers::V4l2CameraOptions options;
  if (camera.options) {
    const YamlNode& node = *camera.options;
    node.ExpectKeys({"device", "buffer_count"});
    options.device = node.String("device", options.device);
    options.buffer_count = node.Int("buffer_count", options.buffer_count);
    std::string why;
    if (!options.IsValid(&why)) node.Fail(why);
  }
  return std::make_unique<drivers::V4l2Camera>(camera.id, options);
}

}  // namespace photorig::daemon
