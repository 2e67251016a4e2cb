// Subcommands that talk to a running photorigd over its HTTP API:
//   photorig submit RECIPE [--watch]     queue a recipe
//   photorig status [RUN]                list runs, or one run
//   photorig watch RUN                   follow progress until the run ends
//   photorig pause|resume|abort RUN
// Common options: --url (default $PHOTORIG_URL or http://127.0.0.1:8750),
// --token-file (default $PHOTORIG_TOKEN); --json as for every command (docs/cli.md).

#include "../command.h"
#include "../command_output.h"
#include "../progress_display.h"
#include "daemon_connection.h"
#include "photorig/config/yaml_node.h"
#include "photorig/daemon/capture/run_control.h"
#include "photorig/daemon/service/service.h"

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>

namespace photorig::app {
namespace {

using nlohmann::json;

// No answer: 3; a request the daemon refused (bad recipe, unknown run): 2; its own failure: 1.
int Fail(const Connection& connection, const daemon::ServiceReply& reply) {
  ResultFields()["http_status"] = reply.http_status;
  if (reply.http_status == 0) return Fail(kExitUnavailable, connection.Unreachable());
  const std::string why = reply.body.value("error", std::string("HTTP ") + std::to_string(reply.http_status));
  return Fail(reply.http_status >= 400 && reply.http_status < 500 ? kExitUsage : kExitFailed, why);
}

bool Ok(const daemon::ServiceReply& reply) { return reply.http_status >= 200 && reply.http_status < 300; }

std::string RunLine(const json& run) {
  char line[256];
  std::snprintf(line, sizeof(line), "%-28s %-11s %4d/%-4d frames  retries %d  dropped %d", run.value("id", "").c_str(),
                run.value("state", "").c_str(), run.value("frames", 0), run.value("steps_total", 0),
                run.value("retries", 0), run.value("dropped_frames", 0));
  std::string text = line;
  if (run.contains("eta_s")) text += "  ETA " + FormatDuration(run["eta_s"].get<double>());
  if (!run.value("reason", "").empty()) text += "  (" + run.value("reason", "") + ")";
  return text;
}

// `state` as the API names it (RunStateName).
int ExitCodeForState(const std::string& state) {
  const std::optional<daemon::RunState> parsed = daemon::RunStateFromName(state);
  if (parsed == daemon::RunState::kDone) return kExitOk;
  if (parsed == daemon::RunState::kAborted) return kExitInterrupted;
  return kExitFailed;
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

// The time left for a running run, from the host timestamps of the frames in
// its journal: the mean time per frame so far times the frames still to take.
std::optional<double> EtaSeconds(daemon::ApiClient& client, const json& run) {
  const int frames = run.value("frames", 0), total = run.value("steps_total", 0);
  if (run.value("state", "") != "running" || frames < 2 || frames >= total) return std::nullopt;
  std::string journal;
  if (client.Download(run.value("id", ""), "journal.jsonl", &journal) != 200) return std::nullopt;
  std::istringstream lines(journal);
  std::int64_t first_ns = 0, last_ns = 0;
  int stamped = 0;
  for (std::string line; std::getline(lines, line);) {
    const json record = json::parse(line, nullptr, false);
    if (!record.is_object() || !record.contains("host_timestamp_ns")) continue;
    last_ns = record["host_timestamp_ns"].get<std::int64_t>();
    if (stamped++ == 0) first_ns = last_ns;
  }
  if (stamped < 2 || last_ns <= first_ns) return std::nullopt;
  return 1e-9 * double(last_ns - first_ns) / (stamped - 1) * (total - frames);
}

// Follows a run's events until it stops: frames as a progress bar with an
// ETA (on stderr), states as lines. A stream that breaks off or is refused
// for want of slots is opened again while the run goes on (api_client.h,
// Reconnect). Returns the exit code of how it ended.
int Watch(const Connection& connection, const std::string& id) {
  auto client = connection.Client(24 * 3600);
  // The run as it stands: an unreachable daemon or an unknown run end here,
  // and frames already taken are replayed by the stream in a burst, which
  // must not count towards the rate behind the ETA.
  const auto run = client.Get("/api/v1/runs/" + id);
  if (!Ok(run)) return Fail(connection, run);
  const int frames_before = run.body.value("frames", 0);
  ResultFields()["id"] = id;
  ProgressDisplay progress;
  json stop;
  const daemon::Reconnect reconnect;
  const std::string error = client.FollowEvents(id, [&](const std::string& type, const json& data) {
    if (type == "frame") {
      const int done = data.value("frames", 0);
      if (done >= frames_before) progress.Update("captured", done, data.value("total", 0), data.value("label", ""));
    } else if (type == "solve_started") {
      progress.EndLine();
      std::printf("solving: %s\n", data.value("stage", "").c_str());
    } else if (type == "solve_submitted") {
      progress.EndLine();
      std::printf("solving: %s as Slurm job %s (%s)\n", data.value("stage", "").c_str(), data.value("job_id", "").c_str(),
                  data.value("batch", "").c_str());
    } else if (type == "solve_progress") {
      progress.Update(data.value("stage", ""), data.value("done", 0), data.value("total", 0), "",
                      data.value("stopped", ""));
    } else if (type == "state" || type == "stop") {
      progress.EndLine();
      std::printf("%s %s%s%s\n", type == "stop" ? "stopped:" : "state:", data.value("state", "").c_str(),
                  data.value("reason", "").empty() ? "" : " - ", data.value("reason", "").c_str());
      if (type == "stop") {
        stop = data;
        std::printf("frames %d/%d, retries %d, dropped frames %d\n", data.value("frames", 0),
                    data.value("steps_total", 0), data.value("retries", 0), data.value("dropped_frames", 0));
        PrintSolve(data);
      }
    }
    std::fflush(stdout);
    return true;
  }, &reconnect);
  progress.EndLine();
  if (stop.is_object()) {
    ResultFields()["state"] = stop.value("state", "");
    ResultFields()["stop"] = stop;
  }
  if (!error.empty()) return Fail(kExitUnavailable, "lost the run's event stream: " + error);
  const std::string state = stop.value("state", "");
  const int code = ExitCodeForState(state);
  if (code != kExitOk)
    return Fail(static_cast<ExitCode>(code), "run " + id + " ended " + state +
                                                 (stop.value("reason", "").empty() ? "" : ": " + stop.value("reason", "")));
  return kExitOk;
}

struct SubmitOptions {
  Connection connection;
  std::string recipe;
  bool watch = false;
};

int Submit(const SubmitOptions& options) {
  // YAML that does not parse (or is no map) is named here with its line,
  // not reported as whatever the daemon, or its absence, makes of it.
  config::YamlNode::LoadFile(options.recipe);
  std::ifstream in(options.recipe);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto client = options.connection.Client();
  // The recipe's own path lets the daemon resolve its recipe.rig as `photorig run` would.
  const auto reply = client.Post("/api/v1/runs", {{"name", options.recipe},
                                                  {"recipe", text},
                                                  {"path", std::filesystem::absolute(options.recipe).string()}});
  if (!Ok(reply)) return Fail(options.connection, reply);
  const json& plan = reply.body["plan"];
  ResultFields() = reply.body;
  std::printf("submitted %s: %d frames, about %.1f s and %.1f MiB\n", reply.body.value("id", "").c_str(),
              plan.value("frames", 0), plan.value("duration_s", 0.0), plan.value("bytes", std::uint64_t{0}) / 1048576.0);
  std::fflush(stdout);
  return options.watch ? Watch(options.connection, reply.body.value("id", "")) : kExitOk;
}

CLI::App* SetupSubmit(CLI::App& app, SubmitOptions* options) {
  CLI::App* sub = app.add_subcommand("submit", "queue a recipe on the photorigd daemon");
  sub->add_option("recipe", options->recipe, "recipe YAML")->required()->check(CLI::ExistingFile);
  sub->add_flag("--watch", options->watch, "follow the run until it ends");
  options->connection.AddOptions(sub);
  return sub;
}

struct RunOptions {
  Connection connection;
  std::string id;
  int limit = daemon::RunService::kRunsPerPage;  // status: the newest this many runs
  std::string before;                            // status: ... added before this run
};

int Status(const RunOptions& options) {
  auto client = options.connection.Client();
  const std::string page = "?limit=" + std::to_string(options.limit) + (options.before.empty() ? "" : "&before=" + options.before);
  auto reply = client.Get(options.id.empty() ? "/api/v1/runs" + page : "/api/v1/runs/" + options.id);
  if (!Ok(reply)) return Fail(options.connection, reply);
  const auto with_eta = [&client](json& run) {
    if (const auto eta = EtaSeconds(client, run)) run["eta_s"] = *eta;
  };
  if (options.id.empty()) {
    for (json& run : reply.body["runs"]) {
      with_eta(run);
      std::printf("%s\n", RunLine(run).c_str());
    }
    if (reply.body.value("older", false))
      std::printf("older runs: photorig status --before %s\n", reply.body.value("before", "").c_str());
  } else {
    with_eta(reply.body);
    std::printf("%s\n", RunLine(reply.body).c_str());
    PrintSolve(reply.body);
  }
  ResultFields() = reply.body;
  return kExitOk;
}

CLI::App* SetupStatus(CLI::App& app, RunOptions* options) {
  CLI::App* sub = app.add_subcommand("status", "list the daemon's runs, or show one");
  sub->add_option("run", options->id, "run id");
  sub->add_option("--limit", options->limit, "list at most this many runs, the newest")
      ->check(CLI::Range(1, daemon::RunService::kMaxRunsPerPage));
  sub->add_option("--before", options->before, "list the runs added before this one (a page further back)");
  options->connection.AddOptions(sub);
  return sub;
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
            if (!Ok(reply)) return Fail(options->connection, reply);
            ResultFields() = reply.body;
            std::printf("%s: %s requested\n", options->id.c_str(), action.c_str());
            return int{kExitOk};
          }};
}

CommandRunner SetupPause(CLI::App& app) { return SetupAction(app, "pause", "pause a running run after its current frame"); }
CommandRunner SetupResume(CLI::App& app) { return SetupAction(app, "resume", "resume a paused run"); }
CommandRunner SetupAbort(CLI::App& app) { return SetupAction(app, "abort", "abort a queued or running run (lights off)"); }

const bool registered = RegisterCommand<SubmitOptions, SetupSubmit, Submit>() &&
                        RegisterCommand<RunOptions, SetupStatus, Status>() && RegisterCommand(SetupWatch) &&
                        RegisterCommand(SetupPause) && RegisterCommand(SetupResume) && RegisterCommand(SetupAbort);

}  // namespace
}  // namespace photorig::app
