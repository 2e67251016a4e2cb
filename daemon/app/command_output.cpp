#include "command_output.h"

#include <fcntl.h>
#include <unistd.h>

#include <cstdio>

namespace photorig::app {
namespace {

struct CommandState {
  std::string name;
  bool json_output = false;
  int json_fd = -1;  // the real stdout while it points at stderr
  nlohmann::json fields = nlohmann::json::object();
  std::string error;
};

CommandState& State() {
  static CommandState state;
  return state;
}

}  // namespace

bool JsonOutput() { return State().json_output; }

nlohmann::json& ResultFields() { return State().fields; }

int Fail(ExitCode code, const std::string& why) {
  State().error = why;
  std::fflush(stdout);  // under --json both reach stderr: keep them in order
  std::fprintf(stderr, "%s: %s\n", State().name.c_str(), why.c_str());
  return code;
}

void ReportResultsDirectory(const std::string& directory, nlohmann::json& fields) {
  std::printf("results: %s/\n", directory.c_str());
  fields["results_directory"] = directory;
}

void SilenceOutput() {
  std::fflush(stdout);
  std::fflush(stderr);
  const int null_fd = ::open("/dev/null", O_WRONLY);
  if (null_fd < 0) return;
  for (int fd : {STDOUT_FILENO, STDERR_FILENO, State().json_fd})
    if (fd >= 0) ::dup2(null_fd, fd);
  ::close(null_fd);
}

namespace internal {

void BeginCommand(const std::string& name, bool json_output) {
  CommandState& state = State();
  state.name = name;
  state.json_output = json_output;
  if (!json_output || state.json_fd >= 0) return;
  std::fflush(stdout);
  state.json_fd = ::dup(STDOUT_FILENO);
  if (state.json_fd >= 0) ::dup2(STDERR_FILENO, STDOUT_FILENO);
}

int EndCommand(int code, const std::string& error_if_unset) {
  CommandState& state = State();
  if (!state.json_output) return code;
  nlohmann::json document = state.fields;
  document["command"] = state.name;
  document["ok"] = code == kExitOk;
  document["exit_code"] = code;
  if (code != kExitOk) document["error"] = state.error.empty() ? error_if_unset : state.error;
  const std::string text = document.dump(2) + "\n";
  std::fflush(stdout);
  std::fflush(stderr);
  const int fd = state.json_fd >= 0 ? state.json_fd : STDOUT_FILENO;
  for (std::size_t written = 0; written < text.size();) {
    const ssize_t n = ::write(fd, text.data() + written, text.size() - written);
    if (n <= 0) break;
    written += static_cast<std::size_t>(n);
  }
  return code;
}

const std::string& CommandName() { return State().name; }

}  // namespace internal
}  // namespace photorig::app
