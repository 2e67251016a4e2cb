#pragma once
// How a CLI command reaches photorigd: --url (default $PHOTORIG_URL or
// http://127.0.0.1:8750) and --token-file (default $PHOTORIG_TOKEN, else the
// file $PHOTORIG_TOKEN_FILE names, e.g. a daemon's DATA/api-token); --json
// is every command's (docs/cli.md). Shared by the remote commands and
// `photorig fetch`.

#include "photorig/daemon/service/internal/api_client.h"

#include <CLI/CLI.hpp>

#include <cstdlib>
#include <fstream>
#include <string>

namespace photorig::app {

struct Connection {
  std::string url;
  std::string token_file;

  void AddOptions(CLI::App* sub) {
    const char* env_url = std::getenv("PHOTORIG_URL");
    url = env_url ? env_url : "http://127.0.0.1:8750";
    // A malformed address is a usage error (exit 2), not an unreachable daemon.
    const CLI::Validator http_url(
        [](std::string& value) -> std::string {
          const bool scheme = value.rfind("http://", 0) == 0 || value.rfind("https://", 0) == 0;
          const std::size_t host = value.find("://") + 3;
          if (scheme && host < value.size() && value[host] != '/' && value[host] != ':') return "";
          return "'" + value + "' is not an address like http://HOST:PORT";
        },
        "URL");
    sub->add_option("--url", url, "photorigd address ($PHOTORIG_URL)")->capture_default_str()->check(http_url);
    sub->add_option("--token-file", token_file, "bearer token file (default: $PHOTORIG_TOKEN, else $PHOTORIG_TOKEN_FILE)")
        ->check(CLI::ExistingFile);
  }

  daemon::ApiClient Client(int timeout_s = 30) const {
    daemon::ApiClientOptions options;
    options.url = url;
    options.timeout_s = timeout_s;
    const char* env_token = std::getenv("PHOTORIG_TOKEN");
    const char* env_file = std::getenv("PHOTORIG_TOKEN_FILE");
    if (token_file.empty() && env_token) {
      options.token = env_token;
    } else if (std::ifstream in(!token_file.empty() ? token_file : env_file ? env_file : ""); in) {
      std::getline(in, options.token);
    }
    return daemon::ApiClient(options);
  }

  // What to say when nothing answers at `url`.
  std::string Unreachable() const {
    return "photorigd is not reachable at " + url +
           "; start it with `photorigd --rig RIG.yaml --data-root DIR` (docs/daemon.md), or point --url or "
           "$PHOTORIG_URL at the one that runs";
  }
};

}  // namespace photorig::app
