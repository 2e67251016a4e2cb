#pragma once
// Subcommands of the `photorig` CLI. Each lives in its own file under
// app/commands/ and registers itself at static-initialisation time:
//
//   namespace {
//   CLI::App* Setup(CLI::App& app, Options* options) {
//     CLI::App* sub = app.add_subcommand("name", "what it does");
//     sub->add_option("--flag", options->flag, "...");   // bound to CLI11 options
//     return sub;
//   }
//   const bool registered = photorig::app::RegisterCommand<Options, Setup, Execute>();
//   }  // namespace
//
// A command whose runner does more than call Execute on its options writes
// its own CommandSetup and registers that with RegisterCommand(setup).
//
// The runner returns the process exit code (command_output.h, docs/cli.md):
// 0 success, 1 a failed run or solve, 2 a usage or configuration error,
// 3 a device or the daemon unavailable, 130 interrupted. It prints text for
// people as it likes and puts its figures in ResultFields(): main prints
// them as one JSON document under --json, which every command takes.

#include "photorig/solvers/core/names.h"

#include <CLI/CLI.hpp>

#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace photorig::app {

struct CommandRunner {
  CLI::App* subcommand = nullptr;  // the runner is called when this one was parsed
  std::function<int()> run;
};
using CommandSetup = CommandRunner (*)(CLI::App& app);

bool RegisterCommand(CommandSetup setup);

// Registers a command whose flags, added by `Setup`, fill an Options that
// `Execute` then runs on; the options live as long as the runner.
template <typename Options, CLI::App* (*Setup)(CLI::App&, Options*), auto Execute>
bool RegisterCommand() {
  return RegisterCommand([](CLI::App& app) -> CommandRunner {
    auto options = std::make_shared<Options>();
    CLI::App* subcommand = Setup(app, options.get());
    return {subcommand, [options] { return Execute(*options); }};
  });
}

// Subcommand groups shared by several files ("solve", "calibrate"): returns the
// existing group or adds it, so `solve ps` and `solve color` can live apart.
CLI::App* SubcommandGroup(CLI::App& app, const std::string& name, const std::string& description);
// The groups that commands of several files join, each described once.
CLI::App* SolveGroup(CLI::App& app);      // solve <family>, solve --from
CLI::App* CalibrateGroup(CLI::App& app);  // calibrate <what>
const std::vector<CommandSetup>& RegisteredCommands();

// An option naming one value of a solver's name table, parsed into the enum:
// its choices, help and error come from the table, never from a copied list.
template <typename Enum, std::size_t N>
CLI::Option* AddChoice(CLI::App* app, const std::string& flag, Enum* value,
                       const solvers::core::NameTable<Enum, N>& table, const std::string& description) {
  const std::string help = description + ": " + solvers::core::JoinNames(table) + " (default " +
                           solvers::core::NameOf(table, *value) + ")";
  return app->add_option(flag, *value, help)->transform(CLI::CheckedTransformer(solvers::core::NameMap(table)).description(""));
}

}  // namespace photorig::app
