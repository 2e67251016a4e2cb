#include "driver_options_parse.h"

#include "photorig/drivers/motion/modbus_drive.h"

#include <cstring>
#include <set>

namespace photorig::config {
namespace {

// Every driver a rig may name, with the module that implements it and
// whether that module is in this build.
struct Driver {
  const char* kind;
  const char* name;
  bool built;
};

constexpr Driver kDrivers[] = {
    {"light", "sim", true},
    {"light", "modbus-tcp", true},
    {"light", "modbus-rtu", true},
    {"light", "gpio", PHOTORIG_HAVE_DRIVERS_GPIO},
    {"light", "usb-relay", PHOTORIG_HAVE_DRIVERS_USBRELAY},
    {"camera", "sim", true},
    {"camera", "aravis", PHOTORIG_HAVE_DRIVERS_ARAVIS},
    {"camera", "v4l2", PHOTORIG_HAVE_DRIVERS_V4L2},
    {"trigger output", "sim", true},
    {"trigger output", "gpio", PHOTORIG_HAVE_DRIVERS_GPIO},
    {"motion", "sim", true},
    {"motion", "modbus-tcp", true},
};

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

// The keys every Modbus link takes besides its address: unit id, timeouts, retries.
void ParseLinkTiming(const YamlNode& options, drivers::ModbusLinkOptions* link) {
  link->response_timeout_ms = IntIn(options, "response_timeout_ms", link->response_timeout_ms, 1, 60000);
  link->byte_timeout_ms = IntIn(options, "byte_timeout_ms", link->byte_timeout_ms, 1, 60000);
  link->retries = IntIn(options, "retries", link->retries, 0, 100);
  link->retry_backoff_ms = IntIn(options, "retry_backoff_ms", link->retry_backoff_ms, 0, 60000);
}

// `rtu` selects the serial keys (device, baud, parity, ...) instead of host/port.
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
  link.unit_id = IntIn(options, "unit_id", link.unit_id, 0, 247);
  ParseLinkTiming(options, &link);
  Check(options, link);
  return link;
}

// options.map; absent = a coil per LED from 0 and no intensity registers.
drivers::ModbusLightMap ParseModbusLightMap(const YamlNode& options, int channels) {
  drivers::ModbusLightMap map;
  map.channels = channels;
  if (auto node = options.Find("map")) {
    node->ExpectKeys({"on_off", "on_off_address", "intensity", "intensity_address", "full_scale", "watchdog_address",
                      "watchdog_timeout_ms"});
    const std::string on_off = node->String("on_off", "coils");
    if (!drivers::ParseModbusSwitch(on_off, &map.on_off))
      (*node)["on_off"].Fail("unknown '" + on_off + "' (expected coils, bitmask or none)");
    map.on_off_address = IntIn(*node, "on_off_address", map.on_off_address, 0, 65535);
    map.intensity = node->Bool("intensity", map.intensity);
    map.intensity_address = IntIn(*node, "intensity_address", map.intensity_address, 0, 65535);
    map.full_scale = IntIn(*node, "full_scale", map.full_scale, 1, 65535);
    map.watchdog_address = IntIn(*node, "watchdog_address", map.watchdog_address, -1, 65535);
    map.watchdog_timeout_ms = IntIn(*node, "watchdog_timeout_ms", map.watchdog_timeout_ms, 1000, 65535);
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

ModbusLightsOptions ParseModbusLights(const YamlNode& options, int channels, bool rtu, bool simulated) {
  if (rtu)
    options.ExpectKeys({"device", "baud", "parity", "data_bits", "stop_bits", "unit_id", "response_timeout_ms",
                        "byte_timeout_ms", "retries", "retry_backoff_ms", "verify", "map", "safety", "sim_faults"});
  else
    options.ExpectKeys({"host", "port", "unit_id", "response_timeout_ms", "byte_timeout_ms", "retries",
                        "retry_backoff_ms", "verify", "map", "safety", "sim_faults"});
  ModbusLightsOptions modbus;
  modbus.map = ParseModbusLightMap(options, channels);
  modbus.verify = options.Bool("verify", true);
  modbus.simulated = options.String(rtu ? "device" : "host", "") == "sim";
  if (!modbus.simulated) {
    if (options.Has("sim_faults")) options["sim_faults"].Fail("only for a simulated controller (host: sim)");
    modbus.link = ParseModbusLink(options, rtu);
    return modbus;
  }
  if (!simulated) options.Fail("a simulated Modbus controller needs the rig's sim: section");
  if (auto faults = options.Find("sim_faults")) {
    faults->ExpectKeys({"exception_at", "disconnect_at", "exception_addresses"});
    modbus.sim_faults.exception_at = Indices(*faults, "exception_at");
    modbus.sim_faults.disconnect_at = Indices(*faults, "disconnect_at");
    for (std::uint64_t address : Indices(*faults, "exception_addresses"))
      modbus.sim_faults.exception_addresses.insert(static_cast<int>(address));
  }
  modbus.link.transport = rtu ? drivers::ModbusLinkOptions::Transport::kRtu : drivers::ModbusLinkOptions::Transport::kTcp;
  modbus.link.unit_id = IntIn(options, "unit_id", 1, 1, 247);
  if (!rtu) modbus.sim_port = IntIn(options, "port", 0, 0, 65535);
  ParseLinkTiming(options, &modbus.link);
  return modbus;
}

#if PHOTORIG_HAVE_DRIVERS_GPIO
// options: {chip: gpiochip0, active_low: false, lines: [offset per LED] or [{chip, offset, active_low}],
//           heartbeat: {chip, offset, active_low}, safety}
GpioLightsOptions ParseGpioLights(const YamlNode& options, std::size_t leds) {
  options.ExpectKeys({"chip", "active_low", "lines", "heartbeat", "safety"});
  const std::string chip = options.String("chip", "gpiochip0");
  const bool active_low = options.Bool("active_low", false);
  GpioLightsOptions gpio;
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
    gpio.lines.push_back(line);
  }
  if (gpio.lines.size() != leds)
    options["lines"].Fail("lists " + std::to_string(gpio.lines.size()) + " lines for " + std::to_string(leds) +
                          " LEDs");
  if (const std::optional<YamlNode> heartbeat = options.Find("heartbeat")) {
    heartbeat->ExpectKeys({"chip", "offset", "active_low"});
    drivers::GpioLine line{heartbeat->String("chip", chip), static_cast<unsigned>(IntIn(*heartbeat, "offset", -1, 0, 4095)),
                           heartbeat->Bool("active_low", false)};
    for (const drivers::GpioLine& led : gpio.lines)
      if (led.chip == line.chip && led.offset == line.offset)
        (*heartbeat)["offset"].Fail("line " + std::to_string(line.offset) + " of " + line.chip + " also drives an LED");
    gpio.heartbeat = line;
  }
  return gpio;
}
#endif

}  // namespace

void CheckDriver(const YamlNode& driver, const char* kind) {
  const std::string name = driver.AsString();
  std::string available;
  for (const Driver& entry : kDrivers) {
    if (std::strcmp(entry.kind, kind) != 0) continue;
    if (name == entry.name && entry.built) return;
    if (name == entry.name)
      driver.Fail("driver '" + name + "' was left out of this build (PHOTORIG_SKIP_MODULES); rebuild without it or "
                  "pick another " + kind);
    if (entry.built) available += std::string(available.empty() ? "" : ", ") + entry.name;
  }
  // "unknown driver 'x'" for lights and cameras, "unknown motion driver 'x'", "unknown trigger output 'x'".
  const std::string what = std::strcmp(kind, "motion") == 0           ? "motion driver"
                           : std::strcmp(kind, "trigger output") == 0 ? "trigger output"
                                                                      : "driver";
  driver.Fail("unknown " + what + " '" + name + "' (available: " + available + ")");
}

void ParseLightsOptions(const YamlNode& lights_node, bool simulated, LightsConfig* lights) {
  const std::optional<YamlNode> options = lights_node.Find("options");
  const int channels = static_cast<int>(lights->leds.size());
  if (lights->driver == "sim") {
    // Only the safety limits: a simulated lamp is rated like the real one it stands for.
    if (options) {
      options->ExpectKeys({"safety"});
      if (auto safety = options->Find("safety")) lights->safety = ParseLightSafety(*safety, channels);
    }
    return;
  }
  if (lights->driver == "modbus-tcp" || lights->driver == "modbus-rtu") {
    lights->modbus = ParseModbusLights(lights_node["options"], channels, lights->driver == "modbus-rtu", simulated);
  }
#if PHOTORIG_HAVE_DRIVERS_GPIO
  if (lights->driver == "gpio") {
    lights->gpio = ParseGpioLights(lights_node["options"], lights->leds.size());
  }
#endif
  if (lights->driver == "usb-relay") {
    if (channels > 8) lights_node["leds"].Fail("a USB relay board drives at most 8 LEDs");
    UsbRelayOptions relay;
    if (options) {
      options->ExpectKeys({"serial", "safety"});
      relay.serial = options->String("serial", "");
    }
    lights->usb_relay = relay;
  }
  if (options)
    if (auto safety = options->Find("safety")) lights->safety = ParseLightSafety(*safety, channels);
}

void ParseCameraOptions(const YamlNode& camera_node, bool simulated, CameraConfig* camera) {
  const std::optional<YamlNode> options = camera_node.Find("options");
  if (camera->driver == "sim") {
    if (options) options->Fail("the simulated camera takes no options");
    return;
  }
#if PHOTORIG_HAVE_DRIVERS_ARAVIS
  if (camera->driver == "aravis") {
    AravisOptions aravis;
    if (options) {
      const YamlNode& node = *options;
      node.ExpectKeys({"device", "buffer_count", "packet_resend", "packet_socket", "timeout_margin_ms", "link_bandwidth_mbps",
                       "reconnect_attempts", "reconnect_delay_ms", "sim_gige"});
      drivers::AravisCameraOptions& o = aravis.camera;
      o.device = node.String("device", o.device);
      o.buffer_count = node.Int("buffer_count", o.buffer_count);
      o.packet_resend = node.Bool("packet_resend", o.packet_resend);
      o.packet_socket = node.Bool("packet_socket", o.packet_socket);
      o.timeout_margin_ms = node.Int("timeout_margin_ms", o.timeout_margin_ms);
      o.link_bandwidth_mbps = node.Double("link_bandwidth_mbps", o.link_bandwidth_mbps);
      o.reconnect_attempts = node.Int("reconnect_attempts", o.reconnect_attempts);
      o.reconnect_delay_ms = node.Int("reconnect_delay_ms", o.reconnect_delay_ms);
      Check(node, o);
      if (auto sim_node = node.Find("sim_gige")) {
#if PHOTORIG_HAVE_SIM_GIGE
        if (!simulated) sim_node->Fail("sim_gige needs the rig's sim: section (it renders the simulated World)");
        sim_node->ExpectKeys({"address", "serial", "lost_packet_ratio", "trigger_poll_hz"});
        sim::GigeFakeCameraOptions fake;
        fake.address = sim_node->String("address", fake.address);
        fake.serial = sim_node->String("serial", fake.serial);
        fake.lost_packet_ratio = sim_node->Double("lost_packet_ratio", fake.lost_packet_ratio);
        fake.trigger_poll_hz = sim_node->Double("trigger_poll_hz", fake.trigger_poll_hz);
        Check(*sim_node, fake);
        if (o.device.empty()) o.device = fake.serial;
        aravis.sim_gige = fake;
#else
        sim_node->Fail("the simulated GigE Vision camera (sim/gige) was left out of this build (PHOTORIG_SKIP_MODULES)");
#endif
      }
    }
    camera->aravis = aravis;
  }
#endif
#if PHOTORIG_HAVE_DRIVERS_V4L2
  if (camera->driver == "v4l2") {
    drivers::V4l2CameraOptions v4l2;
    if (options) {
      options->ExpectKeys({"device", "buffer_count"});
      v4l2.device = options->String("device", v4l2.device);
      v4l2.buffer_count = options->Int("buffer_count", v4l2.buffer_count);
      Check(*options, v4l2);
    }
    camera->v4l2 = v4l2;
  }
#endif
  (void)simulated;
}

void ParseTriggerOutput(const YamlNode& output, TriggerConfig* trigger) {
#if PHOTORIG_HAVE_DRIVERS_GPIO
  if (trigger->output_driver == "gpio")
    trigger->gpio_line = drivers::GpioLine{output.String("chip", "gpiochip0"),
                                           static_cast<unsigned>(IntIn(output, "offset", -1, 0, 4095)),
                                           output.Bool("active_low", false)};
#endif
  if (trigger->output_driver == "sim")
    for (const char* key : {"chip", "offset", "active_low"})
      if (output.Has(key)) output[key].Fail("only a gpio trigger output has '" + std::string(key) + "'");
}

void ParseMotionDriver(const YamlNode& motion_node, MotionConfig* motion) {
  const auto axes = motion_node["axes"].Items();
  if (motion->driver == "sim") {
    // Beyond these the simulated arm either never arrives or jumps in one tick.
    motion->sim_axis.time_scale = motion_node.DoubleIn("time_scale", motion->sim_axis.time_scale, 0.01, 1000.0);
    std::string why;
    if (!motion->sim_axis.IsValid(&why)) motion_node["time_scale"].Fail(why);
    if (motion_node.Has("link")) motion_node["link"].Fail("only a modbus-tcp drive has a link");
    for (const YamlNode& axis : axes)
      if (axis.Has("base_address")) axis["base_address"].Fail("only a modbus-tcp drive has a base_address");
    return;
  }
  if (motion_node.Has("time_scale")) motion_node["time_scale"].Fail("only the simulated drive has a time_scale");
  const YamlNode link = motion_node["link"];
  link.ExpectKeys({"host", "port", "unit_id", "response_timeout_ms", "byte_timeout_ms", "retries", "retry_backoff_ms"});
  motion->link = ParseModbusLink(link, false);
  for (std::size_t i = 0; i < axes.size(); ++i)
    motion->axes[i].base_address = IntIn(axes[i], "base_address", 0, 0, 65535 - drivers::drive_profile::kRegisterCount);
}

}  // namespace photorig::config
