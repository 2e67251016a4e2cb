// photorig fetch RUN [--results] [--out DIR] [--url URL]: downloads a
// finished run of photorigd (or only its results/) into DIR (default
// ./RUN), checking each file's size and CRC-32 against the daemon's listing.
// Each file is written to a temporary name and renamed once it checks out, so
// DIR never holds a partial file under a real name; files already there with
// the listed size and checksum are kept; a listed file that is also a listed
// folder's name is reported and skipped, the rest fetched. Exit codes: 0
// every file fetched, 1 a download failed or was skipped, or the run has not
// ended, 2 bad arguments or an unknown run, 3 the daemon cannot be reached.

#include "../command.h"
#include "../command_output.h"
#include "daemon_connection.h"
#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/capture/run_control.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <set>
#include <vector>

namespace photorig::app {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// Below this much in all, a fetch prints no progress lines.
constexpr std::uint64_t kProgressMinBytes = 4u << 20;

struct Options {
  Connection connection;
  std::string id, out;
  bool results_only = false;
};

struct Fetched {
  std::string path;
  std::uint64_t size = 0;
  bool kept = false;  // already present and intact
  std::string error;
};

double MiB(std::uint64_t bytes) { return bytes / 1048576.0; }

// A listed path must stay inside the output folder, whatever the server says.
bool IsSafeRelative(const std::string& path) {
  const fs::path p = path;
  if (path.empty() || p.is_absolute()) return false;
  for (const fs::path& part : p)
    if (part == ".." || part == ".") return false;
  return true;
}

bool IsIntact(const fs::path& file, std::uint64_t size, std::uint32_t crc32) {
  std::error_code error;
  if (!fs::is_regular_file(file, error) || fs::file_size(file, error) != size) return false;
  std::ifstream in(file, std::ios::binary);
  std::vector<char> buffer(1 << 20);
  std::uint32_t crc = 0;
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    crc = daemon::Crc32(buffer.data(), static_cast<std::size_t>(in.gcount()), crc);
  }
  return !in.bad() && crc == crc32;
}

// Prints a progress line each tenth of the bytes, on stderr.
class ProgressLines {
 public:
  ProgressLines(std::string id, std::uint64_t total_bytes, std::size_t total_files)
      : id_(std::move(id)), total_bytes_(total_bytes), total_files_(total_files) {}
  void Add(std::uint64_t bytes) {
    done_bytes_ += bytes;
    if (total_bytes_ < kProgressMinBytes) return;
    const int tenth = static_cast<int>(10 * done_bytes_ / total_bytes_);
    if (tenth <= last_tenth_) return;
    last_tenth_ = tenth;
    std::fprintf(stderr, "fetch %s: %3d%% (%zu/%zu files, %.1f/%.1f MiB)\n", id_.c_str(), 10 * tenth, files_done_,
                 total_files_, MiB(done_bytes_), MiB(total_bytes_));
  }
  void FileDone() { ++files_done_; }

 private:
  std::string id_;
  std::uint64_t total_bytes_, done_bytes_ = 0;
  std::size_t total_files_, files_done_ = 0;
  int last_tenth_ = 0;
};

Fetched FetchFile(daemon::ApiClient& client, const std::string& id, const json& listed, const fs::path& out,
                  ProgressLines& progress) {
  Fetched fetched;
  fetched.path = listed.value("path", "");
  fetched.size = listed.value("size", std::uint64_t{0});
  const std::uint32_t expected_crc = listed.value("crc32", std::uint32_t{0});
  if (!IsSafeRelative(fetched.path)) {
    fetched.error = "the daemon listed an unsafe path '" + fetched.path + "'; not fetched";
    return fetched;
  }
  const fs::path target = out / fetched.path;
  if (IsIntact(target, fetched.size, expected_crc)) {
    fetched.kept = true;
    progress.Add(fetched.size);
    return fetched;
  }
  std::error_code error;
  fs::create_directories(target.parent_path(), error);
  if (error) {
    fetched.error = "cannot make the folder " + target.parent_path().string() + ": " + error.message() +
                    " (a file of that name in the way?)";
    return fetched;
  }
  const fs::path temp = target.string() + ".fetching";
  std::ofstream file(temp, std::ios::binary | std::ios::trunc);
  if (!file) {
    fetched.error = "cannot write " + temp.string();
    return fetched;
  }
  std::uint64_t received = 0;
  std::uint32_t crc = 0;
  std::string download_error;
  const int status = client.Download(
      id, fetched.path,
      [&](const char* data, std::size_t size) {
        file.write(data, static_cast<std::streamsize>(size));
        crc = daemon::Crc32(data, size, crc);
        received += size;
        progress.Add(size);
        return static_cast<bool>(file);
      },
      &download_error);
  file.close();
  if (status != 200 || !file) {
    fetched.error = !file ? "cannot write " + temp.string() : download_error;
  } else if (received != fetched.size) {
    fetched.error = "received " + std::to_string(received) + " bytes, the daemon listed " + std::to_string(fetched.size);
  } else if (crc != expected_crc) {
    fetched.error = "CRC-32 mismatch: received " + std::to_string(crc) + ", the daemon listed " + std::to_string(expected_crc);
  }
  if (fetched.error.empty()) {
    fs::rename(temp, target, error);
    if (error)
      fetched.error =
          "cannot put it in place as " + target.string() + ": " + error.message() + " (a folder of that name in the way?)";
  }
  if (!fetched.error.empty()) fs::remove(temp, error);
  return fetched;
}

