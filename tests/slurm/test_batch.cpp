// photorig batch: every run of a batch solved by its own `photorig solve ps`
// task, N at a time here or as a Slurm job array, gives the same files as an
// in-process solve; a task cancelled mid-solve leaves the run's previous
// result (or none), never part of a new one; --retry-failed completes the batch.

#include "photorig/daemon/pipelines/ps_pipeline.h"
#include "photorig/daemon/service/internal/batch.h"
#include "photorig/daemon/service/internal/slurm_solve.h"
#include "photorig/daemon/service/run.h"
#include "test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <regex>
#include <string>
#include <sys/wait.h>
#include <unistd.h>
#include <thread>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using photorig::testing::Daemon;
using photorig::testing::ReadText;
using photorig::testing::SmallRecipeYaml;
using photorig::testing::SmallRigYaml;
using photorig::testing::SourceDir;
using photorig::testing::TempDir;

constexpr int kRuns = 8;
// The files a solve writes whose bytes depend on the data alone (report.json has timings).
const char* const kComparedFiles[] = {"normals.tiff", "albedo.tiff", "confidence.tiff", "depth.tiff", "normals.png"};

// Runs `photorig ARGUMENTS --json`; returns the exit code and the document.
int Photorig(const std::string& arguments, json* document, const fs::path& log) {
  const std::string out = log.string() + ".json";
  const std::string command =
      std::string(PHOTORIG_BIN_DIR) + "/photorig " + arguments + " --json > " + out + " 2> " + log.string();
  const int status = std::system(command.c_str());
  *document = json::parse(ReadText(out), nullptr, false);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// `runs` captures of the small dome, each of its own noise (seed) and sphere.
void CaptureRuns(const TempDir& dir, int runs = kRuns) {
  for (int i = 0; i < runs; ++i) {
    std::string rig = SmallRigYaml("", 8);
    rig = std::regex_replace(rig, std::regex("seed: 7"), "seed: " + std::to_string(11 + i));
    rig = std::regex_replace(rig, std::regex("radius_mm: 12"), "radius_mm: " + std::to_string(9 + i));
    const std::string name = "run" + std::to_string(i);
    dir.Write(name + "-rig.yaml", rig);
    RunRequest request;
    request.recipe_path = dir.Write(name + "-recipe.yaml", SmallRecipeYaml(name + "-rig.yaml"));
    request.output_directory = (dir.path() / "runs" / name).string();
    request.solve = false;
    ASSERT_EQ(ExecuteRun(request).capture.status, CaptureStatus::kComplete);
  }
}

fs::path RunDir(const TempDir& dir, int i) { return dir.path() / "runs" / ("run" + std::to_string(i)); }

// runs/run<index> captured with LED 3 dead: a failed capture, with its frames.
void CaptureFailedRun(const TempDir& dir, int index) {
  const std::string name = "run" + std::to_string(index);
  dir.Write(name + "-rig.yaml", SmallRigYaml("{lights: {dim_channels: {3: 0.0}}}", 8));
  RunRequest request;
  request.recipe_path = dir.Write(name + "-recipe.yaml", SmallRecipeYaml(name + "-rig.yaml"));
  request.output_directory = RunDir(dir, index).string();
  request.solve = false;
  request.retry.initial_backoff_ms = 1;
  ASSERT_EQ(ExecuteRun(request).capture.status, CaptureStatus::kFailed);
}

// Each run's results/ps has the bytes of an in-process solve of the same run.
void ExpectSameAsInProcess(const TempDir& dir, const std::string& method, int runs = kRuns) {
  for (int i = 0; i < runs; ++i) {
    config::PhotometricStereoRequest request;
    request.method = *solvers::ps::ParseMethod(method);
    const fs::path reference = dir.path() / "reference" / std::to_string(i);
    SolvePhotometricStereoRun(RunDir(dir, i).string(), request, reference.string());
    for (const char* file : kComparedFiles) {
      const fs::path batch_file = RunDir(dir, i) / "results" / "ps" / file;
      ASSERT_TRUE(fs::exists(batch_file)) << batch_file;
      EXPECT_EQ(ReadText(batch_file), ReadText(reference / file)) << "run " << i << ": " << file;
    }
  }
}

int CountState(const json& status, const std::string& state) {
  return status.contains("counts") ? status["counts"].value(state, 0) : 0;
}

TEST(BatchLocal, TwoProcessesSolveEveryRunAsInProcess) {
  TempDir dir;
  CaptureRuns(dir);
  json solved;
  ASSERT_EQ(Photorig("batch solve --runs '" + (dir.path() / "runs").string() + "/*' --local 2 --method auto --batch " +
                         (dir.path() / "batch").string(),
                     &solved, dir.path() / "solve.log"),
            0)
      << ReadText(dir.path() / "solve.log");
  EXPECT_EQ(solved["command"], "batch solve");
  EXPECT_EQ(solved["processes"], 2);
  EXPECT_EQ(CountState(solved, "completed"), kRuns) << solved.dump(2);
  ASSERT_EQ(solved["tasks"].size(), static_cast<std::size_t>(kRuns));
  EXPECT_EQ(solved["tasks"][3]["report"]["termination"], "success");
  ExpectSameAsInProcess(dir, "auto");
}

TEST(BatchLocal, FailedTaskIsReportedAndRetryCompletesTheBatch) {
  TempDir dir;
  CaptureRuns(dir);
  // Run 5 loses a frame: its solve cannot read the run.
  const fs::path frame = RunDir(dir, 5) / "frames" / "0003_led02.png";
  ASSERT_TRUE(fs::exists(frame));
  fs::rename(frame, dir.path() / "aside.png");
  const std::string batch = (dir.path() / "batch").string();
  json solved;
  EXPECT_EQ(Photorig("batch solve --runs " + (dir.path() / "runs").string() + "/run* --local 2 --batch " + batch,
                     &solved, dir.path() / "solve.log"),
            1);
  EXPECT_EQ(CountState(solved, "failed"), 1) << solved.dump(2);
  EXPECT_EQ(solved["tasks"][5]["state"], "failed");
  EXPECT_NE(solved["tasks"][5]["error"].get<std::string>().find("0003_led02.png"), std::string::npos);
  EXPECT_FALSE(fs::exists(RunDir(dir, 5) / "results" / "ps"));

  fs::rename(dir.path() / "aside.png", frame);
  json retried;
  EXPECT_EQ(Photorig("batch solve --retry-failed --batch " + batch + " --local 2", &retried, dir.path() / "retry.log"), 0)
      << ReadText(dir.path() / "retry.log");
  EXPECT_EQ(CountState(retried, "completed"), kRuns) << retried.dump(2);
  ExpectSameAsInProcess(dir, "auto");
}

TEST(BatchLocal, ATaskRecordWhoseExitCodeIsNoIntegerIsAFailedTaskNamingIt) {
  TempDir dir;
  CaptureRuns(dir, 2);
  const std::string batch = (dir.path() / "batch").string();
  json solved;
  ASSERT_EQ(Photorig("batch solve --runs '" + (dir.path() / "runs").string() + "/*' --local 2 --batch " + batch, &solved,
                     dir.path() / "solve.log"),
            0)
      << ReadText(dir.path() / "solve.log");
  // A record damaged on disk: a number no int holds, which nlohmann's get<int> would convert with undefined behaviour.
  const fs::path record = fs::path(batch) / "tasks" / "1.json";
  json task = json::parse(ReadText(record));
  task["exit_code"] = 1e137;
  std::ofstream(record) << task.dump();
  json status;
  EXPECT_EQ(Photorig("batch status --batch " + batch, &status, dir.path() / "status.log"), 1);
  EXPECT_EQ(status["tasks"][1]["state"], "failed") << status.dump(2);
  EXPECT_NE(status["tasks"][1]["error"].get<std::string>().find("1.json"), std::string::npos) << status.dump(2);
  EXPECT_EQ(status["tasks"][0]["state"], "completed");
}

// Slurm's clients replaced by scripts on PATH that answer as a busy or
// forgetful controller does: what the batch makes of each answer, no cluster needed.
class SlurmAnswers : public ::testing::Test {
 protected:
  void SetUp() override {
    bin_ = dir_.path() / "bin";
    fs::create_directories(bin_);
    // No accounting, as on the test node: sacct fails and squeue alone speaks.
    Tool("sacct", "echo 'sacct: error: Slurm accounting storage is disabled'; exit 1");
    Tool("sbatch", "touch " + (dir_.path() / "sbatch-ran").string() + "; echo 'sbatch: error: not expected'; exit 1");
    saved_path_ = std::getenv("PATH");
    ::setenv("PATH", (bin_.string() + ":" + saved_path_).c_str(), 1);
    fs::create_directories(dir_.path() / "run");
    batch_ = CreateBatch((dir_.path() / "run" / "batch").string(), {(dir_.path() / "run").string()}, "photorig",
                         SolveArguments(config::PhotometricStereoRequest{}), config::Executor::kSlurm, {});
    batch_.job_ids = {"41"};
    SaveBatch(batch_);
  }
  void TearDown() override { ::setenv("PATH", saved_path_.c_str(), 1); }

  void Tool(const std::string& name, const std::string& body) const {
    const fs::path path = bin_ / name;
    std::ofstream(path) << "#!/bin/sh\n" << body << "\n";
    fs::permissions(path, fs::perms::owner_all);
  }
  // squeue answering `answers` in turn (each "EXIT|TEXT"), the last one from
  // then on, running `before_last` first (a task that ends meanwhile).
  void Squeue(const std::vector<std::string>& answers, const std::string& before_last = "") const {
    const fs::path calls = dir_.path() / "squeue-calls";
    std::string body = "n=$(cat " + calls.string() + " 2>/dev/null || echo 0); n=$((n+1)); echo $n > " + calls.string() + "\n";
    for (std::size_t i = 0; i < answers.size(); ++i) {
      const std::size_t bar = answers[i].find('|');
      const bool last = i + 1 == answers.size();
      body += "if " + (last ? std::string("true") : "[ $n -le " + std::to_string(i + 1) + " ]") + "; then " +
              (last && !before_last.empty() ? before_last + "; " : "") + "echo '" + answers[i].substr(bar + 1) +
              "'; exit " + answers[i].substr(0, bar) + "; fi\n";
    }
    Tool("squeue", body);
  }
  fs::path Record() const { return fs::path(batch_.directory) / "tasks" / "0.json"; }
  void WriteRecord(int exit_code) const { std::ofstream(Record()) << json{{"exit_code", exit_code}}.dump(); }

  TempDir dir_;
  fs::path bin_;
  std::string saved_path_;
  BatchManifest batch_;
};

TEST_F(SlurmAnswers, AClientErrorIsSlurmUnavailableNotATaskThatEnded) {
  Squeue({"1|slurm_load_jobs error: Zero Bytes were transmitted or received"});
  try {
    CollectBatchStatus(batch_);
    ADD_FAILURE() << "a failed squeue read as the task's state";
  } catch (const SlurmUnavailable& e) {
    EXPECT_NE(std::string(e.what()).find("Zero Bytes"), std::string::npos) << e.what();
  }
  Squeue({"1|slurm_load_jobs error: Unable to contact slurm controller (connect failure)"});
  EXPECT_THROW(CollectBatchStatus(batch_), SlurmUnavailable);
}

TEST_F(SlurmAnswers, AJobSlurmForgotIsItsTaskRecord) {
  Squeue({"1|slurm_load_jobs error: Invalid job id specified"});
  EXPECT_EQ(CollectBatchStatus(batch_).front().state, "no_result");
  WriteRecord(0);
  EXPECT_EQ(CollectBatchStatus(batch_).front().state, "completed");
  Squeue({"0|41_0|RUNNING"});
  EXPECT_EQ(CollectBatchStatus(batch_).front().state, "running");
}

TEST_F(SlurmAnswers, ARestartedSolveFollowsItsJobThroughABusyController) {
  // The job runs, its task has no record yet; two failed answers (the
  // restart's look, the first poll), then the task has ended and says so.
  Squeue({"1|slurm_load_jobs error: Zero Bytes were transmitted or received",
          "1|slurm_load_jobs error: Socket timed out on send/recv operation", "0|41_0|COMPLETED"},
         "echo '{\"exit_code\": 0}' > " + Record().string());
  config::SolveExecutorConfig executor;
  executor.executor = config::Executor::kSlurm;
  executor.poll_ms = 100;
  const SlurmSolveOutcome outcome = SolvePhotometricStereoOnSlurm((dir_.path() / "run").string(),
                                                                  config::PhotometricStereoRequest{}, executor, RunRequest{});
  EXPECT_FALSE(fs::exists(dir_.path() / "sbatch-ran")) << "a second job was submitted for the run";
  EXPECT_EQ(outcome.job_id, "41_0");
  ASSERT_TRUE(outcome.report.has_value());
  EXPECT_EQ(outcome.report->termination, "completed");
  EXPECT_EQ(ReadText(dir_.path() / "squeue-calls"), "3\n");
}

// A single-node Slurm cluster for each test (tests/slurm/slurm-node.sh).
class SlurmBatch : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string script = SourceDir() + "/tests/slurm/slurm-node.sh";
    const fs::path log = slurm_.path() / "start.log";
    // This process's pid: the node is stopped when the test ends, even if it is killed before TearDown.
    const int status = std::system((script + " start " + (slurm_.path() / "node").string() + " " +
                                    std::to_string(::getpid()) + " > " + log.string() + " 2>&1").c_str());
    const int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    if (code == 77) GTEST_SKIP() << ReadText(log);
    ASSERT_EQ(code, 0) << ReadText(log);
    started_ = true;
    ::setenv("SLURM_CONF", (slurm_.path() / "node" / "slurm.conf").c_str(), 1);
  }
  void TearDown() override {
    if (started_)
      std::system((SourceDir() + "/tests/slurm/slurm-node.sh stop " + (slurm_.path() / "node").string()).c_str());
  }

  // Waits for every task to end; returns `batch status`'s exit code.
  int WaitForBatch(json* status) {
    return Photorig("batch status --wait --batch " + batch(), status, dir_.path() / "status.log");
  }
  std::string batch() const { return (dir_.path() / "batch").string(); }

  TempDir slurm_;
  TempDir dir_;
  bool started_ = false;
};

