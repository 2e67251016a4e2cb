#include "photorig/daemon/service/service.h"

#include "photorig/daemon/io/json_fields.h"

#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/service/run.h"
#include "photorig/config/rig.h"
#include "photorig/config/sim.h"
#include "photorig/config/yaml_node.h"
#include "photorig/daemon/capture/device_factory.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cerrno>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>

namespace photorig::daemon {
using solvers::core::Refuse;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr std::size_t kMaxEvents = 20000;

ServiceReply Error(int http_status, const std::string& message) { return {http_status, {{"error", message}}}; }

// Plans being compiled hold all the memory they may (ServiceOptions::plan_memory_bytes).
ServiceReply PlanMemorySpent() {
  ServiceReply reply = Error(503, "busy: other plans being compiled hold the memory plans may use; try again shortly");
  reply.retry_after_s = 1;
  return reply;
}

bool IsValidRunId(const std::string& id) {
  static const std::regex pattern("[0-9]{6}-[A-Za-z0-9_-]{1,48}");
  return std::regex_match(id, pattern);
}

// Why the rig a recipe names is not the rig this daemon drives; nullopt when
// it is. Same file, or a rig file of the same name, is the same rig. A
// relative `recipe.rig` resolves from the recipe's folder when the client said
// where the recipe is (`recipe_path`, absolute); otherwise only its file name
// is known, and its stem must be the rig's name or its file's stem.
std::optional<std::string> RigMismatch(const std::string& recipe_name, const std::string& named,
                                       const std::string& recipe_path, const config::RigConfig& rig) {
  const std::string drives = "this daemon drives rig '" + rig.name + "' (" + rig.path +
                             "); submit the recipe to that rig's daemon, or change its recipe.rig";
  const fs::path named_path = named;
  fs::path resolved;
  if (named_path.is_absolute()) resolved = named_path;
  else if (fs::path(recipe_path).is_absolute()) resolved = (fs::path(recipe_path).parent_path() / named_path).lexically_normal();
  if (resolved.empty()) {
    const std::string stem = named_path.stem().string();
    if (stem == rig.name || stem == fs::path(rig.path).stem().string()) return std::nullopt;
    return "recipe '" + recipe_name + "' names rig '" + stem + "' (" + named + "), but " + drives;
  }
  std::error_code error;
  if (!fs::is_regular_file(resolved, error))
    return "recipe '" + recipe_name + "' names rig " + named + ", which does not exist (" + resolved.string() +
           "; a relative recipe.rig resolves from the recipe's folder); " + drives;
  if (fs::equivalent(resolved, rig.path, error)) return std::nullopt;
  std::string other;
  try {
    other = config::LoadRigConfig(resolved.string()).name;
  } catch (const std::exception&) {
    // Its errors stay on the client's side: `photorig dry-run` shows them.
    return "recipe '" + recipe_name + "' names rig " + named + ", which is not a rig file photorig can load (" +
           resolved.string() + "; photorig dry-run on the recipe says why); " + drives;
  }
  if (other == rig.name) return std::nullopt;
  return "recipe '" + recipe_name + "' names rig '" + other + "' (" + resolved.string() + "), but " + drives;
}

// {"ok", "stages": [...]}: ok when every stage that ran is usable.
json SolveJson(const std::vector<SolveStageReport>& stages) {
  json solve = {{"ok", true}, {"stages", json::array()}};
  for (const SolveStageReport& stage : stages) {
    solve["stages"].push_back(stage.ToJson());
    if (!stage.usable) solve["ok"] = false;
  }
  return solve;
}

// The steps a run's journal holds a frame of (each once): what an
// interrupted run has kept, before resuming reopens it and checks the frames.
int JournalledFrames(const std::string& directory) {
  std::ifstream in(fs::path(directory) / "journal.jsonl");
  std::set<int> steps;
  for (std::string line; std::getline(in, line);) {
    const json entry = json::parse(line, nullptr, /*allow_exceptions=*/false);
    if (!entry.is_object() || !entry.contains("index")) continue;
    try {
      steps.insert(IntegerAt<int>(entry, "index"));
    } catch (const std::runtime_error&) {
      // A line whose index is no step counts for nothing; resuming checks the frames themselves.
    }
  }
  return static_cast<int>(steps.size());
}

std::uint32_t FileCrc32(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::vector<char> buffer(1 << 20);
  std::uint32_t crc = 0;
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    crc = Crc32(buffer.data(), static_cast<std::size_t>(in.gcount()), crc);
  }
  if (in.bad()) throw std::runtime_error("cannot read " + path.string());
  return crc;
}

}  // namespace

