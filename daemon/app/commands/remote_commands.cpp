// Subcommands that talk to a running photorigd over its HTTP API:
//   photorig submit RECIPE [--watch]     queue a recipe
//   photorig status [RUN]                list runs, or one run
//   photorig watch RUN                   follow progress until the run ends
//   photorig pause|resume|abort RUN
// Common options: --url (default $PHOTORIG_URL or http://127.0.0.1:8750),
// --token-file (default $PHOTORIG_TOKEN), --json for machine-readable output.

#include "../command.h"
#include "daemon_connection.h"
#include "photorig/daemon/run_control.h"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>

namespace photorig::app {
namespace {

using nlohmann::json;

// Exit codes: 0 ok, 1 daemon unreachable or server error, 2 rejected input.
int Fail(const daemon::ServiceReply& reply, bool json_output) {
  if (json_output) {
    std::printf("%s\n", reply.body.dump().c_str());
  } else {
    std::fprintf(stderr, "error: %s\n", reply.body.value("error", std::string("HTTP ") + std::to_string(reply.http_status)).c_str());
  }
  return reply.http_status >= 400 && reply.http_status < 500 ? 2 : 1;
}

bool Ok(const daemon::ServiceReply& reply) { return reply.http_status >= 200 && reply.http_status < 300; }

std::string RunLine(const json& run) {
  char line[256];
  std::snprintf(line, sizeof(line), "%-28s %-11s %4d/%-4d frames  retries %d  dropped %d", run.value("id", "").c_str(),
                run.value("state", "").c_str(), run.value("frames", 0), run.value("steps_total", 0),
                run.value("retries", 0), run.value("dropped_frames", 0));
  std::string text = line;
  if (!run.value("reason", "").empty()) text += "  (" + run.value("reason", "") + ")";
  return text;
}

// `state` as the API names it (RunStateName).
int ExitCodeForState(const std::string& state) {
  const std::optional<daemon::RunState> parsed = daemon::RunStateFromName(state);
  if (parsed == daemon::RunState::kDone) return 0;
  if (parsed == daemon::RunState::kAborted) return 130;
  return 1;
}

// The solve stages and the results' location of a stop event (or run record).
void PrintSolve(const json& run) {
  if (run.contains("solve"))
    for (const json& stage : run["solve"]["stages"]) {
      std::string figures;
      for (const auto& [key, value] : stage["figures"].items()) {
        char number[32];
        std::snprintf(number, sizeof(number), "%.4g", value.is_number() ? value.get<double>() : 0.0);
        figures += ", " + key + " " +
                   (value.is_string() ? value.get<std::string>() : value.is_number_float() ? number : value.dump());
      }
      std::printf("solve %s: %s%s, %.0f ms\n", stage.value("stage", "").c_str(), stage.value("termination", "").c_str(),
                  figures.c_str(), stage["timings_ms"].value("total", 0.0));
      if (!stage.value("message", "").empty()) std::printf("  %s\n", stage.value("message", "").c_str());
    }
  if (run.contains("results"))
    std::printf("results: %s in the data root (photorig fetch %s --results)\n",
                run["results"].value("path", "").c_str(), run.value("id", "").c_str());
}

// Follows a run's events: a redrawn bar on a terminal, plain lines otherwise.
int Watch(const Connection& connection, const std::string& id) {
  auto client = connection.Client(24 * 3600);
  const bool tty = isatty(STDOUT_FILENO) && !connection.json_output;
  std::string final_state;
  const std::string error = client.FollowEvents(id, [&](const std::string& type, const json& data) {
    if (type == "stop") final_state = data.value("state", "");
    if (connection.json_output) {
      std::printf("%s\n", json{{"event", type}, {"data", data}}.dump().c_str());
    } else if (type == "frame") {
      const int done = data.value("frames", 0), total = std::max(1, data.value("total", 1));
      if (tty) {
        const int width = 30, filled = done * width / total;
        std::printf("\r[%.*s%*s] %d/%d %-16s", filled, "##############################", width - filled, "", done,
                    total, data.value("label", "").c_str());
      } else {
        std::printf("frame %d/%d %s\n", done, total, data.value("label", "").c_str());
      }
    } else if (type == "solve_started") {
      std::printf("%ssolving: %s\n", tty ? "\n" : "", data.value("stage", "").c_str());
    } else if (type == "state" || type == "stop") {
      std::printf("%s%s %s%s%s\n", tty ? "\n" : "", type == "stop" ? "stopped:" : "state:",
                  data.value("state", "").c_str(), data.value("reason", "").empty() ? "" : " - ",
                  data.value("reason", "").c_str());
      if (type == "stop") {
        std::printf("frames %d/%d, retries %d, dropped frames %d\n", data.value("frames", 0),
                    data.value("steps_total", 0), data.value("retries", 0), data.value("dropped_frames", 0));
        PrintSolve(data);
      }
    }
    std::fflush(stdout);
    return true;
  });
  if (!error.empty()) {
    std::fprintf(stderr, "error: %s\n", error.c_str());
    return 1;
  }
  return ExitCodeForState(final_state);
}

struct SubmitOptions {
  Connection connection;
  std::string recipe;
  bool watch = false;
};

int Submit(const SubmitOptions& options) {
  std::ifstream in(options.recipe);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto client = options.connection.Client();
  // The recipe's own path lets the daemon resolve its recipe.rig as `photorig run` would.
  const auto reply = client.Post("/api/v1/runs", {{"name", options.recipe},
                                                  {"recipe", text},
                                                  {"path", std::filesystem::absolute(options.recipe).string()}});
  if (!Ok(reply)) return Fail(reply, options.connection.json_output);
  const json& plan = reply.body["plan"];
  if (options.connection.json_output) {
    std::printf("%s\n", reply.body.dump().c_str());
  } else {
    std::printf("submitted %s: %d frames, about %.1f s and %.1f MiB\n", reply.body.value("id", "").c_str(),
                plan.value("frames", 0), plan.value("duration_s", 0.0),
                plan.value("bytes", std::uint64_t{0}) / 1048576.0);
  }
  return options.watch ? Watch(options.connection, reply.body.value("id", "")) : 0;
}

CommandRunner SetupSubmit(CLI::App& app) {
  auto options = std::make_shared<SubmitOptions>();
  CLI::App* sub = app.add_subcommand("submit", "queue a recipe on the photorigd daemon");
  sub->add_option("recipe", options->recipe, "recipe YAML")->required()->check(CLI::ExistingFile);
  sub->add_flag("--watch", options->watch, "follow the run until it ends");
  options->connection.AddOptions(sub);
  return {sub, [options] { return Submit(*options); }};
}

struct RunOptions {
  Connection connection;
  std::string id;
};

int Status(const RunOptions& options) {
  auto client = options.connection.Client();
  const auto reply = client.Get(options.id.empty() ? "/api/v1/runs" : "/api/v1/runs/" + options.id);
  if (!Ok(reply)) return Fail(reply, options.connection.json_output);
  if (options.connection.json_output) {
    std::printf("%s\n", reply.body.dump().c_str());
  } else if (options.id.empty()) {
    for (const json& run : reply.body["runs"]) std::printf("%s\n", RunLine(run).c_str());
  } else {
    std::printf("%s\n", RunLine(reply.body).c_str());
    PrintSolve(reply.body);
  }
  return 0;
}

CommandRunner SetupStatus(CLI::App& app) {
  auto options = std::make_shared<RunOptions>();
  CLI::App* sub = app.add_subcommand("status", "list the daemon's runs, or show one");
  sub->add_option("run", options->id, "run id");
  options->connection.AddOptions(sub);
  return {sub, [options] { return Status(*options); }};
}

CommandRunner SetupWatch(CLI::App& app) {
  auto options = std::make_shared<RunOptions>();
  CLI::App* sub = app.add_subcommand("watch", "follow a run's progress until it ends");
  sub->add_option("run", options->id, "run id")->required();
  options->connection.AddOptions(sub);
  return {sub, [options] { return Watch(options->connection, options->id); }};
}

CommandRunner SetupAction(CLI::App& app, const std::string& action, const std::string& description) {
  auto options = std::make_shared<RunOptions>();
  CLI::App* sub = app.add_subcommand(action, description);
  sub->add_option("run", options->id, "run id")->required();
  options->connection.AddOptions(sub);
  return {sub, [options, action] {
            auto client = options->connection.Client();
            const auto reply = client.Post("/api/v1/runs/" + options->id + "/" + action, json::object());
            if (!Ok(reply)) return Fail(reply, options->connection.json_output);
            if (options->connection.json_output) {
              std::printf("%s\n", reply.body.dump().c_str());
            } else {
              std::printf("%s: %s requested\n", options->id.c_str(), action.c_str());
            }
            return 0;
          }};
}

CommandRunner SetupPause(CLI::App& app) { return SetupAction(app, "pause", "pause a running run after its current frame"); }
CommandRunner SetupResume(CLI::App& app) { return SetupAction(app, "resume", "resume a paused run"); }
CommandRunner SetupAbort(CLI::App& app) { return SetupAction(app, "abort", "abort a queued or running run (lights off)"); }

const bool registered = RegisterCommand(SetupSubmit) && RegisterCommand(SetupStatus) && RegisterCommand(SetupWatch) &&
                        RegisterCommand(SetupPause) && RegisterCommand(SetupResume) && RegisterCommand(SetupAbort);

}  // namespace
}  // namespace photorig::app
