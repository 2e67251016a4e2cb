#include "photorig/daemon/capture/internal/device_makers.h"

#include "photorig/drivers/light_safety.h"
#include "photorig/drivers/modbus/modbus_lights.h"
#include "photorig/drivers/motion/modbus_drive.h"
#include "photorig/sim/modbus/led_peer.h"
#include "photorig/sim/modbus/server.h"

#if PHOTORIG_HAVE_DRIVERS_GPIO
#include "photorig/drivers/gpio/gpio_lights.h"
#endif
#if PHOTORIG_HAVE_DRIVERS_USBRELAY
#include "photorig/drivers/usbrelay/usb_relay.h"
#endif

#include <stdexcept>

namespace photorig::daemon {
namespace {

// A Modbus light controller whose peer is a simulated controller this process
// serves on loopback, bound to the rig's World: the real driver over real TCP.
class ServedModbusLights : public drivers::LightController {
 public:
  ServedModbusLights(std::unique_ptr<sim::SimModbusServer> server, std::unique_ptr<drivers::LightController> inner)
      : LightController(inner->id()), server_(std::move(server)), inner_(std::move(inner)) {}
  ~ServedModbusLights() override { (void)Close(); }
  int channel_count() const override { return inner_->channel_count(); }

 protected:
  Status DoOpen() override { return inner_->Open(); }
  Status DoSetPattern(const drivers::LightPattern& pattern) override { return inner_->SetPattern(pattern); }
  Result<drivers::LightPattern> DoReadBack() override { return inner_->ReadBack(); }
  Status DoClose() override { return inner_->Close(); }

 private:
  std::unique_ptr<sim::SimModbusServer> server_;  // declared first: outlives the client
  std::unique_ptr<drivers::LightController> inner_;
};

// Puts a hardware controller behind the SafeLightController with the rig's limits.
std::unique_ptr<drivers::LightController> WithSafety(std::unique_ptr<drivers::LightController> lights,
                                                     const DeviceContext& context) {
  return std::make_unique<drivers::SafeLightController>(std::move(lights), context.rig.lights.safety);
}

}  // namespace

std::unique_ptr<drivers::LightController> MakeModbusLights(const DeviceContext& context) {
  const config::LightsConfig& lights = context.rig.lights;
  const config::ModbusLightsOptions& options = *lights.modbus;
  if (!options.simulated)
    return WithSafety(
        std::make_unique<drivers::ModbusLightController>(lights.id, options.link, options.map, options.verify),
        context);
  if (!context.world) throw std::logic_error("a simulated Modbus controller needs the rig's sim: section");
  sim::ModbusServerOptions server_options;
  server_options.faults = options.sim_faults;
  server_options.unit_id = options.link.unit_id;
  auto server = std::make_unique<sim::SimModbusServer>(server_options);
  server->AddPeer(std::make_shared<sim::SimModbusLedController>(options.map, context.world));
  const bool rtu = options.link.transport == drivers::ModbusLinkOptions::Transport::kRtu;
  const Status started = rtu ? server->StartRtu() : server->StartTcp("127.0.0.1", options.sim_port);
  if (!started.ok()) throw std::runtime_error("simulated Modbus controller '" + lights.id + "': " + started.message());
  drivers::ModbusLinkOptions link = options.link;  // the timeouts and retries the rig gives
  link.host = "127.0.0.1";
  link.port = server->port();
  link.serial_device = server->rtu_path();
  link.baud = server_options.rtu_baud;
  auto client = std::make_unique<drivers::ModbusLightController>(lights.id, link, options.map, options.verify);
  return WithSafety(std::make_unique<ServedModbusLights>(std::move(server), std::move(client)), context);
}

#if PHOTORIG_HAVE_DRIVERS_GPIO
std::unique_ptr<drivers::LightController> MakeGpioLights(const DeviceContext& context) {
  const config::LightsConfig& lights = context.rig.lights;
  return WithSafety(
      std::make_unique<drivers::GpioLightController>(lights.id, lights.gpio->lines, drivers::MakeLibgpiodBackend(),
                                                     lights.gpio->heartbeat),
      context);
}
#endif

#if PHOTORIG_HAVE_DRIVERS_USBRELAY
std::unique_ptr<drivers::LightController> MakeUsbRelayLights(const DeviceContext& context) {
  const config::LightsConfig& lights = context.rig.lights;
  const std::string serial = lights.usb_relay->serial;
  return WithSafety(std::make_unique<drivers::UsbRelayLightController>(
                        lights.id, static_cast<int>(lights.leds.size()),
                        [serial] { return drivers::OpenUsbRelayBoard(serial); }),
                    context);
}
#endif

MotionRig MakeModbusMotion(const config::MotionConfig& motion) {
  MotionRig rig;
  std::vector<drivers::Motion*> axes;
  for (const config::AxisConfig& axis : motion.axes) {
    rig.axes.push_back(std::make_unique<drivers::ModbusDriveAxis>(axis.id, motion.link, axis.base_address,
                                                                  axis.limits, motion.settle));
    axes.push_back(rig.axes.back().get());
  }
  rig.goniometer = std::make_unique<drivers::Goniometer>(axes, motion.constraints);
  return rig;
}

}  // namespace photorig::daemon
