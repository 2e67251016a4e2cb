// photorigd: the rig daemon. Keeps a persistent queue of capture recipes,
// runs them on its rig one at a time and serves the HTTP API (see
// daemon/include/photorig/daemon/service/api_server.h and docs/api.md).
//   photorigd [--data-root DIR] --rig RIG.yaml [--listen ADDR] [--port N] [--token-file FILE] [--allow-host NAME]
//             [--web-root DIR] [--recipes DIR]
// It prints the browser interface's address on stdout once it listens (docs/ui.md).
// Listening off loopback without a token, it uses the one in DATA/api-token,
// made at the first such start, and says so. A port another process holds
// ends it with exit code 2, naming that process.
// On SIGTERM or SIGINT the current run finishes its frame, the lights go off
// and the run stays queued for the next start. Under systemd (Type=notify)
// it reports readiness and feeds the watchdog while the worker is alive.

#include "photorig/config/yaml_node.h"
#include "photorig/daemon/service/api_server.h"
#include "photorig/daemon/service/service.h"
#include "library_logging.h"
#include "signals.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>
#include <systemd/sd-daemon.h>

#include <sys/stat.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <thread>

namespace {

// The browser interface's pages: installed beside the executable
// (<prefix>/bin/../share/photorig/web), else the source tree's daemon/web
// (a build tree); empty when neither exists.
std::string DefaultWebRoot() {
  namespace fs = std::filesystem;
  std::error_code error;
  const fs::path exe = fs::read_symlink("/proc/self/exe", error);
  for (const fs::path& candidate : {exe.parent_path().parent_path() / "share" / "photorig" / "web",
                                    fs::path(PHOTORIG_WEB_SOURCE_DIR)})
    if (fs::is_regular_file(candidate / "index.html", error)) return candidate.string();
  return "";
}

// The token of a daemon that listens off loopback and was given none: the
// one in DATA/api-token, or a new random one written there (readable by its
// owner alone) so clients can be given the file and it survives restarts.
std::string StoredToken(const std::filesystem::path& file) {
  std::string token;
  if (std::ifstream in(file); in) {
    std::getline(in, token);
    if (!token.empty()) return token;
  }
  unsigned char bytes[24];
  std::ifstream random("/dev/urandom", std::ios::binary);
  if (!random.read(reinterpret_cast<char*>(bytes), sizeof(bytes)))
    throw std::runtime_error("cannot read /dev/urandom to make a bearer token");
  for (unsigned char byte : bytes) {
    char hex[3];
    std::snprintf(hex, sizeof(hex), "%02x", byte);
    token += hex;
  }
  const mode_t before = ::umask(077);
  std::ofstream out(file, std::ios::trunc);
  out << token << "\n";
  out.close();
  ::umask(before);
  if (!out) throw std::runtime_error("cannot write the bearer token to " + file.string());
  return token;
}

// Where the queue and runs live without --data-root: systemd's
// StateDirectory=, else the user's data directory (XDG), never the working
// directory, where `photorig run` keeps its own runs/. Empty when there is no
// home to put it in.
std::string DefaultDataRoot() {
  if (const char* state = std::getenv("STATE_DIRECTORY"); state && *state) {
    const std::string first(state);  // several directories are separated by ':'
    return first.substr(0, first.find(':'));
  }
  if (const char* xdg = std::getenv("XDG_DATA_HOME"); xdg && *xdg == '/') return std::string(xdg) + "/photorig";
  if (const char* home = std::getenv("HOME"); home && *home == '/') return std::string(home) + "/.local/share/photorig";
  return "";
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"photorigd: runs queued capture recipes on the rig, driven over HTTP"};
  photorig::daemon::ServiceOptions service_options;
  photorig::daemon::ApiOptions api_options;
  std::string token_file;
  bool no_resume = false;
  bool no_solve = false;
  std::string log_level = "info";
  service_options.data_root = DefaultDataRoot();
  app.add_option("--data-root", service_options.data_root,
                 "queue, recipes and run directories live here (default: $STATE_DIRECTORY under systemd, else "
                 "$XDG_DATA_HOME/photorig, else ~/.local/share/photorig)")
      ->capture_default_str();
  app.add_option("--rig", service_options.rig_path, "rig YAML this daemon drives")->required()->check(CLI::ExistingFile);
  app.add_option("--listen", api_options.bind_address, "address to bind (off loopback every API request needs the token: --token-file, $PHOTORIG_TOKEN, else "
                 "one kept in DATA/api-token)")
      ->capture_default_str();
  app.add_option("--port", api_options.port, "TCP port (0: any free port, printed at start)")->capture_default_str();
  app.add_option("--allow-host", api_options.allowed_hosts,
                 "a host name browsers and clients without a token may use besides loopback addresses and localhost "
                 "(exact, repeatable)");
  app.add_option("--token-file", token_file, "file holding the bearer token (default: $PHOTORIG_TOKEN)")
      ->check(CLI::ExistingFile);
  app.add_option("--web-root", api_options.web_root,
                 "folder of the browser interface's pages (default: installed share/photorig/web, else the "
                 "source tree's daemon/web; 'none': no interface)");
  app.add_option("--recipes", service_options.recipe_folders,
                 "a folder of recipes the interface offers (repeatable; default: the recipes folder beside the "
                 "rig's folder, e.g. config/recipes for config/rigs/sim-dome.yaml)");
  app.add_flag("--no-resume", no_resume, "mark runs a crash interrupted as interrupted instead of resuming them");
  app.add_flag("--no-solve", no_solve, "capture only; skip the recipes' solve: stages");
  app.add_option("--max-attempts", service_options.retry.max_attempts_per_step,
                 "attempts per step before a device fault fails the run")
      ->capture_default_str();
  app.add_option("--backoff-ms", service_options.retry.initial_backoff_ms, "first retry backoff")->capture_default_str();
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error")->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // Help exits 0; bad flags and a missing --rig file exit 2, as photorig's do, not with CLI11's own codes.
    const int printed = app.exit(e);
    return printed == 0 ? 0 : 2;
  }
  if (service_options.data_root.empty()) {
    std::cerr << "photorigd: no --data-root, and no $HOME for the default ~/.local/share/photorig: give --data-root DIR\n";
    return 2;
  }
  if (api_options.web_root.empty()) api_options.web_root = DefaultWebRoot();
  if (api_options.web_root == "none") api_options.web_root.clear();
  if (service_options.recipe_folders.empty()) {
    const auto beside = std::filesystem::absolute(service_options.rig_path).parent_path().parent_path() / "recipes";
    if (std::filesystem::is_directory(beside)) service_options.recipe_folders.push_back(beside.lexically_normal().string());
  }
  service_options.resume_interrupted = !no_resume;
  service_options.solve = !no_solve;
  if (!token_file.empty()) {
    std::ifstream in(token_file);
    std::getline(in, api_options.token);
  } else if (const char* token = std::getenv("PHOTORIG_TOKEN")) {
    api_options.token = token;
  }

  // logfmt: one event per line, key=value, easy for journald and grep alike.
  spdlog::set_pattern("ts=%Y-%m-%dT%H:%M:%S.%e%z level=%l %v");
  spdlog::set_level(spdlog::level::from_str(log_level));
  photorig::app::QuietLibraryLogging(argv[0]);
  photorig::app::InstallStopHandlers();
  try {
    photorig::daemon::RunService service(service_options);
    if (api_options.token.empty() && !photorig::daemon::IsLoopbackAddress(api_options.bind_address)) {
      const auto file = std::filesystem::absolute(service_options.data_root) / "api-token";
      api_options.token = StoredToken(file);
      std::cout << "photorigd: listening on " << api_options.bind_address << " needs a bearer token: it is in "
                << file.string() << " (give clients --token-file " << file.string() << ")" << std::endl;
    }
    photorig::daemon::ApiServer server(service, api_options);
    server.Bind();
    service.Start();
    std::thread serving([&server] { server.Serve(); });
    spdlog::info("event=ready listen={}:{} data_root={} rig={} auth={}", api_options.bind_address, server.port(),
                 service_options.data_root, service_options.rig_path, api_options.token.empty() ? "none" : "bearer");
    if (!api_options.web_root.empty()) {
      // The address to open (a literal IPv6 address goes in brackets).
      const std::string& host = api_options.bind_address;
      std::cout << "photorigd: open http://" << (host.find(':') != std::string::npos ? "[" + host + "]" : host) << ":"
                << server.port() << "/" << (api_options.token.empty() ? "" : "#token=<your token>") << std::endl;
    }
    sd_notifyf(0, "READY=1\nSTATUS=listening on %s:%d", api_options.bind_address.c_str(), server.port());

    std::uint64_t watchdog_us = 0;
    const bool watchdog = sd_watchdog_enabled(0, &watchdog_us) > 0;
    const auto watchdog_period = std::chrono::microseconds(watchdog_us / 2);
    auto last_ping = std::chrono::steady_clock::now();
    while (!photorig::app::g_stop_requested) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      if (watchdog && std::chrono::steady_clock::now() - last_ping >= watchdog_period && service.Healthy()) {
        sd_notify(0, "WATCHDOG=1");
        last_ping = std::chrono::steady_clock::now();
      }
    }
    spdlog::info("event=stopping reason=signal");
    sd_notify(0, "STOPPING=1");
    service.Stop();  // the current frame completes, lights off, run stays queued
    server.Stop();
    serving.join();
    spdlog::info("event=stopped");
  } catch (const photorig::daemon::BindError& e) {
    spdlog::error("event=fatal error={}", nlohmann::json(e.what()).dump());
    std::cerr << "photorigd: " << e.what() << std::endl;
    return 2;
  } catch (const photorig::config::ConfigError& e) {
    // A rig that does not load is a configuration error (exit 2), as for photorig.
    spdlog::error("event=fatal error={}", nlohmann::json(e.what()).dump());
    std::cerr << "photorigd: configuration error: " << e.what() << std::endl;
    return 2;
  } catch (const std::exception& e) {
    spdlog::error("event=fatal error={}", nlohmann::json(e.what()).dump());
    std::cerr << "photorigd: " << e.what() << std::endl;
    return 1;
  }
  return 0;
}