json StopEventData(const json& run) {
  json data = {{"id", run.value("id", "")},             {"state", run.value("state", "")},
               {"reason", run.value("reason", "")},
               {"frames", run.value("frames", 0)},       {"steps_total", run.value("steps_total", 0)},
               {"retries", run.value("retries", 0)},     {"dropped_frames", run.value("dropped_frames", 0)}};
  for (const char* key : {"solve", "results"})
    if (run.contains(key)) data[key] = run[key];
  return data;
}

bool ServiceOptions::IsValid(std::string* why) const {
  if (data_root.empty()) return Refuse(why, "data_root is required");
  if (rig_path.empty()) return Refuse(why, "rig_path is required");
  if (max_recipe_bytes == 0) return Refuse(why, "max_recipe_bytes must be > 0");
  std::string detail;
  if (!retry.IsValid(&detail)) return Refuse(why, "retry: " + detail);
  if (!plan.IsValid(&detail)) return Refuse(why, "plan: " + detail);
  if (!limits.IsValid(&detail)) return Refuse(why, "limits: " + detail);
  if (max_listed_steps == 0) return Refuse(why, "max_listed_steps must be > 0");
  if (plan_memory_bytes == 0) return Refuse(why, "plan_memory_bytes must be > 0");
  if (plan_wait_ms < 0) return Refuse(why, "plan_wait_ms must be >= 0");
  return true;
}

RunService::RunService(ServiceOptions options) : options_(std::move(options)), rig_(options_.rig_path) {
  std::string why;
  if (!options_.IsValid(&why)) throw std::runtime_error("daemon options: " + why);
  rig_.Get();  // a broken rig file stops the daemon at start, not at the first run
  // On a full disk the folders may not be creatable yet: the daemon starts
  // read-only (health says "disk full") and a run creates them once there is room.
  for (const char* folder : {"recipes", "runs"}) {
    std::error_code error;
    fs::create_directories(fs::path(options_.data_root) / folder, error);
    if (error && error != std::errc::no_space_on_device && error.value() != EDQUOT)
      throw fs::filesystem_error("cannot create the data folder", fs::path(options_.data_root) / folder, error);
  }
  queue_ = std::make_unique<RunQueue>((fs::path(options_.data_root) / "queue.sqlite").string());
  plan_budget_ = std::make_unique<PlanMemoryBudget>(options_.plan_memory_bytes);
  started_ = std::chrono::steady_clock::now();
}

RunService::~RunService() { Stop(); }

namespace {

// Whatever a previous process left lit goes dark now, before any run
// (device_factory.h). A controller that cannot be reached is reported, not
// fatal: runs will say so.
void DarkenLightsAtStart(const std::string& rig_path) {
  try {
    const config::RigConfig rig = config::LoadRigConfig(rig_path);
    if (!LightsOutliveTheProcess(rig)) return;
    if (const Status darkened = DarkenLights(rig); !darkened.ok())
      spdlog::warn("event=lights_unreachable error={}", json(darkened.ToString()).dump());
    else
      spdlog::info("event=lights_off lights={}", rig.lights.id);
  } catch (const std::exception& e) {
    spdlog::warn("event=lights_unreachable error={}", json(e.what()).dump());
  }
}

}  // namespace

void RunService::Start() {
  DarkenLightsAtStart(options_.rig_path);
  std::vector<QueuedRun> unfinished;
  try {
    unfinished = queue_->Unfinished();
    // A run that failed while its directory could not be written (a full
    // disk) gets its stop record and manifest once there is room again.
    for (const QueuedRun& run : queue_->List())
      if (run.state == RunState::kFailed)
        FinishRunDirectory(run.id, {CaptureStatus::kFailed, run.reason, run.frames, run.steps_total, run.retries,
                                    run.dropped_frames});
  } catch (const std::exception& e) {
    NoteStorageError(e.what());
  }
  for (QueuedRun run : unfinished) {
    if (options_.resume_interrupted) {
      // The queue's count is as of the run's last state change; its journal knows every frame kept.
      run.frames = JournalledFrames(RunDirectory(run.id));
      spdlog::warn("run={} event=recovered state={} frames={} action=resume", run.id, RunStateName(run.state),
                   run.frames);
      SetState(run, RunState::kQueued, "interrupted by a daemon restart; resumes from its last checkpoint");
      continue;
    }
    const std::string directory = RunDirectory(run.id);
    if (fs::exists(fs::path(directory) / "journal.jsonl")) {
      try {
        RecoveryReport recovery;
        auto writer = RunWriter::Reopen(directory, &recovery);
        run.frames = recovery.frames_kept;
        writer->Finish({CaptureStatus::kInterrupted, "interrupted by a daemon restart", recovery.frames_kept, run.steps_total,
                        run.retries, run.dropped_frames});
      } catch (const std::exception& e) {
        spdlog::error("run={} event=recovery_failed error=\"{}\"", run.id, e.what());
      }
    }
    spdlog::warn("run={} event=recovered action=mark_interrupted", run.id);
    SetState(run, RunState::kInterrupted, "interrupted by a daemon restart");
  }
  stopping_ = false;
  worker_alive_ = true;
  worker_ = std::thread([this] { WorkerLoop(); });
}