TEST_F(SlurmBatch, JobArraySolvesEveryRunAsInProcess) {
  CaptureRuns(dir_);
  json submitted;
  ASSERT_EQ(Photorig("batch solve --runs '" + (dir_.path() / "runs").string() + "/*' --slurm --time 00:05:00 --mem 100M" +
                         " --method blinn-phong --batch " + batch(),
                     &submitted, dir_.path() / "solve.log"),
            0)
      << ReadText(dir_.path() / "solve.log");
  EXPECT_EQ(submitted["tasks_submitted"].size(), static_cast<std::size_t>(kRuns));
  const json manifest = json::parse(ReadText(fs::path(batch()) / "batch.json"));
  EXPECT_EQ(manifest["job_ids"], json::array({submitted["job_id"]}));
  EXPECT_EQ(manifest["tasks"][2]["run"], RunDir(dir_, 2).string());

  json status;
  ASSERT_EQ(WaitForBatch(&status), 0) << status.dump(2) << ReadText(dir_.path() / "status.log");
  EXPECT_EQ(CountState(status, "completed"), kRuns);
  EXPECT_TRUE(status["finished"].get<bool>());
  EXPECT_EQ(status["tasks"][7]["job_id"], submitted["job_id"].get<std::string>() + "_7");
  EXPECT_EQ(status["tasks"][7]["report"]["method"], "blinn-phong");
  ExpectSameAsInProcess(dir_, "blinn-phong");
}

