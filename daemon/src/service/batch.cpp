#include "photorig/daemon/service/internal/batch.h"

#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/io/json_fields.h"
#include "photorig/daemon/io/utc_time.h"

#include <fcntl.h>
#include <glob.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <thread>

namespace photorig::daemon {
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

// 'text' for bash, whatever it holds.
std::string ShellQuote(const std::string& text) {
  std::string quoted = "'";
  for (char c : text) {
    if (c == '\'') quoted += "'\\''";
    else quoted += c;
  }
  quoted += '\'';
  return quoted;
}

struct ProgramResult {
  int exit_code = -1;  // 127: could not be started
  std::string output;  // stdout and stderr together
};

// Runs a program (found on PATH) and collects what it prints.
ProgramResult RunProgram(const std::vector<std::string>& argv) {
  int pipe_fds[2];
  if (::pipe2(pipe_fds, O_CLOEXEC) != 0) throw std::runtime_error(std::string("pipe: ") + std::strerror(errno));
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error(std::string("fork: ") + std::strerror(errno));
  if (pid == 0) {
    ::dup2(pipe_fds[1], STDOUT_FILENO);
    ::dup2(pipe_fds[1], STDERR_FILENO);
    std::vector<char*> args;
    for (const std::string& arg : argv) args.push_back(const_cast<char*>(arg.c_str()));
    args.push_back(nullptr);
    ::execvp(args[0], args.data());
    ::_exit(127);
  }
  ::close(pipe_fds[1]);
  ProgramResult result;
  char buffer[4096];
  for (ssize_t n; (n = ::read(pipe_fds[0], buffer, sizeof(buffer))) != 0;) {
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) break;
    result.output.append(buffer, static_cast<std::size_t>(n));
  }
  ::close(pipe_fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return result;
}

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);)
    if (!line.empty()) lines.push_back(line);
  return lines;
}

// A program's words on one line, for an error message.
std::string OneLine(const std::string& output) {
  std::string line;
  for (const std::string& part : Lines(output)) {
    if (!line.empty()) line += "; ";
    line += part;
  }
  return line;
}

std::string Lowercase(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

// Slurm's job states in the words TaskStatus uses ("CANCELLED by 0" -> "cancelled").
std::string StateName(const std::string& slurm_state) {
  std::string state = Lowercase(slurm_state.substr(0, slurm_state.find(' ')));
  if (state == "configuring" || state == "requeued" || state == "requeue_hold" || state == "resizing" ||
      state == "suspended" || state == "completing" || state == "stage_out" || state == "signaling")
    return "running";
  if (state == "deadline") return "timeout";
  if (state == "boot_fail") return "node_fail";
  return state;
}

// Slurm's clients say so when slurmctld does not answer.
bool ControllerUnreachable(const std::string& output) {
  return output.find("Unable to contact slurm controller") != std::string::npos ||
         output.find("Socket timed out") != std::string::npos;
}

fs::path TaskRecord(const BatchManifest& batch, int index) {
  return fs::path(batch.directory) / "tasks" / (std::to_string(index) + ".json");
}

// The task's script: every run listed in it, so a node needs nothing but the
// batch folder and photorig.
std::string TaskScript(const BatchManifest& batch) {
  std::string script =
      "#!/bin/bash\n"
      "# One task of the photorig batch in this folder (docs/scaling.md): solves the run\n"
      "# numbered $SLURM_ARRAY_TASK_ID, or $1, and records the solve's JSON document in\n"
      "# tasks/N.json by rename as it ends.\n"
      "set -u\n"
      "task=${1:-${SLURM_ARRAY_TASK_ID:-}}\n"
      "dir=" + ShellQuote(batch.directory) + "\n"
      "runs=(\n";
  for (const BatchTask& task : batch.tasks) {
    script += "  ";
    script += ShellQuote(task.run);
    script += '\n';
  }
  script += ")\n"
            "solve=(";
  for (const std::string& argument : batch.solve_arguments) {
    script += ' ';
    script += ShellQuote(argument);
  }
  script += " )\n"
            "if [ -z \"$task\" ] || [ -z \"${runs[$task]:-}\" ]; then echo \"no task '$task' in $dir\" >&2; exit 2; fi\n"
            "exec 2>>\"$dir/logs/$task.log\"\n"
            "# The solver's threads: as many as the CPUs Slurm gave the task, unless told.\n"
            "if [ -n \"${SLURM_CPUS_PER_TASK:-}\" ] && [ -z \"${OMP_NUM_THREADS:-}\" ]; then\n"
            "  export OMP_NUM_THREADS=$SLURM_CPUS_PER_TASK\n"
            "fi\n"
            "record=\"$dir/tasks/$task.json\"\n"
            "partial=\"$record.partial-$(hostname -s)-$$\"\n"
            "echo \"== $(date -u +%FT%TZ) task $task on $(hostname -s): ${runs[$task]}\" >&2\n" +
            ShellQuote(batch.photorig) + " solve \"${solve[@]}\" --run \"${runs[$task]}\" --json > \"$partial\"\n"
            "code=$?\n"
            "mv -f \"$partial\" \"$record\"\n"
            "exit $code\n";
  return script;
}

}  // namespace