void RunService::Stop() {
  stopping_ = true;
  changed_.notify_all();
  if (worker_.joinable()) worker_.join();
}

bool RunService::Healthy() const { return worker_alive_.load(); }

void RunService::WorkerLoop() {
  while (!stopping_) {
    std::optional<QueuedRun> next;
    try {
      next = queue_->NextQueued();
    } catch (const std::exception& e) {
      spdlog::error("event=queue_error error=\"{}\"", e.what());
    }
    if (!next) {
      std::unique_lock lock(mutex_);
      changed_.wait_for(lock, std::chrono::milliseconds(200));
      continue;
    }
    try {
      Execute(*next);
    } catch (const std::exception& e) {
      // The queue could not record the run's start: try again later, not in a tight loop.
      NoteStorageError(e.what());
      std::unique_lock lock(mutex_);
      changed_.wait_for(lock, std::chrono::seconds(1), [this] { return stopping_.load(); });
    }
  }
  worker_alive_ = false;
}

void RunService::SetState(QueuedRun& run, RunState state, const std::string& reason) {
  run.state = state;
  run.reason = reason;
  // The queue row may not follow (a full disk): the run still changes state
  // in memory and for every listener, and the failure is reported on /health.
  bool stored = true;
  try {
    queue_->Update(run);
  } catch (const std::exception& e) {
    stored = false;
    NoteStorageError(e.what());
  }
  {
    std::lock_guard lock(mutex_);
    if (run.id == current_id_) current_ = run;
    if (stored) storage_error_.clear();
  }
  AnnounceState(run);
}

void RunService::NoteStorageError(const std::string& what) {
  spdlog::error("event=storage_error error={}", json(what).dump(-1, ' ', false, json::error_handler_t::replace));
  std::lock_guard lock(mutex_);
  storage_error_ = what;
}

void RunService::FinishRunDirectory(const std::string& run_id, const StopRecord& stop) {
  const fs::path directory = RunDirectory(run_id);
  if (!fs::exists(directory / "journal.jsonl") || fs::exists(directory / "manifest.json")) return;
  try {
    RecoveryReport recovery;
    RunWriter::Reopen(directory.string(), &recovery)->Finish(stop);
    spdlog::info("run={} event=stop_record_written frames={}", run_id, recovery.frames_kept);
  } catch (const std::exception& e) {
    spdlog::error("run={} event=stop_record_failed error={}", run_id,
                  json(e.what()).dump(-1, ' ', false, json::error_handler_t::replace));
  }
}

void RunService::AnnounceState(const QueuedRun& run) {
  spdlog::info("run={} event=state state={}{}{}", run.id, RunStateName(run.state), run.reason.empty() ? "" : " reason=",
               run.reason.empty() ? "" : json(run.reason).dump(-1, ' ', false, json::error_handler_t::replace));
  Publish(run.id, "state", {{"state", RunStateName(run.state)}, {"reason", run.reason}});
}

void RunService::Publish(const std::string& run_id, const std::string& type, json data) {
  std::lock_guard lock(mutex_);
  PublishLocked(run_id, type, std::move(data));
}

void RunService::PublishLocked(const std::string& run_id, const std::string& type, json data) {
  events_.push_back({next_seq_++, run_id, type, std::move(data)});
  while (events_.size() > kMaxEvents) events_.pop_front();
  changed_.notify_all();
}