TEST_F(SlurmBatch, CancelledTaskKeepsThePreviousResultAndRetryCompletes) {
  constexpr int kHeldRuns = 3;  // one to cancel, two that finish
  CaptureRuns(dir_, kHeldRuns);
  // Run 0 has an earlier result; a cancelled task must leave it whole.
  config::PhotometricStereoRequest earlier;
  earlier.method = solvers::ps::Method::kL2;
  SolvePhotometricStereoRun(RunDir(dir_, 0).string(), earlier, (RunDir(dir_, 0) / "results" / "ps").string());
  const std::string earlier_normals = ReadText(RunDir(dir_, 0) / "results" / "ps" / "normals.tiff");

  // Every task holds its finished results, unrenamed, while the gate exists.
  const fs::path gate = dir_.path() / "gate";
  std::ofstream(gate) << "hold\n";
  json submitted;
  ASSERT_EQ(Photorig("batch solve --runs '" + (dir_.path() / "runs").string() + "/*' --slurm --method auto --commit-gate " +
                         gate.string() + " --batch " + batch(),
                     &submitted, dir_.path() / "solve.log"),
            0)
      << ReadText(dir_.path() / "solve.log");
  const std::string job = submitted["job_id"];

  // Task 0 has written its results beside the old ones: cancel it there.
  auto partial_exists = [this] {
    for (const auto& entry : fs::directory_iterator(RunDir(dir_, 0) / "results"))
      if (entry.path().filename().string().rfind(".ps.partial-", 0) == 0) return true;
    return false;
  };
  for (int i = 0; i < 600 && !partial_exists(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  ASSERT_TRUE(partial_exists()) << "task 0 never reached its commit";
  ASSERT_EQ(std::system(("scancel " + job + "_0").c_str()), 0);
  json status;
  for (int i = 0; i < 600; ++i) {
    Photorig("batch status --batch " + batch(), &status, dir_.path() / "status.log");
    if (status["tasks"][0]["state"] != "running") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  fs::remove(gate);

  EXPECT_EQ(WaitForBatch(&status), 1) << status.dump(2);
  EXPECT_EQ(status["tasks"][0]["state"], "cancelled") << status.dump(2);
  EXPECT_EQ(CountState(status, "completed"), kHeldRuns - 1);
  EXPECT_EQ(ReadText(RunDir(dir_, 0) / "results" / "ps" / "normals.tiff"), earlier_normals);
  EXPECT_EQ(json::parse(ReadText(RunDir(dir_, 0) / "results" / "ps" / "report.json"))["method"], "l2");
  for (const auto& entry : fs::directory_iterator(RunDir(dir_, 0) / "results"))
    EXPECT_EQ(entry.path().filename(), "ps") << "left behind: " << entry.path();

  json retried;
  ASSERT_EQ(Photorig("batch solve --retry-failed --batch " + batch(), &retried, dir_.path() / "retry.log"), 0)
      << ReadText(dir_.path() / "retry.log");
  EXPECT_EQ(retried["tasks_submitted"], json::array({0}));
  ASSERT_EQ(WaitForBatch(&status), 0) << status.dump(2);
  EXPECT_EQ(CountState(status, "completed"), kHeldRuns);
  EXPECT_EQ(status["job_ids"].size(), 2u);
  ExpectSameAsInProcess(dir_, "auto", kHeldRuns);
}

// A task on a run whose capture failed refuses it: the batch counts it failed, saying why.
TEST_F(SlurmBatch, ARunWhoseCaptureFailedIsAFailedTask) {
  CaptureRuns(dir_, 2);
  CaptureFailedRun(dir_, 2);
  json submitted;
  ASSERT_EQ(Photorig("batch solve --runs '" + (dir_.path() / "runs").string() + "/*' --slurm --method lambertian --batch " +
                         batch(),
                     &submitted, dir_.path() / "solve.log"),
            0)
      << ReadText(dir_.path() / "solve.log");
  json status;
  EXPECT_EQ(WaitForBatch(&status), 1) << status.dump(2);
  EXPECT_EQ(CountState(status, "completed"), 2) << status.dump(2);
  EXPECT_EQ(CountState(status, "failed"), 1) << status.dump(2);
  EXPECT_EQ(status["tasks"][2]["state"], "failed");
  EXPECT_NE(status["tasks"][2].value("error", "").find("the capture failed"), std::string::npos) << status.dump(2);
  EXPECT_FALSE(fs::exists(RunDir(dir_, 2) / "results"));
}

// The recipe chooses Slurm here (its `solve:` map overrides a rig that solves locally); the restart test below
// has the rig choose it.
TEST_F(SlurmBatch, DaemonHandsTheRecipesSolveToSlurmAndTracksTheJob) {
  const std::string rig = dir_.Write("slurm-rig.yaml", SmallRigYaml("", 8) + "solve: {executor: local, poll_ms: 200}\n");
  const std::string recipe = dir_.Write(
      "slurm-recipe.yaml",
      SmallRecipeYaml() + "solve:\n  executor: slurm\n  stages:\n    - photometric_stereo: {method: robust}\n");
  const Daemon daemon(dir_.path() / "data", rig, dir_.path() / "photorigd.log");
  const std::string url = daemon.WaitReady();
  ASSERT_FALSE(url.empty()) << ReadText(dir_.path() / "photorigd.log");

  const fs::path watch_log = dir_.path() / "watch.log";
  ASSERT_EQ(photorig::testing::RunPhotorig("submit " + recipe + " --watch --url " + url, watch_log), 0)
      << ReadText(watch_log) << ReadText(dir_.path() / "photorigd.log");
  const std::string watched = ReadText(watch_log);
  std::smatch job;
  ASSERT_TRUE(std::regex_search(watched, job, std::regex(R"(solving: photometric_stereo as Slurm job (\d+_0))"))) << watched;
  EXPECT_NE(watched.find("state: solving - photometric_stereo: Slurm job " + job[1].str()), std::string::npos) << watched;

  json status;
  ASSERT_EQ(Photorig("status --url " + url, &status, dir_.path() / "status.log"), 0);
  ASSERT_EQ(status["runs"].size(), 1u) << status.dump(2);
  const json& run = status["runs"][0];
  EXPECT_EQ(run["state"], "done");
  ASSERT_EQ(run["solve"]["stages"].size(), 1u) << run.dump(2);
  const json& stage = run["solve"]["stages"][0];
  EXPECT_TRUE(stage["ok"].get<bool>()) << stage.dump(2);
  EXPECT_EQ(stage["figures"]["slurm_job_id"], job[1].str());
  EXPECT_EQ(stage["figures"]["method"], "robust");

  // The task solved the daemon's run as an in-process solve would.
  const fs::path run_directory = dir_.path() / "data" / "runs" / run["id"].get<std::string>();
  EXPECT_EQ(json::parse(ReadText(run_directory / "batch" / "batch.json"))["job_ids"][0].get<std::string>() + "_0", job[1].str());
  config::PhotometricStereoRequest request;
  request.method = solvers::ps::Method::kRobust;
  SolvePhotometricStereoRun(run_directory.string(), request, (dir_.path() / "reference").string());
  for (const char* file : kComparedFiles)
    EXPECT_EQ(ReadText(run_directory / "results" / "ps" / file), ReadText(dir_.path() / "reference" / file)) << file;
}

TEST_F(SlurmBatch, RestartedDaemonFollowsTheJobItSubmitted) {
  const std::string rig = dir_.Write("slurm-rig.yaml", SmallRigYaml("", 8) + "solve: {executor: slurm, poll_ms: 200}\n");
  const std::string recipe = dir_.Write("slurm-recipe.yaml", SmallRecipeYaml() + "solve:\n  - photometric_stereo: {}\n");
  const fs::path data = dir_.path() / "data";
  auto daemon = std::make_unique<Daemon>(data, rig, dir_.path() / "photorigd-1.log");
  std::string url = daemon->WaitReady();
  ASSERT_FALSE(url.empty()) << ReadText(dir_.path() / "photorigd-1.log");
  json submitted;
  ASSERT_EQ(Photorig("submit " + recipe + " --url " + url, &submitted, dir_.path() / "submit.log"), 0);
  const std::string id = submitted["id"];
  // Stop the daemon once it has handed the solve to Slurm.
  json run;
  for (int i = 0; i < 600; ++i) {
    Photorig("status " + id + " --url " + url, &run, dir_.path() / "status.log");
    if (run.value("reason", "").find("Slurm job") != std::string::npos) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_EQ(run["state"], "solving") << run.dump(2);
  daemon.reset();

  daemon = std::make_unique<Daemon>(data, rig, dir_.path() / "photorigd-2.log");
  url = daemon->WaitReady();
  ASSERT_FALSE(url.empty()) << ReadText(dir_.path() / "photorigd-2.log");
  json watched;
  EXPECT_EQ(Photorig("watch " + id + " --url " + url, &watched, dir_.path() / "watch.log"), 0)
      << watched.dump(2) << ReadText(dir_.path() / "photorigd-2.log");
  EXPECT_NE(ReadText(dir_.path() / "photorigd-2.log").find("following Slurm job"), std::string::npos);
  // One job in all: the second daemon followed the first one's.
  const json batch = json::parse(ReadText(data / "runs" / id / "batch" / "batch.json"));
  ASSERT_EQ(batch["job_ids"].size(), 1u);
  EXPECT_EQ(watched["stop"]["solve"]["stages"][0]["figures"]["slurm_job_id"], batch["job_ids"][0].get<std::string>() + "_0");
  EXPECT_TRUE(fs::exists(data / "runs" / id / "results" / "ps" / "report.json"));
}

}  // namespace
}  // namespace photorig::daemon
