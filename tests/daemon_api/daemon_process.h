#pragma once
// The real photorigd in a child process, its output appended to a log file.

#include "test_support.h"

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <regex>
#include <string>
#include <thread>
#include <vector>

namespace photorig::testing {

class DaemonProcess {
 public:
  // photorigd --data-root DATA --rig RIG --port PORT ARGS...
  DaemonProcess(const std::filesystem::path& data_root, const std::string& rig, const std::filesystem::path& log,
                const std::vector<std::string>& args, int port = 0) {
    std::vector<std::string> argv = {std::string(PHOTORIG_BIN_DIR) + "/photorigd", "--data-root", data_root.string(),
                                     "--rig", rig, "--port", std::to_string(port)};
    argv.insert(argv.end(), args.begin(), args.end());
    pid_ = ::fork();
    if (pid_ == 0) {
      if (!std::freopen(log.c_str(), "a", stdout) || !std::freopen(log.c_str(), "a", stderr)) _exit(126);
      std::vector<char*> raw;
      for (std::string& arg : argv) raw.push_back(arg.data());
      raw.push_back(nullptr);
      ::execv(raw[0], raw.data());
      _exit(127);
    }
  }
  ~DaemonProcess() {
    if (pid_ > 0) Kill();
  }
  pid_t pid() const { return pid_; }
  DaemonProcess(const DaemonProcess&) = delete;
  DaemonProcess& operator=(const DaemonProcess&) = delete;

  // The port from the "event=ready" line of this start (the log is appended
  // to); 0 when it did not come within 5 s.
  int WaitReady(const std::filesystem::path& log, int starts_before) {
    static const std::regex ready(R"(event=ready listen=127\.0\.0\.1:(\d+))");
    for (int i = 0; i < 500; ++i) {
      const std::string text = ReadText(log);
      int seen = 0;
      int port = 0;
      for (auto it = std::sregex_iterator(text.begin(), text.end(), ready); it != std::sregex_iterator(); ++it) {
        ++seen;
        port = std::stoi((*it)[1]);
      }
      if (seen > starts_before) return port;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return 0;
  }
  void Kill() {
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }
  // The exit code once the process ends by itself within `timeout`; -1 if
  // it is still running then (or was killed by a signal).
  int WaitExit(std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    int status = 0;
    while (::waitpid(pid_, &status, WNOHANG) == 0) {
      if (std::chrono::steady_clock::now() > deadline) return -1;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  // SIGTERM; the exit code.
  int Terminate() {
    ::kill(pid_, SIGTERM);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

 private:
  pid_t pid_ = -1;
};

}  // namespace photorig::testing
