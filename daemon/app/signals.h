#pragma once
// SIGINT/SIGTERM request a stop; the sequencer finishes the current step,
// switches the lights off and closes the devices before the process exits.

#include <atomic>
#include <csignal>

namespace photorig::app {

inline std::atomic<bool> g_stop_requested{false};

inline void InstallStopHandlers() {
  struct sigaction action {};
  action.sa_handler = [](int) { g_stop_requested.store(true); };
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

}  // namespace photorig::app