void RunService::Execute(QueuedRun run) {
  const std::string recipe_path = (fs::path(options_.data_root) / "recipes" / (run.id + ".yaml")).string();
  const std::string directory = RunDirectory(run.id);
  const bool resume = fs::exists(fs::path(directory) / "journal.jsonl");
  auto control = std::make_shared<RunControl>();
  {
    // The run is claimed under mutex_, where Abort decides too: a run
    // aborted since NextQueued returned it is not started, and a started
    // one is aborted through its control.
    std::lock_guard lock(mutex_);
    if (!queue_->LeaveQueued(run, RunState::kRunning, resume ? "resuming from the last checkpoint" : "")) return;
    current_id_ = run.id;
    current_control_ = control;
    current_ = run;
  }
  // A directory without a journal holds nothing of value (the crash came
  // before the first durable write): start it afresh.
  if (!resume && fs::exists(directory)) fs::remove_all(directory);
  AnnounceState(run);

  RunRequest request;
  request.recipe_path = recipe_path;
  request.rig_path = options_.rig_path;
  request.output_directory = directory;
  request.solve = options_.solve;
  request.resume = resume;
  request.stop_requested = &stopping_;
  request.control = control.get();
  request.retry = options_.retry;
  const std::string id = run.id;
  request.on_frame = [this, id](const config::CaptureStep& step, const FrameRecord& record, int frames, int total) {
    {
      std::lock_guard lock(mutex_);
      current_.frames = frames;
      current_.steps_total = total;
      last_frame_ = ToJson(record);
      last_frame_["run"] = id;
    }
    Publish(id, "frame", {{"index", step.index}, {"label", step.label}, {"file", record.file}, {"frames", frames},
                          {"total", total}});
  };
  request.on_solve_started = [this, id](const std::string& stage) { Publish(id, "solve_started", {{"stage", stage}}); };
  // Solvers report about every percent (solvers/progress.h): one event each.
  request.solve_progress = [this, id](const solvers::core::Progress& progress) {
    json event = {{"stage", std::string(progress.stage)}, {"done", progress.done}, {"total", progress.total}};
    if (!progress.stopped.empty()) event["stopped"] = std::string(progress.stopped);
    Publish(id, "solve_progress", event);
  };
  request.on_solve_submitted = [this, id](const std::string& stage, const std::string& job_id, const std::string& batch) {
    Publish(id, "solve_submitted", {{"stage", stage}, {"executor", "slurm"}, {"job_id", job_id}, {"batch", batch}});
    std::lock_guard lock(mutex_);
    if (current_.solve.is_null()) current_.solve = {{"ok", true}, {"stages", json::array()}};
    current_.solve["slurm_job_id"] = job_id;
  };
  request.on_solve_finished = [this, id](const SolveStageReport& report) {
    const json stage = report.ToJson();
    {
      // The record shows each stage as soon as it ends.
      std::lock_guard lock(mutex_);
      if (current_.solve.is_null()) current_.solve = {{"ok", true}, {"stages", json::array()}};
      current_.solve["stages"].push_back(stage);
      if (!report.usable) current_.solve["ok"] = false;
    }
    Publish(id, "solve_finished", stage);
  };
  request.on_state = [this, &run](RunState state, const std::string& detail) {
    if (state == RunState::kSuspended) {
      std::lock_guard lock(mutex_);
      last_device_fault_ = detail;
      ++current_.retries;
    }
    {
      std::lock_guard lock(mutex_);
      run.frames = current_.frames;
      run.steps_total = current_.steps_total;
      run.retries = current_.retries;
      run.solve = current_.solve;
    }
    SetState(run, state, detail);
  };

  RunState final_state = RunState::kFailed;
  std::string reason;
  StopRecord stop;
  try {
    const RunOutcome outcome = ExecuteRun(request);
    stop = outcome.capture.ToStopRecord();
    reason = outcome.capture.reason;
    if (outcome.capture.status == CaptureStatus::kComplete) {
      // A run is done when its data can be used: an unusable solve fails it.
      final_state = RunState::kDone;
      if (!outcome.solve_stages.empty()) run.solve = SolveJson(outcome.solve_stages);
      for (const SolveStageReport& stage : outcome.solve_stages)
        if (!stage.usable) {
          final_state = RunState::kFailed;
          reason = stage.stage + ": " + (stage.message.empty() ? stage.termination : stage.message);
          break;
        }
      if (control->abort_requested()) {
        final_state = RunState::kAborted;
        reason = "aborted after the capture; the solve stages after the one in progress were skipped";
      }
    } else if (outcome.capture.status == CaptureStatus::kAborted) {
      // SIGTERM leaves the run queued, to resume at the next start; an abort request ends it.
      final_state = control->abort_requested() ? RunState::kAborted : RunState::kQueued;
      if (final_state == RunState::kQueued) reason = "daemon stopped; resumes at the next start";
    }
  } catch (const std::exception& e) {
    reason = e.what();
    stop.status = CaptureStatus::kFailed;
    stop.reason = reason;
    {
      std::lock_guard lock(mutex_);
      stop.frames = current_.frames;
      stop.steps_total = current_.steps_total;
      stop.retries = current_.retries;
      if (current_.state == RunState::kSolving) {
        // A stage that threw (an unreadable run, a result that cannot be written) is an unusable solve.
        run.solve = current_.solve.is_null() ? json{{"stages", json::array()}} : current_.solve;
        run.solve["ok"] = false;
        reason = "solve: " + reason;
        stop = {CaptureStatus::kComplete, "", current_.frames, current_.steps_total, current_.retries, 0};
      }
    }
    // Storage failed mid-run (a full disk): the stop record and manifest where they can still be written.
    FinishRunDirectory(run.id, stop);
  }
  run.frames = stop.frames;
  run.steps_total = stop.steps_total;
  run.retries = stop.retries;
  run.dropped_frames = stop.dropped_frames;
  SetState(run, final_state, reason);
  {
    // No longer current before anyone hears it stopped: a client reacting to
    // the stop event (an abort, a new submission) must find the run final.
    std::lock_guard lock(mutex_);
    current_id_.clear();
    current_control_.reset();
  }
  Publish(run.id, "stop", StopEventData(RunJson(run)));
}

