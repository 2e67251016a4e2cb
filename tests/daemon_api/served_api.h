#pragma once
// A RunService and its ApiServer on a free loopback port, served from a
// thread for as long as the object lives: the in-process daemon the API
// tests talk to over real sockets.
#include "photorig/daemon/service/internal/api_client.h"
#include "photorig/daemon/service/api_server.h"
#include "photorig/daemon/service/service.h"

#include <memory>
#include <string>
#include <thread>

namespace photorig::daemon {

class ServedApi {
 public:
  ServedApi(const ServiceOptions& service_options, const ApiOptions& api_options)
      : service_(std::make_unique<RunService>(service_options)),
        server_(std::make_unique<ApiServer>(*service_, api_options)) {
    server_->Bind();
    service_->Start();
    serving_ = std::thread([this] { server_->Serve(); });
  }
  ~ServedApi() {
    service_->Stop();
    server_->Stop();
    if (serving_.joinable()) serving_.join();
  }
  ServedApi(const ServedApi&) = delete;
  ServedApi& operator=(const ServedApi&) = delete;

  RunService& service() { return *service_; }
  int port() const { return server_->port(); }
  std::string Url() const { return "http://127.0.0.1:" + std::to_string(port()); }
  ApiClient Client(const std::string& token = "") const {
    ApiClientOptions options;
    options.url = Url();
    options.token = token;
    options.timeout_s = 20;
    return ApiClient(options);
  }

 private:
  std::unique_ptr<RunService> service_;
  std::unique_ptr<ApiServer> server_;
  std::thread serving_;
};

}  // namespace photorig::daemon
