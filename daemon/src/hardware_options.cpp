#include "photorig/daemon/hardware_options.h"

#include "photorig/drivers/gpio/gpio_lights.h"
#include "photorig/drivers/usbrelay/usb_relay.h"
#include "photorig/sim/modbus/led_peer.h"
#include "photorig/sim/modbus/server.h"

#include <set>

namespace photorig::daemon {
namespace {

template <typename Options>
void Check(const YamlNode& node, const Options& options) {
  std::string why;
  if (!options.IsValid(&why)) node.Fail(why);
}

int IntIn(const YamlNode& node, const std::string& key, int fallback, int low, int high) {
  const int value = node.Int(key, fallback);
  if (value < low || value > high)
    node[key].Fail("must be within [" + std::to_string(low) + ", " + std::to_string(high) + "]");
  return value;
}

std::set<std::uint64_t> Indices(const YamlNode& node, const char* key) {
  std::set<std::uint64_t> values;
  if (auto list = node.Find(key))
    for (const YamlNode& item : list->Items()) {
      if (item.AsInt() < 0) item.Fail("must be >= 0");
      values.insert(static_cast<std::uint64_t>(item.AsInt()));
    }
  return values;
}

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

const char* kLinkKeys[] = {"unit_id", "response_timeout_ms", "byte_timeout_ms", "retries", "retry_backoff_ms"};

}  // namespace

drivers::ModbusLinkOptions ParseModbusLink(const YamlNode& options, bool rtu) {
  drivers::ModbusLinkOptions link;
  link.transport = rtu ? drivers::ModbusLinkOptions::Transport::kRtu : drivers::ModbusLinkOptions::Transport::kTcp;
  if (rtu) {
    link.serial_device = options["device"].AsString();
    link.baud = IntIn(options, "baud", link.baud, 1, 4000000);
    const std::string parity = options.String("parity", "N");
    if (parity != "N" && parity != "E" && parity != "O") options["parity"].Fail("must be N, E or O");
    link.parity = parity[0];
    link.data_bits = IntIn(options, "data_bits", link.data_bits, 5, 8);
    link.stop_bits = IntIn(options, "stop_bits", link.stop_bits, 1, 2);
  } else {
    link.host = options["host"].AsString();
    link.port = IntIn(options, "port", link.port, 0, 65535);
  }
  link.unit_id = IntIn(options, kLinkKeys[0], link.unit_id, 0, 247);
  link.response_timeout_ms = IntIn(options, kLinkKeys[1], link.response_timeout_ms, 1, 60000);
  link.byte_timeout_ms = IntIn(options, kLinkKeys[2], link.byte_timeout_ms, 1, 60000);
  link.retries = IntIn(options, kLinkKeys[3], link.retries, 0, 100);
  link.retry_backoff_ms = IntIn(options, kLinkKeys[4], link.retry_backoff_ms, 0, 60000);
  Check(options, link);
  return link;
}

drivers::ModbusLightMap ParseModbusLightMap(const YamlNode& options, int channels) {
  drivers::ModbusLightMap map;
  map.channels = channels;
  if (auto node = options.Find("map")) {
    node->ExpectKeys({"on_off", "on_off_address", "intensity", "intensity_address", "full_scale"});
    const std::string on_off = node->String("on_off", "coils");
    if (!drivers::ParseModbusSwitch(on_off, &map.on_off))
      (*node)["on_off"].Fail("unknown '" + on_off + "' (expected coils, bitmask or none)");
    map.on_off_address = IntIn(*node, "on_off_address", map.on_off_address, 0, 65535);
    map.intensity = node->Bool("intensity", map.intensity);
    map.intensity_address = IntIn(*node, "intensity_address", map.intensity_address, 0, 65535);
    map.full_scale = IntIn(*node, "full_scale", map.full_scale, 1, 65535);
    Check(*node, map);
  }
  return map;
}

drivers::LightSafetyOptions ParseLightSafety(const YamlNode& safety, int channels) {
  safety.ExpectKeys({"max_on_ms", "max_duty", "duty_window_ms", "watchdog_ms", "channels"});
  drivers::LightSafetyOptions options;
  options.defaults.max_on_ms = safety.Double("max_on_ms", options.defaults.max_on_ms);
  options.defaults.max_duty = safety.Double("max_duty", options.defaults.max_duty);
  options.duty_window_ms = safety.Double("duty_window_ms", options.duty_window_ms);
  options.watchdog_ms = safety.Double("watchdog_ms", options.watchdog_ms);
  if (auto per = safety.Find("channels")) {
    options.per_channel.assign(channels, options.defaults);
    for (const std::string& key : per->Keys()) {
      const YamlNode entry = (*per)[key];
      entry.ExpectKeys({"max_on_ms", "max_duty"});
      int channel = -1;
      try {
        channel = std::stoi(key);
      } catch (const std::exception&) {
      }
      if (channel < 0 || channel >= channels)
        entry.Fail("channel '" + key + "' is not within [0, " + std::to_string(channels - 1) + "]");
      options.per_channel[channel].max_on_ms = entry.Double("max_on_ms", options.defaults.max_on_ms);
      options.per_channel[channel].max_duty = entry.Double("max_duty", options.defaults.max_duty);
    }
  }
  std::string why;
  if (!options.IsValid(channels, &why)) safety.Fail(why);
  return options;
}

std::unique_ptr<drivers::LightController> WithSafety(std::unique_ptr<drivers::LightController> lights,
                                                     const DeviceContext& context) {
  drivers::LightSafetyOptions limits;
  if (context.rig.lights.options)
    if (auto safety = context.rig.lights.options->Find("safety"))
      limits = ParseLightSafety(*safety, lights->channel_count());
  return std::make_unique<drivers::SafeLightController>(std::move(lights), limits);
}

std::unique_ptr<drivers::LightController> MakeModbusLights(const DeviceContext& context, bool rtu) {
  const LightsConfig& lights = context.rig.lights;
  if (!lights.options) throw ConfigError(context.rig.path, 0, 0, "lights.options", "the Modbus driver needs options");
  const YamlNode& options = *lights.options;
  if (rtu)
    options.ExpectKeys({"device", "baud", "parity", "data_bits", "stop_bits", "unit_id", "response_timeout_ms",
                        "byte_timeout_ms", "retries", "retry_backoff_ms", "verify", "map", "safety", "sim_faults"});
  else
    options.ExpectKeys({"host", "port", "unit_id", "response_timeout_ms", "byte_timeout_ms", "retries",
                        "retry_backoff_ms", "verify", "map", "safety", "sim_faults"});
  const int channels = static_cast<int>(lights.leds.size());
  const drivers::ModbusLightMap map = ParseModbusLightMap(options, channels);
  const bool verify = options.Bool("verify", true);
  // "sim" as host/device: serve a simulated controller bound to the World in this process.
  const bool served = options.String(rtu ? "device" : "host", "") == "sim";
  if (!served) {
    if (options.Has("sim_faults")) options["sim_faults"].Fail("only for a simulated controller (host: sim)");
    return WithSafety(std::make_unique<drivers::ModbusLightController>(lights.id, ParseModbusLink(options, rtu), map,
                                                                       verify),
                      context);
  }
  if (!context.world) options.Fail("a simulated Modbus controller needs the rig's sim: section");
  sim::ModbusServerOptions server_options;
  if (auto faults = options.Find("sim_faults")) {
    faults->ExpectKeys({"exception_at", "disconnect_at", "exception_addresses"});
    server_options.faults.exception_at = Indices(*faults, "exception_at");
    server_options.faults.disconnect_at = Indices(*faults, "disconnect_at");
    for (std::uint64_t address : Indices(*faults, "exception_addresses"))
      server_options.faults.exception_addresses.insert(static_cast<int>(address));
  }
  server_options.unit_id = IntIn(options, "unit_id", 1, 1, 247);
  auto server = std::make_unique<sim::SimModbusServer>(server_options);
  server->AddPeer(std::make_shared<sim::SimModbusLedController>(map, context.world));
  Status started = rtu ? server->StartRtu() : server->StartTcp("127.0.0.1", options.Int("port", 0));
  if (!started.ok()) options.Fail(started.message());
  drivers::ModbusLinkOptions link;
  link.transport = rtu ? drivers::ModbusLinkOptions::Transport::kRtu : drivers::ModbusLinkOptions::Transport::kTcp;
  link.host = "127.0.0.1";
  link.port = server->port();
  link.serial_device = server->rtu_path();
  link.baud = server_options.rtu_baud;
  link.unit_id = server_options.unit_id;
  link.response_timeout_ms = IntIn(options, kLinkKeys[1], link.response_timeout_ms, 1, 60000);
  link.byte_timeout_ms = IntIn(options, kLinkKeys[2], link.byte_timeout_ms, 1, 60000);
  link.retries = IntIn(options, kLinkKeys[3], link.retries, 0, 100);
  link.retry_backoff_ms = IntIn(options, kLinkKeys[4], link.retry_backoff_ms, 0, 60000);
  auto client = std::make_unique<drivers::ModbusLightController>(lights.id, link, map, verify);
  return WithSafety(std::make_unique<ServedModbusLights>(std::move(server), std::move(client)), context);
}

std::unique_ptr<drivers::LightController> MakeGpioLights(const DeviceContext& context) {
  const LightsConfig& lights = context.rig.lights;
  if (!lights.options) throw ConfigError(context.rig.path, 0, 0, "lights.options", "the GPIO driver needs options");
  const YamlNode& options = *lights.options;
  // options: {chip: gpiochip0, active_low: false, lines: [offset per LED] or [{chip, offset, active_low}], safety}
  options.ExpectKeys({"chip", "active_low", "lines", "safety"});
  const std::string chip = options.String("chip", "gpiochip0");
  const bool active_low = options.Bool("active_low", false);
  std::vector<drivers::GpioLine> lines;
  for (const YamlNode& item : options["lines"].Items()) {
    drivers::GpioLine line{chip, 0, active_low};
    if (item.IsMap()) {
      item.ExpectKeys({"chip", "offset", "active_low"});
      line.chip = item.String("chip", chip);
      line.offset = static_cast<unsigned>(IntIn(item, "offset", -1, 0, 4095));
      line.active_low = item.Bool("active_low", active_low);
    } else {
      const int offset = item.AsInt();
      if (offset < 0) item.Fail("must be >= 0");
      line.offset = static_cast<unsigned>(offset);
    }
    lines.push_back(line);
  }
  if (lines.size() != lights.leds.size())
    options["lines"].Fail("lists " + std::to_string(lines.size()) + " lines for " +
                          std::to_string(lights.leds.size()) + " LEDs");
  return WithSafety(
      std::make_unique<drivers::GpioLightController>(lights.id, std::move(lines), drivers::MakeLibgpiodBackend()),
      context);
}

std::unique_ptr<drivers::LightController> MakeUsbRelayLights(const DeviceContext& context) {
  const LightsConfig& lights = context.rig.lights;
  std::string serial;
  if (lights.options) {
    lights.options->ExpectKeys({"serial", "safety"});
    serial = lights.options->String("serial", "");
  }
  const int channels = static_cast<int>(lights.leds.size());
  if (channels > 8)
    throw ConfigError(context.rig.path, 0, 0, "lights.leds", "a USB relay board drives at most 8 LEDs");
  return WithSafety(std::make_unique<drivers::UsbRelayLightController>(
                        lights.id, channels, [serial] { return drivers::OpenUsbRelayBoard(serial); }),
                    context);
}

MotionRig MakeModbusMotion(const MotionConfig& motion) {
  const YamlNode link_node = motion.source["link"];
  link_node.ExpectKeys({"host", "port", "unit_id", "response_timeout_ms", "byte_timeout_ms", "retries",
                        "retry_backoff_ms"});
  const drivers::ModbusLinkOptions link = ParseModbusLink(link_node, false);
  MotionRig rig;
  std::vector<drivers::Motion*> axes;
  for (const AxisConfig& axis : motion.axes) {
    rig.axes.push_back(std::make_unique<drivers::ModbusDriveAxis>(
        axis.id, link, IntIn(axis.source, "base_address", 0, 0, 65535 - drivers::drive_profile::kRegisterCount),
        axis.limits, motion.settle));
    axes.push_back(rig.axes.back().get());
  }
  rig.goniometer = std::make_unique<drivers::Goniometer>(axes, motion.constraints);
  if (Status valid = rig.goniometer->Validate(); !valid.ok()) motion.source.Fail(valid.message());
  return rig;
}

}  // namespace photorig::daemon