ServiceReply RunService::Validate(const std::string& name, const std::string& recipe_yaml,
                                  const std::string& recipe_path, bool for_submit) const {
  if (recipe_yaml.size() > options_.max_recipe_bytes)
    return Error(413, "recipe is " + std::to_string(recipe_yaml.size()) + " bytes; the limit is " +
                          std::to_string(options_.max_recipe_bytes));
  if (recipe_yaml.empty()) return Error(400, "empty recipe");
  try {
    const std::shared_ptr<const config::RigConfig> loaded_rig = rig_.Get();
    const config::RigConfig& rig = *loaded_rig;
    // Resolved where the run will read it from: the recipes folder of the data root.
    const config::Recipe recipe =
        config::LoadRecipeText(recipe_yaml, name, rig, (fs::path(options_.data_root) / "recipes").string());
    // A recipe without recipe.rig runs on the daemon's rig; one naming another rig is refused.
    if (auto named = config::YamlNode::LoadString(recipe_yaml, name)["recipe"].Find("rig")) {
      if (auto mismatch = RigMismatch(recipe.name, named->AsString(), recipe_path.empty() ? name : recipe_path, rig))
        return {422, {{"error", *mismatch}, {"recipe_rig", named->AsString()}, {"rig", rig.name}}};
    }
    config::CaptureLimits limits = options_.limits;
    limits.step_overhead_ms = options_.plan.step_overhead_ms;
    // The recipe's size is known once it is expanded: its rig's worst case
    // is reserved first, then what the plan holds.
    const std::size_t channels = rig.lights.leds.size();
    const auto reservation = plan_budget_->Reserve(
        PlanMemoryBytes(static_cast<std::size_t>(limits.max_frames), channels, options_.max_listed_steps),
        std::chrono::milliseconds(options_.plan_wait_ms));
    if (!reservation) return PlanMemorySpent();
    std::vector<config::CaptureStep> steps = config::CompileSteps(recipe, rig, limits);
    reservation->Shrink(PlanMemoryBytes(steps.size(), channels, std::min(steps.size(), options_.max_listed_steps)));
    const RunPlan plan = PlanRun(recipe, rig, steps, options_.plan);
    json body = plan.ToJson(steps, options_.max_listed_steps);
    steps = {};
    body["recipe"] = recipe.name;
    body["rig"] = rig.name;
    if (!plan.ok()) return {422, {{"error", plan.errors.front()}, {"plan", std::move(body)}}, 0, reservation};
    const std::uint64_t free_bytes = FreeBytes(options_.data_root);
    body["free_bytes"] = free_bytes;
    if (for_submit && free_bytes < plan.estimate.bytes)
      return {507, {{"error", "not enough free space: the run needs about " + std::to_string(plan.estimate.bytes >> 20) +
                                  " MiB, " + std::to_string(free_bytes >> 20) + " MiB free"},
                    {"plan", std::move(body)}}, 0, reservation};
    return {200, std::move(body), 0, reservation};
  } catch (const std::bad_alloc&) {
    // Memory ran out all the same (a limit on the process): this request fails, the daemon serves on.
    return PlanMemorySpent();
  } catch (const config::ConfigError& e) {
    // A recipe that expands beyond the limits is too large, not malformed.
    const bool too_large = dynamic_cast<const config::CaptureLimitError*>(&e) != nullptr;
    return {too_large ? 413 : 400,
            {{"error", e.what()}, {"file", e.file()}, {"line", e.line()}, {"column", e.column()}, {"key", e.key()}}};
  } catch (const std::exception& e) {
    return Error(400, e.what());
  }
}

ServiceReply RunService::DryRun(const std::string& name, const std::string& recipe_yaml,
                                const std::string& recipe_path) const {
  return Validate(name, recipe_yaml, recipe_path, false);
}

