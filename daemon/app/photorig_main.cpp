// photorig: the command-line front end. Subcommands live in app/commands/.

#include "command.h"
#include "command_output.h"
#include "library_logging.h"
#include "photorig/config/rig.h"
#include "photorig/config/sim.h"
#include "photorig/config/yaml_node.h"
#include "photorig/daemon/capture/run_store.h"
#include "signals.h"

#include <spdlog/spdlog.h>

#include <cstdio>
#include <cstring>

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

CLI::App* SolveGroup(CLI::App& app) { return SubcommandGroup(app, "solve", "run a solver on stored data"); }

CLI::App* CalibrateGroup(CLI::App& app) { return SubcommandGroup(app, "calibrate", "calibrate the rig"); }

namespace {

// Every command takes --json (command_output.h), and so does a group that
// runs without a subcommand (`solve --from`); other groups do not, and a
// command that declares its own keeps it.
void AddJsonFlag(CLI::App* app, bool* json_output) {
  const auto subcommands = app->get_subcommands(std::function<bool(CLI::App*)>([](CLI::App*) { return true; }));
  for (CLI::App* sub : subcommands) AddJsonFlag(sub, json_output);
  const bool runs = subcommands.empty() || app->get_require_subcommand_min() == 0;
  if (runs && app->get_parent() != nullptr && app->get_option_no_throw("--json") == nullptr)
    app->add_flag("--json", *json_output, "print one JSON document on stdout (docs/cli.md); text goes to stderr");
}

// "solve ps" for `photorig solve ps --run x`: the subcommand names the
// arguments start with, known even when parsing failed.
std::string CommandNameFromArguments(CLI::App& app, int argc, char** argv) {
  std::string name;
  CLI::App* current = &app;
  for (int i = 1; i < argc; ++i) {
    CLI::App* sub = nullptr;
    try {
      sub = current->get_subcommand(argv[i]);
    } catch (const CLI::OptionNotFound&) {
      break;
    }
    name += (name.empty() ? "" : " ") + sub->get_name();
    current = sub;
  }
  return name.empty() ? "photorig" : name;
}

// The first argument when it is meant as a command and names none ("" otherwise).
std::string UnknownCommand(CLI::App& app, int argc, char** argv) {
  if (argc < 2 || argv[1][0] == '-') return "";
  try {
    app.get_subcommand(argv[1]);
    return "";
  } catch (const CLI::OptionNotFound&) {
    return argv[1];
  }
}

bool ArgumentsAskForJson(int argc, char** argv) {
  for (int i = 1; i < argc; ++i)
    if (std::strcmp(argv[i], "--json") == 0) return true;
  return false;
}

}  // namespace
}  // namespace photorig::app

int main(int argc, char** argv) {
  using namespace photorig::app;
  CLI::App app{"photorig: capture and reconstruct with a light dome (simulated or real)"};
  app.require_subcommand(1);
  std::vector<CommandRunner> runners;
  for (auto setup : RegisteredCommands()) runners.push_back(setup(app));
  bool json_output = false;
  AddJsonFlag(&app, &json_output);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // Usage errors exit 2 like every other configuration error, not with CLI11's own codes.
    internal::BeginCommand(CommandNameFromArguments(app, argc, argv), ArgumentsAskForJson(argc, argv));
    if (const std::string unknown = UnknownCommand(app, argc, argv); !unknown.empty())
      return internal::EndCommand(
          Fail(kExitUsage, "unknown command '" + unknown + "': `photorig --help` lists the commands"), "");
    app.exit(e);
    return internal::EndCommand(kExitUsage, e.what());
  }
  internal::BeginCommand(CommandNameFromArguments(app, argc, argv), json_output);

  spdlog::set_pattern("[%H:%M:%S.%e] [%^%l%$] %v");
  QuietLibraryLogging(argv[0]);
  InstallStopHandlers();
  try {
    // The innermost command parsed runs: `solve ps`, not the `solve` group around it.
    for (const auto& runner : runners)
      if (runner.subcommand->parsed() && runner.subcommand->get_subcommands().empty())
        return internal::EndCommand(runner.run(), "failed");
  } catch (const photorig::config::ConfigError& e) {
    return internal::EndCommand(Fail(kExitUsage, std::string("configuration error: ") + e.what()), "");
  } catch (const photorig::daemon::DamagedRunError& e) {
    return internal::EndCommand(Fail(kExitUsage, e.what()), "");
  } catch (const std::invalid_argument& e) {
    return internal::EndCommand(Fail(kExitUsage, e.what()), "");
  } catch (const std::exception& e) {
    return internal::EndCommand(Fail(kExitFailed, e.what()), "");
  }
  return internal::EndCommand(kExitOk, "");
}
