#include "photorig/daemon/capture/device_factory.h"

#include "photorig/daemon/capture/internal/device_makers.h"
#include "photorig/drivers/light_safety.h"
#include "photorig/sim/devices.h"
#include "photorig/sim/gonio.h"

#include <stdexcept>
#include <utility>
#include <vector>

namespace photorig::daemon {
namespace {

void RequireWorld(const DeviceContext& context, const char* what) {
  if (!context.world) throw std::logic_error(std::string(what) + " needs the rig's sim: section");
}

// LoadRigConfig accepts only drivers this build has; anything else is a bug.
[[noreturn]] void NotBuilt(const char* kind, const std::string& driver) {
  throw std::logic_error(std::string("no ") + kind + " driver '" + driver + "' in this build");
}

std::unique_ptr<drivers::LightController> MakeSimLights(const DeviceContext& context) {
  RequireWorld(context, "the simulated light dome");
  // Behind the same safety layer as hardware, so that a simulated run meets
  // the limits (on-time, duty, watchdog) a real dome would.
  return std::make_unique<drivers::SafeLightController>(
      std::make_unique<sim::SimLightDome>(context.rig.lights.id, context.world), context.rig.lights.safety);
}

std::unique_ptr<drivers::Camera> MakeSimCamera(const DeviceContext& context) {
  RequireWorld(context, "the simulated camera");
  return std::make_unique<sim::SimCamera>(context.rig.camera.id, context.world);
}

// The makers by driver name, as rig files name drivers; a module this build
// lacks has no entry (LoadRigConfig refuses its name first).
const std::vector<std::pair<std::string, LightMaker>>& LightMakers() {
  static const std::vector<std::pair<std::string, LightMaker>> makers = {
      {"sim", MakeSimLights},
      {"modbus-tcp", MakeModbusLights},
      {"modbus-rtu", MakeModbusLights},
#if PHOTORIG_HAVE_DRIVERS_GPIO
      {"gpio", MakeGpioLights},
#endif
#if PHOTORIG_HAVE_DRIVERS_USBRELAY
      {"usb-relay", MakeUsbRelayLights},
#endif
  };
  return makers;
}

const std::vector<std::pair<std::string, CameraMaker>>& CameraMakers() {
  static const std::vector<std::pair<std::string, CameraMaker>> makers = {
      {"sim", MakeSimCamera},
#if PHOTORIG_HAVE_DRIVERS_ARAVIS
      {"aravis", MakeAravisCamera},
#endif
#if PHOTORIG_HAVE_DRIVERS_V4L2
      {"v4l2", MakeV4l2Camera},
#endif
  };
  return makers;
}

template <typename Maker>
Maker Find(const std::vector<std::pair<std::string, Maker>>& makers, const std::string& driver, const char* kind) {
  for (const auto& [name, make] : makers)
    if (name == driver) return make;
  NotBuilt(kind, driver);
}

}  // namespace

std::unique_ptr<drivers::LightController> MakeLightController(const DeviceContext& context) {
  return Find(LightMakers(), context.rig.lights.driver, "light")(context);
}

bool LightsOutliveTheProcess(const config::RigConfig& rig) {
  return rig.lights.driver != "sim" && !(rig.lights.modbus && rig.lights.modbus->simulated);
}

Status DarkenLights(const config::RigConfig& rig) {
  if (!LightsOutliveTheProcess(rig)) return Status::Ok();
  const std::unique_ptr<drivers::LightController> lights = MakeLightController(DeviceContext{rig, nullptr});
  const Status opened = lights->Open();
  const Status closed = lights->Close();
  return opened.ok() ? closed : opened;
}

std::unique_ptr<drivers::Camera> MakeCamera(const DeviceContext& context) {
  return Find(CameraMakers(), context.rig.camera.driver, "camera")(context);
}

std::unique_ptr<drivers::TriggerOutput> MakeTriggerOutput(const DeviceContext& context) {
  const config::TriggerConfig& trigger = context.rig.camera.trigger;
  if (trigger.mode != drivers::TriggerMode::kHardware) return nullptr;
  const std::string id = context.rig.camera.id + "-trigger";
  if (trigger.output_driver == "sim") {
    RequireWorld(context, "the simulated trigger wire");
    return std::make_unique<sim::SimTriggerLine>(id, context.world);
  }
#if PHOTORIG_HAVE_DRIVERS_GPIO
  if (trigger.output_driver == "gpio")
    return std::make_unique<drivers::GpioTriggerLine>(id, *trigger.gpio_line, drivers::MakeLibgpiodBackend());
#endif
  NotBuilt("trigger output", trigger.output_driver);
}

MotionRig MakeMotion(const DeviceContext& context) {
  if (!context.rig.motion) return {};
  const config::MotionConfig& motion = *context.rig.motion;
  if (motion.driver != "sim") return MakeModbusMotion(motion);
  RequireWorld(context, "the simulated gonioreflectometer");
  MotionRig rig;
  std::vector<drivers::Motion*> axes;
  for (const config::AxisConfig& axis : motion.axes) {
    sim::SimAxisOptions axis_options = motion.sim_axis;
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