ServiceReply RunService::Submit(const std::string& name, const std::string& recipe_yaml, const std::string& recipe_path) {
  ServiceReply reply = Validate(name, recipe_yaml, recipe_path, true);
  if (reply.http_status != 200) return reply;
  json plan = std::move(reply.body);
  // The recipe is on disk before the worker can see the run, and the run's
  // "queued" event goes out before the worker can publish its next state
  // (SetState waits for mutex_).
  std::lock_guard lock(mutex_);
  QueuedRun run;
  try {
    run = queue_->Add(plan.value("recipe", name), plan.value("frames", 0), [&](const QueuedRun& added) {
      WriteFileDurably((fs::path(options_.data_root) / "recipes" / (added.id + ".yaml")).string(), recipe_yaml);
    });
  } catch (const std::exception& e) {
    spdlog::error("event=storage_error error={}", json(e.what()).dump(-1, ' ', false, json::error_handler_t::replace));
    storage_error_ = e.what();
    return Error(507, std::string("cannot store the run: ") + e.what());
  }
  storage_error_.clear();
  spdlog::info("run={} event=submitted recipe={} steps={}", run.id, run.recipe_name, run.steps_total);
  PublishLocked(run.id, "state", {{"state", "queued"}, {"reason", ""}});
  return {201, {{"id", run.id}, {"state", "queued"}, {"plan", std::move(plan)}}, 0, reply.holds};
}

ServiceReply RunService::ListRuns(int limit, const std::string& before) const {
  if (limit < 1 || limit > kMaxRunsPerPage)
    return Error(400, "limit must be within [1, " + std::to_string(kMaxRunsPerPage) + "], got " + std::to_string(limit));
  if (!before.empty() && (!IsValidRunId(before) || !queue_->Get(before))) return Error(404, "no run '" + before + "'");
  bool older = false;
  json runs = json::array();
  std::lock_guard lock(mutex_);
  for (const QueuedRun& run : queue_->Page(limit, before, &older))
    runs.push_back(RunJson(run.id == current_id_ ? current_ : run));
  json body = {{"runs", runs}, {"older", older}};
  if (older) body["before"] = runs.front()["id"];
  return {200, body};
}

json RunService::RunJson(const QueuedRun& run) const {
  json body = run.ToJson();
  if (!fs::is_directory(fs::path(RunDirectory(run.id)) / "results")) return body;
  body["results"] = {{"path", "runs/" + run.id + "/results"},
                     {"url", "/api/v1/runs/" + run.id + "/files?under=results"}};
  // The verdict of the capture the results were solved from, for whoever shows
  // them: results of a capture that did not complete exist only because a
  // solve accepted it (--accept-failed-capture).
  if (fs::exists(fs::path(RunDirectory(run.id)) / "manifest.json")) {
    try {
      CaptureVerdict capture = CaptureVerdictOf(LoadRunManifest(RunDirectory(run.id)));
      capture.accepted_failed_capture = !capture.complete();
      body["results"]["capture"] = capture.ToJson();
    } catch (const std::exception& e) {
      body["results"]["capture"] = {{"error", e.what()}};
    }
  }
  return body;
}

ServiceReply RunService::GetRun(const std::string& id) const {
  if (!IsValidRunId(id)) return Error(404, "no run '" + id + "'");
  auto run = queue_->Get(id);
  if (!run) return Error(404, "no run '" + id + "'");
  json body;
  {
    std::lock_guard lock(mutex_);
    body = RunJson(id == current_id_ ? current_ : *run);
  }
  const fs::path manifest = fs::path(RunDirectory(id)) / "manifest.json";
  if (IsFinal(run->state) && fs::exists(manifest)) {
    try {
      const RunManifest m = LoadRunManifest(RunDirectory(id));
      if (m.stop) body["stop"] = ToJson(*m.stop);
    } catch (const std::exception& e) {
      body["manifest_error"] = e.what();
    }
  }
  return {200, body};
}

ServiceReply RunService::NotTheCurrentRun(const std::string& id, const std::string& request) const {
  const auto found = IsValidRunId(id) ? queue_->Get(id) : std::nullopt;
  if (!found) return Error(404, "no run '" + id + "'");
  return Error(409, "run '" + id + "' is " + RunStateName(found->state) + ": only the running run can " + request);
}

// The reply to pause, resume or abort: 202 with the run's record as it
// stands and what was asked of it (the run acts on it at its next step).
ServiceReply RunService::Requested(const QueuedRun& run, const char* what) const {
  json body = RunJson(run);
  body["requested"] = what;
  return {202, body};
}

