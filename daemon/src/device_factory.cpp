#include "photorig/daemon/device_factory.h"

#include "photorig/daemon/camera_options.h"
#include "photorig/daemon/hardware_options.h"
#include "photorig/drivers/gpio/gpio_lights.h"
#include "photorig/sim/devices.h"
#include "photorig/sim/gonio.h"

#include <functional>
#include <stdexcept>
#include <vector>

namespace photorig::daemon {
namespace {

using LightFactory = std::function<std::unique_ptr<drivers::LightController>(const DeviceContext&)>;
using CameraFactory = std::function<std::unique_ptr<drivers::Camera>(const DeviceContext&)>;

template <typename Factory>
struct Entry {
  const char* name;
  Factory make;
};

void RequireWorld(const DeviceContext& context, const char* what) {
  if (!context.world) throw std::logic_error(std::string(what) + " needs the rig's sim: section");
}

const std::vector<Entry<LightFactory>>& LightDrivers() {
  static const std::vector<Entry<LightFactory>> drivers = {
      {"sim",
       [](const DeviceContext& c) -> std::unique_ptr<drivers::LightController> {
         RequireWorld(c, "the simulated light dome");
         return std::make_unique<sim::SimLightDome>(c.rig.lights.id, c.world);
       }},
      {"modbus-tcp", [](const DeviceContext& c) { return MakeModbusLights(c, false); }},
      {"modbus-rtu", [](const DeviceContext& c) { return MakeModbusLights(c, true); }},
      {"gpio", [](const DeviceContext& c) { return MakeGpioLights(c); }},
      {"usb-relay", [](const DeviceContext& c) { return MakeUsbRelayLights(c); }},
  };
  return drivers;
}

const std::vector<Entry<CameraFactory>>& CameraDrivers() {
  static const std::vector<Entry<CameraFactory>> drivers = {
      {"sim",
       [](const DeviceContext& c) -> std::unique_ptr<drivers::Camera> {
         RequireWorld(c, "the simulated camera");
         return std::make_unique<sim::SimCamera>(c.rig.camera.id, c.world);
       }},
      {"aravis", [](const DeviceContext& c) { return MakeAravisCamera(c); }},
      {"v4l2", [](const DeviceContext& c) { return MakeV4l2Camera(c); }},
  };
  return drivers;
}

template <typename Factory>
const Entry<Factory>* Find(const std::vector<Entry<Factory>>& table, const std::string& name) {
  for (const auto& entry : table)
    if (name == entry.name) return &entry;
  return nullptr;
}

template <typename Factory>
std::string Names(const std::vector<Entry<Factory>>& table) {
  std::string names;
  for (const auto& entry : table) names += std::string(names.empty() ? "" : ", ") + entry.name;
  return names;
}

}  // namespace

bool IsKnownLightDriver(const std::string& name) { return Find(LightDrivers(), name) != nullptr; }
bool IsKnownCameraDriver(const std::string& name) { return Find(CameraDrivers(), name) != nullptr; }
std::string LightDriverNames() { return Names(LightDrivers()); }
std::string CameraDriverNames() { return Names(CameraDrivers()); }

std::unique_ptr<drivers::LightController> MakeLightController(const DeviceContext& context) {
  const auto* entry = Find(LightDrivers(), context.rig.lights.driver);
  if (!entry) throw std::invalid_argument("unknown light driver '" + context.rig.lights.driver + "'");
  return entry->make(context);
}

std::unique_ptr<drivers::Camera> MakeCamera(const DeviceContext& context) {
  const auto* entry = Find(CameraDrivers(), context.rig.camera.driver);
  if (!entry) throw std::invalid_argument("unknown camera driver '" + context.rig.camera.driver + "'");
  return entry->make(context);
}

std::unique_ptr<drivers::TriggerOutput> MakeTriggerOutput(const DeviceContext& context) {
  const TriggerConfig& trigger = context.rig.camera.trigger;
  if (trigger.mode != drivers::TriggerMode::kHardware) return nullptr;
  const std::string id = context.rig.camera.id + "-trigger";
  if (trigger.output_driver == "sim") {
    RequireWorld(context, "the simulated trigger wire");
    return std::make_unique<sim::SimTriggerLine>(id, context.world);
  }
  const YamlNode& output = *trigger.output;
  const int offset = output["offset"].AsInt();
  if (offset < 0) output["offset"].Fail("must be >= 0");
  return std::make_unique<drivers::GpioTriggerLine>(
      id, drivers::GpioLine{output.String("chip", "gpiochip0"), static_cast<unsigned>(offset), output.Bool("active_low", false)},
      drivers::MakeLibgpiodBackend());
}

MotionRig MakeMotion(const DeviceContext& context) {
  if (!context.rig.motion) return {};
  const MotionConfig& motion = *context.rig.motion;
  if (motion.driver != "sim") return MakeModbusMotion(motion);
  RequireWorld(context, "the simulated gonioreflectometer");
  sim::SimAxisOptions options;
  options.time_scale = motion.source.Double("time_scale", options.time_scale);
  std::string why;
  if (!options.IsValid(&why)) motion.source["time_scale"].Fail(why);
  MotionRig rig;
  std::vector<drivers::Motion*> axes;
  for (const AxisConfig& axis : motion.axes) {
    sim::SimAxisOptions axis_options = options;
    if (context.rig.sim && context.rig.sim->axis_faults.count(axis.id))
      axis_options.faults = context.rig.sim->axis_faults.at(axis.id);
    rig.axes.push_back(std::make_unique<sim::SimRotaryAxis>(
        axis.id, axis.limits, motion.settle, axis_options,
        // The drive counts from its home switch, which sits at home_deg on the rig.
        [world = context.world, id = axis.id, home = axis.limits.home_deg](double deg) {
          world->SetArm(id, deg + home);
        }));
    axes.push_back(rig.axes.back().get());
  }
  rig.goniometer = std::make_unique<drivers::Goniometer>(axes, motion.constraints);
  return rig;
}

}  // namespace photorig::daemon
