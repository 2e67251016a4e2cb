// photorig: the command-line front end. Subcommands live in app/commands/.

#include "command.h"
#include "photorig/daemon/rig_config.h"
#include "signals.h"

#include <spdlog/spdlog.h>

#include <cstdio>

namespace photorig::app {

std::vector<CommandSetup>& MutableCommands() {
  static std::vector<CommandSetup> commands;
  return commands;
}
bool RegisterCommand(CommandSetup setup) {
  MutableCommands().push_back(setup);
  return true;
}
const std::vector<CommandSetup>& RegisteredCommands() { return MutableCommands(); }

CLI::App* SubcommandGroup(CLI::App& app, const std::string& name, const std::string& description) {
  const auto named = [&name](CLI::App* sub) { return sub->get_name() == name; };
  for (CLI::App* existing : app.get_subcommands(std::function<bool(CLI::App*)>(named))) return existing;
  CLI::App* group = app.add_subcommand(name, description);
  group->require_subcommand(1);
  return group;
}

}  // namespace photorig::app

int main(int argc, char** argv) {
  CLI::App app{"photorig: capture and reconstruct with a light dome (simulated or real)"};
  app.require_subcommand(1);
  std::vector<photorig::app::CommandRunner> runners;
  for (auto setup : photorig::app::RegisteredCommands()) runners.push_back(setup(app));
  CLI11_PARSE(app, argc, argv);

  spdlog::set_pattern("[%H:%M:%S.%e] [%^%l%$] %v");
  photorig::app::InstallStopHandlers();
  try {
    for (const auto& runner : runners)
      if (runner.subcommand->parsed()) return runner.run();
  } catch (const photorig::daemon::ConfigError& e) {
    std::fprintf(stderr, "configuration error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
