#pragma once
// Connection handling in front of cpp-httplib's request parsing and routing
// (docs/daemon.md, "Connections"). One epoll thread owns every connection
// while it is idle or still sending its request's headers, and hands it to a
// worker only once the whole header block has arrived; after the answer a
// keep-alive connection returns to the loop. Idle and slow clients therefore
// hold no worker, and workers serve only requests that are ready.

#include <httplib.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

namespace photorig::daemon {

struct FrontOptions {
  int worker_threads = 64;
  // A request's header block must arrive whole within this time of its first
  // byte (or of the connection's start): a client trickling bytes is cut off.
  int header_timeout_ms = 5000;
  // A keep-alive connection silent this long between requests is closed.
  int idle_timeout_ms = 5000;
  // A worker's wait for more of a body, or for the client to take the answer.
  int io_timeout_ms = 5000;
  // Connections beyond this many are answered 503 and closed at once.
  int max_connections = 1024;
  std::size_t max_header_bytes = 64 * 1024;  // beyond it 431
  int listen_backlog = 128;
};

class HttpFront : public httplib::Server {
 public:
  explicit HttpFront(FrontOptions options);
  ~HttpFront() override;
  HttpFront(const HttpFront&) = delete;
  HttpFront& operator=(const HttpFront&) = delete;

  // Binds address:port (0: any free port) for this process alone: no
  // SO_REUSEPORT, so a second server on the port fails here. Returns the
  // port, or -1 with the failing call's errno in *error_number.
  int Listen(const std::string& address, int port, int* error_number);
  // Accepts and serves until Stop(); call from its own thread.
  void Serve();
  void Stop();
  // Answers one request given as the bytes a loopback client would send,
  // through the same parsing and routes but without a socket, and returns
  // the bytes it would read (fuzz/fuzz_api.cpp drives the API this way).
  std::string AnswerInMemory(const std::string& request);

 private:
  struct Connection;
  using Clock = std::chrono::steady_clock;

  void Accept();
  void ReadHeaders(Connection& connection);
  void Wait(Connection& connection, Clock::time_point deadline);
  void Dispatch(Connection& connection);
  void Close(int fd);
  void TakeReturned();
  void Work();
  void Answer(Connection& connection);
  void Wake();

  FrontOptions options_;
  int listen_fd_ = -1;
  int epoll_fd_ = -1;
  int wake_fd_ = -1;  // eventfd: a worker returned a connection, or Stop()
  bool listen_paused_ = false;  // out of descriptors: accepting resumes at the next sweep
  std::atomic<bool> stopping_{false};
  // Owned by the loop thread; a connection in a worker is not in epoll.
  std::unordered_map<int, std::unique_ptr<Connection>> connections_;

  std::mutex mutex_;
  std::condition_variable ready_cv_;
  std::deque<Connection*> ready_;     // to workers
  std::vector<Connection*> returned_;  // back to the loop (keep-alive) or to close
  std::vector<std::thread> workers_;
};

}  // namespace photorig::daemon