// A request that would change nothing is refused (409) naming the state, not
// acknowledged as if it had been carried out.
ServiceReply RunService::Pause(const std::string& id) {
  std::lock_guard lock(mutex_);
  if (id != current_id_ || !current_control_) return NotTheCurrentRun(id, "pause");
  if (current_.state == RunState::kSolving)
    return Error(409, "run '" + id + "' is solving: its capture is over, and a solve stage cannot pause");
  if (current_control_->abort_requested()) return Error(409, "run '" + id + "' is aborting");
  if (current_control_->paused()) return Error(409, "run '" + id + "' is already paused");
  current_control_->Pause();
  return Requested(current_, "pause");
}

ServiceReply RunService::Resume(const std::string& id) {
  std::lock_guard lock(mutex_);
  if (id != current_id_ || !current_control_) return NotTheCurrentRun(id, "resume");
  if (!current_control_->paused()) return Error(409, "run '" + id + "' is not paused: nothing to resume");
  current_control_->Resume();
  return Requested(current_, "resume");
}

ServiceReply RunService::Abort(const std::string& id) {
  if (!IsValidRunId(id)) return Error(404, "no run '" + id + "'");
  QueuedRun run;
  {
    std::lock_guard lock(mutex_);  // as Execute claims a run
    if (id == current_id_ && current_control_) {
      if (current_control_->abort_requested()) return Error(409, "run '" + id + "' is already aborting");
      current_control_->Abort();
      return Requested(current_, "abort");
    }
    auto found = queue_->Get(id);
    if (!found) return Error(404, "no run '" + id + "'");
    run = *found;
    if (!queue_->LeaveQueued(run, RunState::kAborted, "aborted before it started"))
      return Error(409, "run '" + id + "' is " + RunStateName(run.state) + "; nothing to abort");
  }
  AnnounceState(run);
  ServiceReply reply = Requested(run, "abort");
  reply.http_status = 200;  // carried out, not only requested: the run never started
  Publish(id, "stop", StopEventData(RunJson(run)));
  return reply;
}

ServiceReply RunService::ResolveRunPath(const std::string& id, const std::string& relative,
                                        std::string* absolute) const {
  const std::string directory = RunDirectory(id);
  std::error_code error;
  if (directory.empty() || !fs::is_directory(directory, error)) return Error(404, "no run '" + id + "'");
  const fs::path root = fs::weakly_canonical(directory, error);
  // Resolve first, then check: "..", absolute paths and symlinks all end up outside the root.
  const fs::path target = fs::weakly_canonical(root / relative, error);
  const auto outside = std::mismatch(root.begin(), root.end(), target.begin(), target.end()).first != root.end();
  if (relative.find('\0') != std::string::npos || fs::path(relative).is_absolute() || (!error && outside))
    return Error(400, "path '" + relative + "' leaves the run directory");
  // A name the file system refuses (longer than a file name may be, a loop
  // of links) names no file of the run.
  if (error) return Error(404, "no file '" + relative + "' in the run (" + error.message() + ")");
  *absolute = target.string();
  return {200, json::object()};
}

ServiceReply RunService::ListFiles(const std::string& id, const std::string& under) const {
  std::string folder;
  if (const ServiceReply resolved = ResolveRunPath(id, under, &folder); resolved.http_status != 200) return resolved;
  std::error_code error;
  if (!fs::is_directory(folder, error)) return Error(404, "no folder '" + under + "' in run '" + id + "'");
  const fs::path root = fs::weakly_canonical(RunDirectory(id));
  json files = json::array();
  std::uint64_t bytes = 0;
  // Symlinks are left out (and not followed): what a run holds is its own files.
  for (auto it = fs::recursive_directory_iterator(folder, error); !error && it != fs::recursive_directory_iterator();
       it.increment(error)) {
    if (it->is_symlink() || !it->is_regular_file()) continue;
    try {
      const std::uint64_t size = it->file_size();
      files.push_back({{"path", it->path().lexically_relative(root).generic_string()},
                       {"size", size},
                       {"crc32", FileCrc32(it->path())}});
      bytes += size;
    } catch (const std::exception&) {
      // Gone or replaced while listing (a temp file of a running run): not part of the listing.
    }
  }
  if (error) return Error(500, "cannot list run '" + id + "': " + error.message());
  std::sort(files.begin(), files.end(), [](const json& a, const json& b) { return a["path"] < b["path"]; });
  return {200, {{"id", id}, {"under", under}, {"files", files}, {"bytes", bytes}}};
}

