#pragma once
// What every device maker is given, and the gonioreflectometer it builds.

#include "photorig/config/rig.h"
#include "photorig/drivers/motion/goniometer.h"

#include <memory>
#include <vector>

namespace photorig::sim {
class World;  // only simulated rigs have one; the daemon's headers need no simulator header
}  // namespace photorig::sim

namespace photorig::daemon {

// `world` is non-null for rigs with a `sim:` section; simulated devices render
// from it and simulated protocol peers serve it.
struct DeviceContext {
  const config::RigConfig& rig;
  std::shared_ptr<sim::World> world;
};

// A gonioreflectometer's axes and the Goniometer that moves them under the
// rig's separation constraints. Empty for a rig without `motion:`.
struct MotionRig {
  std::vector<std::unique_ptr<drivers::Motion>> axes;
  std::unique_ptr<drivers::Goniometer> goniometer;
};

}  // namespace photorig::daemon