json BatchManifest::ToJson() const {
  json document = {{"format", kBatchFormat},
                   {"directory", directory},
                   {"executor", solvers::core::NameOf(config::kExecutorNames, executor)},
                   {"photorig", photorig},
                   {"solve_arguments", solve_arguments},
                   {"slurm", {{"partition", slurm.partition}, {"time", slurm.time}, {"mem", slurm.mem}}},
                   {"job_ids", job_ids},
                   {"created_utc", created_utc},
                   {"tasks", json::array()}};
  for (const BatchTask& task : tasks) document["tasks"].push_back({{"index", task.index}, {"run", task.run}});
  return document;
}

json TaskStatus::ToJson() const {
  json document = {{"index", index}, {"run", run}, {"state", state}, {"job_id", job_id}};
  if (exit_code) document["exit_code"] = *exit_code;
  if (!error.empty()) document["error"] = error;
  if (!report.is_null()) document["report"] = report;
  return document;
}

std::vector<std::string> ExpandRunArguments(const std::vector<std::string>& patterns) {
  std::vector<std::string> runs;
  std::set<std::string> seen;
  auto add = [&](const std::string& path) {
    const std::string absolute = fs::absolute(path).lexically_normal().string();
    const std::string run = !absolute.empty() && absolute.back() == '/' ? absolute.substr(0, absolute.size() - 1) : absolute;
    if (seen.insert(run).second) runs.push_back(run);
  };
  for (const std::string& argument : patterns) {
    std::istringstream items(argument);
    for (std::string pattern; std::getline(items, pattern, ',');) {
      if (pattern.empty()) continue;
      glob_t matches{};
      const int found = ::glob(pattern.c_str(), GLOB_MARK, nullptr, &matches);
      int runs_found = 0;
      for (std::size_t i = 0; found == 0 && i < matches.gl_pathc; ++i)
        if (fs::is_regular_file(fs::path(matches.gl_pathv[i]) / "manifest.json")) {
          add(matches.gl_pathv[i]);
          ++runs_found;
        }
      ::globfree(&matches);
      if (runs_found == 0)
        throw std::invalid_argument("--runs " + pattern + ": no run directory (a folder with manifest.json) matches");
    }
  }
  if (runs.empty()) throw std::invalid_argument("--runs names no run directory");
  return runs;
}