ServiceReply RunService::Devices() const {
  const std::shared_ptr<const config::RigConfig> loaded_rig = rig_.Get();
  const config::RigConfig& rig = *loaded_rig;
  std::lock_guard lock(mutex_);
  const std::string use = current_id_.empty() ? "idle" : "in use by run " + current_id_;
  json devices = json::array();
  devices.push_back({{"role", "lights"}, {"id", rig.lights.id}, {"driver", rig.lights.driver},
                     {"channels", rig.lights.leds.size()}, {"state", use}});
  devices.push_back({{"role", "camera"}, {"id", rig.camera.id}, {"driver", rig.camera.driver},
                     {"width", rig.camera.width}, {"height", rig.camera.height}, {"state", use}});
  if (rig.motion) {
    json axes = json::array();
    for (const config::AxisConfig& axis : rig.motion->axes) axes.push_back(axis.id);
    devices.push_back({{"role", "motion"}, {"driver", rig.motion->driver}, {"axes", axes}, {"state", use}});
  }
  return {200, {{"rig", rig.name}, {"simulated", rig.IsSimulated()}, {"devices", devices},
                {"last_fault", last_device_fault_}, {"last_frame", last_frame_}}};
}

ServiceReply RunService::ListRecipes() const {
  std::vector<std::pair<std::string, fs::path>> folders;  // (source, folder)
  for (const std::string& folder : options_.recipe_folders) folders.emplace_back("config", folder);
  folders.emplace_back("data_root", fs::path(options_.data_root) / "recipes");
  json recipes = json::array();
  json listed_folders = json::array();
  for (const auto& [source, folder] : folders) {
    std::error_code error;
    if (!fs::is_directory(folder, error)) continue;
    listed_folders.push_back(fs::absolute(folder).lexically_normal().string());
    std::vector<fs::path> files;
    for (const auto& entry : fs::directory_iterator(folder, error))
      if (entry.is_regular_file() && entry.path().extension() == ".yaml" &&
          !IsValidRunId(entry.path().stem().string()))  // a submitted run's copy
        files.push_back(entry.path());
    std::sort(files.begin(), files.end());
    for (const fs::path& file : files) {
      const std::uintmax_t size = fs::file_size(file, error);
      if (error || size > options_.max_recipe_bytes) continue;
      std::ifstream in(file, std::ios::binary);
      const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      json recipe = {{"file", file.filename().string()}, {"source", source},
                     {"path", fs::absolute(file).lexically_normal().string()}, {"text", text}};
      try {
        const config::YamlNode root = config::YamlNode::LoadString(text, file.string());
        recipe["name"] = root["recipe"]["name"].AsString();
        if (auto description = root["recipe"].Find("description")) recipe["description"] = description->AsString();
      } catch (const std::exception& e) {
        recipe["name"] = file.stem().string();
        recipe["error"] = e.what();  // listed all the same: a dry-run shows where it is wrong
      }
      recipes.push_back(recipe);
    }
  }
  return {200, {{"folders", listed_folders}, {"recipes", recipes}}};
}

ServiceReply RunService::Health() const {
  int queued = 0;
  // A queue opened read-only on a full disk becomes writable here once there is room.
  std::string queue_error = queue_->ReadOnlyReason();
  try {
    queued = queue_->CountQueued();
  } catch (const std::exception& e) {
    queue_error = e.what();
  }
  const std::uint64_t free_bytes = FreeBytes(options_.data_root);
  std::lock_guard lock(mutex_);
  const std::string storage_error = !queue_error.empty() ? queue_error : storage_error_;
  // A full disk is the cause of the storage errors it brings: named first.
  const char* status = !worker_alive_.load()     ? "worker stopped"
                       : free_bytes == 0        ? "disk full"
                       : !storage_error.empty() ? "storage error"
                                                : "ok";
  json body = {{"status", status},
               {"uptime_s", std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count()},
               {"current_run", current_id_},
               {"queued", queued},
               {"free_bytes", free_bytes}};
  if (!storage_error.empty()) body["storage_error"] = storage_error;
  return {std::string(status) == "ok" ? 200 : 503, body};
}

std::vector<RunEvent> RunService::EventsAfter(const std::string& run_id, std::uint64_t after_seq, int wait_ms) const {
  std::unique_lock lock(mutex_);
  std::vector<RunEvent> found;
  auto collect = [&] {
    for (const RunEvent& event : events_)
      if (event.seq > after_seq && event.run_id == run_id) found.push_back(event);
    return !found.empty() || stopping_;
  };
  changed_.wait_for(lock, std::chrono::milliseconds(wait_ms), collect);
  return found;
}

bool RunService::IsRunFinal(const std::string& run_id) const {
  auto run = queue_->Get(run_id);
  return !run || IsFinal(run->state);
}

std::string RunService::RunDirectory(const std::string& id) const {
  if (!IsValidRunId(id)) return "";
  return (fs::path(options_.data_root) / "runs" / id).string();
}

}  // namespace photorig::daemon
