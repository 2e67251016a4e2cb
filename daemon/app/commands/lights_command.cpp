// photorig lights off --rig FILE: switch off every output of the rig's light
// controller. For what a process that died outright (SIGKILL, a crash, the
// OOM killer) left lit on hardware without a dead-man of its own; photorigd's
// systemd unit runs it as ExecStopPost (config/systemd/photorigd.service).

#include "../command.h"
#include "../command_output.h"
#include "photorig/daemon/capture/device_factory.h"
#include "photorig/config/rig.h"
#include "photorig/config/sim.h"
#include "photorig/config/yaml_node.h"

#include <cstdio>

namespace photorig::app {
namespace {

struct Options {
  std::string rig;
};

int Execute(const Options& options) {
  const config::RigConfig rig = config::LoadRigConfig(options.rig);
  const bool outside = daemon::LightsOutliveTheProcess(rig);
  ResultFields() = {{"rig", rig.path}, {"lights", rig.lights.id}, {"driver", rig.lights.driver}, {"touched", outside}};
  if (!outside) {
    std::printf("lights %s: simulated in-process, dark with no process; nothing to do\n", rig.lights.id.c_str());
    return kExitOk;
  }
  if (const Status darkened = daemon::DarkenLights(rig); !darkened.ok())
    return Fail(kExitUnavailable, "lights " + rig.lights.id + " not switched off: " + darkened.ToString());
  std::printf("lights %s (%s): all off\n", rig.lights.id.c_str(), rig.lights.driver.c_str());
  return kExitOk;
}

CLI::App* Setup(CLI::App& app, Options* options) {
  CLI::App* group = SubcommandGroup(app, "lights", "the rig's light controller");
  CLI::App* off = group->add_subcommand("off", "switch every output of the rig's light controller off");
  off->add_option("--rig", options->rig, "rig YAML")->required()->check(CLI::ExistingFile);
  return off;
}

const bool registered = RegisterCommand<Options, Setup, Execute>();

}  // namespace
}  // namespace photorig::app