BatchManifest CreateBatch(const std::string& directory, const std::vector<std::string>& runs,
                          const std::string& photorig, const std::vector<std::string>& solve_arguments,
                          config::Executor executor, const SlurmOptions& slurm) {
  BatchManifest batch;
  batch.directory = fs::absolute(directory).lexically_normal().string();
  if (fs::exists(fs::path(batch.directory) / "batch.json"))
    throw std::invalid_argument(batch.directory + " already holds a batch; photorig batch status or --retry-failed use it");
  batch.executor = executor;
  batch.photorig = photorig;
  batch.solve_arguments = solve_arguments;
  batch.slurm = slurm;
  batch.created_utc = UtcNowIso8601();
  for (std::size_t i = 0; i < runs.size(); ++i) batch.tasks.push_back({static_cast<int>(i), runs[i]});
  fs::create_directories(fs::path(batch.directory) / "tasks");
  fs::create_directories(fs::path(batch.directory) / "logs");
  const std::string script = (fs::path(batch.directory) / "task.sh").string();
  WriteFileDurably(script, TaskScript(batch));
  fs::permissions(script, fs::perms::owner_exec | fs::perms::group_exec | fs::perms::others_exec, fs::perm_options::add);
  SaveBatch(batch);
  return batch;
}

BatchManifest LoadBatch(const std::string& directory) {
  const fs::path path = fs::path(directory) / "batch.json";
  std::ifstream in(path);
  if (!in) throw std::invalid_argument(path.string() + ": no batch here (photorig batch solve writes batch.json)");
  json document;
  try {
    document = json::parse(in);
    if (document.value("format", "") != kBatchFormat)
      throw std::invalid_argument(path.string() + ": not a " + std::string(kBatchFormat) + " manifest");
    BatchManifest batch;
    batch.directory = fs::absolute(directory).lexically_normal().string();
    if (!batch.directory.empty() && batch.directory.back() == '/') batch.directory.pop_back();
    const std::string executor = document.at("executor");
    const std::optional<config::Executor> parsed = solvers::core::ParseName(config::kExecutorNames, executor);
    if (!parsed) throw std::invalid_argument(path.string() + ": unknown executor '" + executor + "' (expected local or slurm)");
    batch.executor = *parsed;
    batch.photorig = document.at("photorig");
    batch.solve_arguments = document.at("solve_arguments").get<std::vector<std::string>>();
    batch.slurm.partition = document.at("slurm").value("partition", "");
    batch.slurm.time = document.at("slurm").value("time", "");
    batch.slurm.mem = document.at("slurm").value("mem", "");
    batch.job_ids = document.at("job_ids").get<std::vector<std::string>>();
    batch.created_utc = document.value("created_utc", "");
    for (const json& task : document.at("tasks")) batch.tasks.push_back({task.at("index"), task.at("run")});
    return batch;
  } catch (const json::exception& e) {
    throw std::invalid_argument(path.string() + ": " + e.what());
  }
}

void SaveBatch(const BatchManifest& batch) {
  WriteFileDurably((fs::path(batch.directory) / "batch.json").string(), batch.ToJson().dump(2) + "\n");
}