// Listed paths that are also the folder of another listed path: a file and a
// folder of one name cannot both be written.
std::set<std::string> FileFolderConflicts(const json& files) {
  std::set<std::string> paths, folders;
  for (const json& listed : files) {
    const std::string path = listed.value("path", "");
    paths.insert(path);
    for (fs::path folder = fs::path(path).parent_path(); !folder.empty(); folder = folder.parent_path())
      folders.insert(folder.generic_string());
  }
  std::set<std::string> conflicts;
  for (const std::string& path : paths)
    if (folders.count(path)) conflicts.insert(path);
  return conflicts;
}

// The report as the command's result; with an error, the command's failure.
int Finish(const json& report, ExitCode exit_code, const std::string& error) {
  ResultFields() = report;
  return error.empty() ? exit_code : Fail(exit_code, error);
}

// Unreachable: 3; an unknown run or a refused request: 2; otherwise 1.
int FailedRequest(const Options& options, const json& report, const daemon::ServiceReply& reply) {
  if (reply.http_status == 0) return Finish(report, kExitUnavailable, options.connection.Unreachable());
  return Finish(report, reply.http_status >= 400 && reply.http_status < 500 ? kExitUsage : kExitFailed,
                reply.body.value("error", "HTTP " + std::to_string(reply.http_status)));
}

int Execute(const Options& options) {
  auto client = options.connection.Client();
  json report = {{"id", options.id}};
  const daemon::ServiceReply run = client.Get("/api/v1/runs/" + options.id);
  if (run.http_status != 200) return FailedRequest(options, report, run);
  const std::string state = run.body.value("state", "");
  const auto parsed = daemon::RunStateFromName(state);
  if (!parsed || !daemon::IsFinal(*parsed))
    return Finish(report, kExitFailed,
                  "run " + options.id + " is " + state + "; fetch it once it has ended (photorig watch " + options.id + ")");
  if (options.results_only && !run.body.contains("results"))
    return Finish(report, kExitFailed,
                  "run " + options.id + " has no results: its recipe has no solve stage, or the daemon skips them (--no-solve)");
  const daemon::ServiceReply listing =
      client.Get("/api/v1/runs/" + options.id + "/files" + (options.results_only ? "?under=results" : ""));
  if (listing.http_status != 200) return FailedRequest(options, report, listing);

  const fs::path out = options.out.empty() ? fs::path(options.id) : fs::path(options.out);
  const json& files = listing.body["files"];
  ProgressLines progress(options.id, listing.body.value("bytes", std::uint64_t{0}), files.size());
  std::uint64_t bytes = 0;
  int fetched = 0, kept = 0, failed = 0;
  json failures = json::array();
  const std::set<std::string> conflicts = FileFolderConflicts(files);
  for (const json& listed : files) {
    Fetched file;
    if (const std::string path = listed.value("path", ""); conflicts.count(path)) {
      file.path = path;
      file.error = "the daemon listed both a file and a folder named '" + path + "'; the folder's files are fetched, "
                   "this file is not";
    } else {
      file = FetchFile(client, options.id, listed, out, progress);
    }
    progress.FileDone();
    if (!file.error.empty()) {
      ++failed;
      failures.push_back({{"path", file.path}, {"error", file.error}});
      std::fprintf(stderr, "failed: %s: %s\n", file.path.c_str(), file.error.c_str());
      continue;
    }
    (file.kept ? kept : fetched) += 1;
    bytes += file.size;
  }
  report["directory"] = out.string();
  report["files"] = files.size();
  report["fetched"] = fetched;
  report["kept"] = kept;
  report["failed"] = failures;
  report["bytes"] = bytes;
  std::printf("%s: %d files fetched, %d already present, %.1f MiB, into %s\n", options.id.c_str(), fetched, kept,
                MiB(bytes), out.string().c_str());
  if (failed > 0)
    return Finish(report, kExitFailed,
                  std::to_string(failed) + " of " + std::to_string(files.size()) + " files failed; run the fetch again");
  return Finish(report, kExitOk, "");
}

CLI::App* Setup(CLI::App& app, Options* options) {
  CLI::App* sub = app.add_subcommand("fetch", "download a finished run (or its results) from the photorigd daemon");
  sub->add_option("run", options->id, "run id")->required();
  sub->add_flag("--results", options->results_only, "only the run's results/ folder");
  sub->add_option("--out", options->out, "folder to write into (default: ./RUN)");
  options->connection.AddOptions(sub);
  return sub;
}

const bool registered = RegisterCommand<Options, Setup, Execute>();

}  // namespace
}  // namespace photorig::app