std::vector<TaskStatus> CollectBatchStatus(const BatchManifest& batch) {
  // Slurm's word for each task of the batch's jobs, newer jobs over older ones.
  std::map<int, std::pair<std::string, std::string>> scheduler;  // index -> (state, "JOB_TASK")
  if (!batch.job_ids.empty()) {
    std::string jobs;
    for (const std::string& id : batch.job_ids) {
      if (!jobs.empty()) jobs += ',';
      jobs += id;
    }
    std::map<std::string, int> job_order;
    for (std::size_t i = 0; i < batch.job_ids.size(); ++i) job_order[batch.job_ids[i]] = static_cast<int>(i);
    std::map<int, int> newest;  // index -> job order of the state kept
    auto consider = [&](const std::string& job_task, const std::string& state) {
      const std::size_t underscore = job_task.find('_');
      if (underscore == std::string::npos) return;
      const std::string job = job_task.substr(0, underscore);
      int index = 0;
      try {
        index = std::stoi(job_task.substr(underscore + 1));
      } catch (const std::exception&) {
        return;  // "12_[3-5]": pending tasks squeue -r lists one by one anyway
      }
      const auto order = job_order.find(job);
      if (order == job_order.end()) return;
      const auto kept = newest.find(index);
      if (kept != newest.end() && kept->second > order->second) return;
      newest[index] = order->second;
      scheduler[index] = {StateName(state), job_task};
    };
    // Accounting knows every task that ever ran; squeue the live ones (and
    // recently ended ones, for clusters without accounting), so it speaks last.
    const ProgramResult sacct = RunProgram({"sacct", "-n", "-P", "-X", "-j", jobs, "-o", "JobID,State"});
    if (sacct.exit_code == 0)
      for (const std::string& line : Lines(sacct.output)) {
        const std::size_t bar = line.find('|');
        if (bar != std::string::npos) consider(line.substr(0, bar), line.substr(bar + 1));
      }
    const ProgramResult squeue = RunProgram({"squeue", "-h", "-r", "--states=all", "-j", jobs, "-o", "%i|%T"});
    // Jobs Slurm has forgotten make squeue fail ("Invalid job id"): their tasks'
    // records speak for them. Any other failure (a controller too busy to
    // answer, "Zero Bytes were transmitted or received"; a client killed) says
    // nothing about the jobs, so it must not read as a task that ended.
    if (squeue.exit_code == 127) throw SlurmUnavailable("squeue cannot be run (Debian: slurm-client)");
    if (ControllerUnreachable(squeue.output) ||
        (squeue.exit_code != 0 && squeue.output.find("Invalid job id") == std::string::npos))
      throw SlurmUnavailable("squeue (exit " + std::to_string(squeue.exit_code) + "): " + OneLine(squeue.output));
    if (squeue.exit_code == 0)
      for (const std::string& line : Lines(squeue.output)) {
        const std::size_t bar = line.find('|');
        if (bar != std::string::npos) consider(line.substr(0, bar), line.substr(bar + 1));
      }
  }

  std::vector<TaskStatus> statuses;
  for (const BatchTask& task : batch.tasks) {
    TaskStatus status;
    status.index = task.index;
    status.run = task.run;
    const auto known = scheduler.find(task.index);
    if (known != scheduler.end()) status.job_id = known->second.second;
    std::ifstream in(TaskRecord(batch, task.index));
    json record;
    if (in) {
      try {
        record = json::parse(in);
      } catch (const json::exception&) {
        record = nullptr;  // a document cut short: the solve died mid-print
      }
    }
    const bool live = known != scheduler.end() && (known->second.first == "pending" || known->second.first == "running");
    if (live) {
      status.state = known->second.first;
    } else if (record.is_object() && record.contains("exit_code")) {
      try {
        status.exit_code = IntegerAt<int>(record, "exit_code");
        status.state = *status.exit_code == 0 ? "completed" : "failed";
        status.error = record.value("error", "");
      } catch (const std::runtime_error& e) {
        status.state = "failed";
        status.error = TaskRecord(batch, task.index).string() + ": " + e.what();
      }
      status.report = record;
    } else if (known != scheduler.end() && known->second.first != "completed") {
      status.state = known->second.first;
    } else {
      status.state = "no_result";
    }
    statuses.push_back(std::move(status));
  }
  return statuses;
}

void ClearTaskRecords(const BatchManifest& batch, const std::vector<int>& indices) {
  for (int index : indices) fs::remove(TaskRecord(batch, index));
}

std::string SubmitSlurmArray(BatchManifest* batch, const std::vector<int>& indices) {
  std::string array;
  for (int index : indices) {
    if (!array.empty()) array += ',';
    array += std::to_string(index);
  }
  const fs::path dir = batch->directory;
  std::vector<std::string> argv = {"sbatch", "--parsable", "--job-name=photorig-batch", "--array=" + array,
                                   "--ntasks=1", "--cpus-per-task=1", "--open-mode=append",
                                   "--output=" + (dir / "logs" / "%a.slurm.log").string(), "--chdir=" + dir.string()};
  if (!batch->slurm.partition.empty()) argv.push_back("--partition=" + batch->slurm.partition);
  if (!batch->slurm.time.empty()) argv.push_back("--time=" + batch->slurm.time);
  if (!batch->slurm.mem.empty()) argv.push_back("--mem=" + batch->slurm.mem);
  argv.push_back((dir / "task.sh").string());
  const ProgramResult sbatch = RunProgram(argv);
  if (sbatch.exit_code == 127)
    throw SlurmUnavailable("sbatch cannot be run (is Slurm's client installed and on PATH? Debian: slurm-client)");
  if (ControllerUnreachable(sbatch.output)) throw SlurmUnavailable(OneLine(sbatch.output));
  const std::vector<std::string> lines = Lines(sbatch.output);
  if (sbatch.exit_code != 0 || lines.empty())
    throw std::runtime_error("sbatch refused the job array: " + (lines.empty() ? "no output" : OneLine(sbatch.output)));
  // --parsable: "JOBID" or "JOBID;CLUSTER" on the last line (warnings may come first).
  const std::string job_id = lines.back().substr(0, lines.back().find(';'));
  if (job_id.empty() || job_id.find_first_not_of("0123456789") != std::string::npos)
    throw std::runtime_error("sbatch gave no job id: " + OneLine(sbatch.output));
  batch->job_ids.push_back(job_id);
  return job_id;
}

bool CancelSlurmJobs(const BatchManifest& batch) {
  if (batch.job_ids.empty()) return false;
  std::vector<std::string> argv = {"scancel"};
  argv.insert(argv.end(), batch.job_ids.begin(), batch.job_ids.end());
  return RunProgram(argv).exit_code == 0;
}

bool RunBatchLocally(const BatchManifest& batch, const std::vector<int>& indices, int processes,
                     const std::atomic<bool>* stop_requested,
                     const std::function<void(const TaskStatus& ended, int done, int total)>& on_task_end) {
  const std::string script = (fs::path(batch.directory) / "task.sh").string();
  std::map<pid_t, int> running;  // pid -> task index
  std::size_t next = 0;
  int done = 0;
  const int total = static_cast<int>(indices.size());
  auto stopping = [stop_requested] { return stop_requested && stop_requested->load(); };
  while ((next < indices.size() || !running.empty())) {
    while (!stopping() && next < indices.size() && static_cast<int>(running.size()) < std::max(1, processes)) {
      const int index = indices[next++];
      const pid_t pid = ::fork();
      if (pid < 0) throw std::runtime_error(std::string("fork: ") + std::strerror(errno));
      if (pid == 0) {
        // Its own process group: the batch, not the terminal, decides when it stops.
        ::setpgid(0, 0);
        const int null_fd = ::open("/dev/null", O_RDWR);
        if (null_fd >= 0) {
          ::dup2(null_fd, STDIN_FILENO);
          ::dup2(null_fd, STDOUT_FILENO);
        }
        const std::string argument = std::to_string(index);
        ::execl("/bin/bash", "bash", script.c_str(), argument.c_str(), static_cast<char*>(nullptr));
        ::_exit(127);
      }
      ::setpgid(pid, pid);
      running[pid] = index;
    }
    if (stopping()) {
      for (const auto& [pid, index] : running) ::kill(-pid, SIGTERM);
    }
    int status = 0;
    const pid_t ended = ::waitpid(-1, &status, 0);
    if (ended < 0) {
      if (errno == EINTR) continue;
      break;
    }
    const auto it = running.find(ended);
    if (it == running.end()) continue;
    const int index = it->second;
    running.erase(it);
    ++done;
    if (on_task_end) {
      BatchManifest one = batch;
      one.job_ids.clear();
      one.tasks = {batch.tasks.at(static_cast<std::size_t>(index))};
      on_task_end(CollectBatchStatus(one).front(), done, total);
    }
  }
  return !stopping();
}

}  // namespace photorig::daemon
