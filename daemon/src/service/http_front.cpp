#include "http_front.h"

#include <spdlog/spdlog.h>

#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <stdexcept>

namespace photorig::daemon {

struct HttpFront::Connection {
  int fd = -1;
  sockaddr_storage peer{};
  socklen_t peer_size = 0;
  std::string buffer;       // bytes received and not yet parsed
  std::size_t start = 0;    // the first unparsed byte of `buffer`
  std::size_t scanned = 0;  // the header's end was not found before this
  bool waiting = false;     // in the loop (not in a worker)
  bool registered = false;  // added to epoll once
  bool keep = false;        // a worker's verdict: serve the next request
  Clock::time_point deadline;

  std::size_t Pending() const { return buffer.size() - start; }
  // Whether a whole header block is in: the request can be parsed without waiting.
  bool HasHeader() {
    const std::size_t from = std::max(start, scanned);
    if (buffer.find("\r\n\r\n", from) != std::string::npos) return true;
    scanned = buffer.size() < 3 ? 0 : buffer.size() - 3;
    return false;
  }
  void Consume(std::size_t n) {
    start += n;
    if (start == buffer.size()) buffer.clear(), start = 0, scanned = 0;
  }
};

namespace {

constexpr int kSweepMs = 100;  // how often deadlines are checked

// Set by the post-routing handler for the answer being written on this
// thread: the connection ends after it (the client asked, or the request's
// body may be left unread on the socket).
thread_local bool t_close_after_answer = false;

bool WaitFor(int fd, short events, int timeout_ms, short* revents = nullptr) {
  pollfd p{fd, events, 0};
  int r;
  do r = ::poll(&p, 1, timeout_ms);
  while (r < 0 && errno == EINTR);
  if (revents) *revents = p.revents;
  return r > 0;
}

// cpp-httplib's view of a connection: the bytes the loop read first, then the
// socket, with the front's timeouts.
class ConnectionStream final : public httplib::Stream {
 public:
  ConnectionStream(int fd, std::string& buffer, std::size_t& start, const sockaddr_storage& peer, socklen_t peer_size,
                   int timeout_ms, std::function<void(std::size_t)> consume)
      : fd_(fd), buffer_(buffer), start_(start), peer_(peer), peer_size_(peer_size), timeout_ms_(timeout_ms),
        consume_(std::move(consume)) {}

  bool is_readable() const override { return start_ < buffer_.size() || WaitFor(fd_, POLLIN, timeout_ms_); }

  // A client that has hung up is not writable: a stream or download it
  // abandoned ends at the next check instead of at a write that fails
  // only once the socket's buffer is full.
  bool is_writable() const override {
    short revents = 0;
    if (!WaitFor(fd_, POLLOUT | POLLRDHUP, timeout_ms_, &revents)) return false;
    return (revents & (POLLRDHUP | POLLHUP | POLLERR)) == 0 && (revents & POLLOUT) != 0;
  }

  ssize_t read(char* ptr, size_t size) override {
    if (start_ < buffer_.size()) {
      const std::size_t n = std::min(size, buffer_.size() - start_);
      std::memcpy(ptr, buffer_.data() + start_, n);
      consume_(n);
      return static_cast<ssize_t>(n);
    }
    for (;;) {
      const ssize_t n = ::recv(fd_, ptr, size, 0);
      if (n >= 0) return n;
      if (errno == EINTR) continue;
      if ((errno != EAGAIN && errno != EWOULDBLOCK) || !WaitFor(fd_, POLLIN, timeout_ms_)) return -1;
    }
  }

  ssize_t write(const char* ptr, size_t size) override {
    std::size_t sent = 0;
    while (sent < size) {
      const ssize_t n = ::send(fd_, ptr + sent, size - sent, MSG_NOSIGNAL);
      if (n > 0) {
        sent += static_cast<std::size_t>(n);
      } else if (n < 0 && errno == EINTR) {
        continue;
      } else if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK) && WaitFor(fd_, POLLOUT, timeout_ms_)) {
        continue;
      } else {
        return sent > 0 ? static_cast<ssize_t>(sent) : -1;
      }
    }
    return static_cast<ssize_t>(sent);
  }

  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    Describe(reinterpret_cast<const sockaddr*>(&peer_), peer_size_, ip, port);
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage local{};
    socklen_t size = sizeof(local);
    if (::getsockname(fd_, reinterpret_cast<sockaddr*>(&local), &size) == 0)
      Describe(reinterpret_cast<const sockaddr*>(&local), size, ip, port);
  }
  socket_t socket() const override { return fd_; }

 private:
  static void Describe(const sockaddr* address, socklen_t size, std::string& ip, int& port) {
    char host[NI_MAXHOST], service[NI_MAXSERV];
    if (::getnameinfo(address, size, host, sizeof(host), service, sizeof(service), NI_NUMERICHOST | NI_NUMERICSERV) == 0) {
      ip = host;
      port = std::atoi(service);
    }
  }

  int fd_;
  std::string& buffer_;
  const std::size_t& start_;
  const sockaddr_storage& peer_;
  socklen_t peer_size_;
  int timeout_ms_;
  std::function<void(std::size_t)> consume_;
};

// A client without a socket: it sends its bytes at once, half-closes, and
// takes the answer's headers and first part of its body before it hangs up,
// so an event stream or a download ends instead of waiting for more.
class MemoryStream final : public httplib::Stream {
 public:
  explicit MemoryStream(const std::string& request) : request_(request) {}

  bool is_readable() const override { return read_ < request_.size(); }
  bool is_writable() const override { return writes_ < 2; }  // the headers, then one part of the body

  ssize_t read(char* ptr, size_t size) override {
    const std::size_t n = std::min(size, request_.size() - read_);
    std::memcpy(ptr, request_.data() + read_, n);
    read_ += n;
    return static_cast<ssize_t>(n);
  }
  ssize_t write(const char* ptr, size_t size) override {
    ++writes_;
    answer_.append(ptr, size);
    return static_cast<ssize_t>(size);
  }
  void get_remote_ip_and_port(std::string& ip, int& port) const override { ip = "127.0.0.1", port = 40000; }
  void get_local_ip_and_port(std::string& ip, int& port) const override { ip = "127.0.0.1", port = 0; }
  socket_t socket() const override { return INVALID_SOCKET; }

  const std::string& answer() const { return answer_; }

 private:
  const std::string& request_;
  std::size_t read_ = 0;
  int writes_ = 0;
  std::string answer_;
};

// A whole answer the loop sends itself before closing (best effort: the
// socket is not waited for).
void SendAndClose(int fd, int status, const char* reason, const std::string& message) {
  const std::string body = "{\"error\": \"" + message + "\"}";
  const std::string text = "HTTP/1.1 " + std::to_string(status) + " " + reason +
                           "\r\nContent-Type: application/json\r\nContent-Length: " + std::to_string(body.size()) +
                           "\r\nConnection: close\r\n\r\n" + body;
  [[maybe_unused]] const ssize_t sent = ::send(fd, text.data(), text.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
  ::close(fd);
}

}  // namespace

HttpFront::HttpFront(FrontOptions options)
    : options_(options), epoll_fd_(::epoll_create1(EPOLL_CLOEXEC)), wake_fd_(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC)) {
  if (epoll_fd_ < 0 || wake_fd_ < 0) throw std::runtime_error(std::string("HTTP front: ") + std::strerror(errno));
  set_keep_alive_timeout(std::max(1, options_.idle_timeout_ms / 1000));
  set_post_routing_handler([](const httplib::Request& req, httplib::Response& res) {
    // A request refused before its body was read (403, 401, 415, ...) leaves
    // that body on the socket, where it would be parsed as the next request.
    const bool body_unread =
        req.body.empty() && std::strtoull(req.get_header_value("Content-Length").c_str(), nullptr, 10) > 0;
    t_close_after_answer = body_unread || res.get_header_value("Connection") == "close" || res.status == 400 ||
                           res.status == 411 || res.status == 413 || res.status == 414;
    if (body_unread) res.set_header("Connection", "close");
  });
}

HttpFront::~HttpFront() {
  for (const auto& [fd, connection] : connections_) ::close(fd);
  for (int fd : {listen_fd_, epoll_fd_, wake_fd_})
    if (fd >= 0) ::close(fd);
}

int HttpFront::Listen(const std::string& address, int port, int* error_number) {
  *error_number = 0;
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
  addrinfo* found = nullptr;
  if (const int e = ::getaddrinfo(address.c_str(), std::to_string(port).c_str(), &hints, &found); e != 0) {
    *error_number = EADDRNOTAVAIL;
    return -1;
  }
  for (addrinfo* ai = found; ai && listen_fd_ < 0; ai = ai->ai_next) {
    const int fd = ::socket(ai->ai_family, ai->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, ai->ai_protocol);
    if (fd < 0) continue;
    // SO_REUSEADDR alone lets a restart bind over connections in TIME_WAIT;
    // unlike SO_REUSEPORT it never lets a second listener share the port.
    const int yes = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
    if (::bind(fd, ai->ai_addr, ai->ai_addrlen) == 0 && ::listen(fd, options_.listen_backlog) == 0) {
      listen_fd_ = fd;
    } else {
      *error_number = errno;
      ::close(fd);
    }
  }
  ::freeaddrinfo(found);
  if (listen_fd_ < 0) return -1;
  sockaddr_storage bound{};
  socklen_t size = sizeof(bound);
  ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&bound), &size);
  svr_sock_ = listen_fd_;  // cpp-httplib's "not shutting down"
  return ntohs(bound.ss_family == AF_INET6 ? reinterpret_cast<sockaddr_in6*>(&bound)->sin6_port
                                           : reinterpret_cast<sockaddr_in*>(&bound)->sin_port);
}

void HttpFront::Stop() {
  if (stopping_.exchange(true)) return;
  svr_sock_ = INVALID_SOCKET;  // content providers (event streams) end
  Wake();
  ready_cv_.notify_all();
}

void HttpFront::Serve() {
  if (listen_fd_ < 0) throw std::runtime_error("HTTP front: Serve() before Listen()");
  for (int fd : {listen_fd_, wake_fd_}) {
    epoll_event event{};
    event.events = EPOLLIN;
    event.data.fd = fd;
    ::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, fd, &event);
  }
  for (int i = 0; i < options_.worker_threads; ++i) workers_.emplace_back([this] { Work(); });

  auto last_sweep = Clock::now();
  std::vector<epoll_event> events(256);
  while (!stopping_) {
    const int n = ::epoll_wait(epoll_fd_, events.data(), static_cast<int>(events.size()), kSweepMs);
    for (int i = 0; i < n; ++i) {
      const int fd = events[i].data.fd;
      if (fd == listen_fd_) {
        Accept();
      } else if (fd == wake_fd_) {
        std::uint64_t count;
        [[maybe_unused]] const ssize_t r = ::read(wake_fd_, &count, sizeof(count));
        TakeReturned();
      } else if (auto it = connections_.find(fd); it != connections_.end() && it->second->waiting) {
        ReadHeaders(*it->second);
      }
    }
    const auto now = Clock::now();
    if (now - last_sweep >= std::chrono::milliseconds(kSweepMs)) {
      last_sweep = now;
      std::vector<int> expired;
      for (const auto& [fd, connection] : connections_)
        if (connection->waiting && connection->deadline <= now) expired.push_back(fd);
      for (int fd : expired) Close(fd);
      // Out of descriptors, accepting was paused (Accept) rather than spun on.
      if (listen_paused_) {
        epoll_event event{};
        event.events = EPOLLIN;
        event.data.fd = listen_fd_;
        listen_paused_ = ::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, listen_fd_, &event) != 0;
      }
    }
  }

  {
    std::lock_guard lock(mutex_);
    ready_.clear();  // connections not yet served are closed below
  }
  ready_cv_.notify_all();
  for (std::thread& worker : workers_) worker.join();
  workers_.clear();
  std::vector<int> open;
  for (const auto& [fd, connection] : connections_) open.push_back(fd);
  for (int fd : open) Close(fd);
}

void HttpFront::Accept() {
  for (;;) {
    auto connection = std::make_unique<Connection>();
    connection->peer_size = sizeof(connection->peer);
    const int fd = ::accept4(listen_fd_, reinterpret_cast<sockaddr*>(&connection->peer), &connection->peer_size,
                             SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) {
      if (errno == EINTR || errno == ECONNABORTED) continue;
      if (errno == EMFILE || errno == ENFILE || errno == ENOBUFS || errno == ENOMEM) {
        spdlog::warn("event=http_accept_paused error=\"{}\"", std::strerror(errno));
        ::epoll_ctl(epoll_fd_, EPOLL_CTL_DEL, listen_fd_, nullptr);
        listen_paused_ = true;
      }
      return;
    }
    if (static_cast<int>(connections_.size()) >= options_.max_connections) {
      SendAndClose(fd, 503, "Service Unavailable",
                   "too many open connections (" + std::to_string(options_.max_connections) + ")");
      continue;
    }
    connection->fd = fd;
    Connection& added = *connection;
    connections_.emplace(fd, std::move(connection));
    Wait(added, Clock::now() + std::chrono::milliseconds(options_.header_timeout_ms));
  }
}

void HttpFront::Wait(Connection& connection, Clock::time_point deadline) {
  connection.waiting = true;
  connection.deadline = deadline;
  epoll_event event{};
  event.events = EPOLLIN | EPOLLRDHUP | EPOLLONESHOT;
  event.data.fd = connection.fd;
  ::epoll_ctl(epoll_fd_, connection.registered ? EPOLL_CTL_MOD : EPOLL_CTL_ADD, connection.fd, &event);
  connection.registered = true;
}

void HttpFront::ReadHeaders(Connection& connection) {
  const bool was_idle = connection.Pending() == 0;
  bool ended = false;
  char chunk[16384];
  for (;;) {
    const ssize_t n = ::recv(connection.fd, chunk, sizeof(chunk), 0);
    if (n > 0) {
      connection.buffer.append(chunk, static_cast<std::size_t>(n));
      if (connection.Pending() > options_.max_header_bytes) break;
    } else if (n < 0 && errno == EINTR) {
      continue;
    } else {
      ended = n == 0 || (errno != EAGAIN && errno != EWOULDBLOCK);
      break;
    }
  }
  if (connection.HasHeader()) return Dispatch(connection);
  if (ended) return Close(connection.fd);
  if (connection.Pending() > options_.max_header_bytes) {
    const int fd = connection.fd;
    connections_.erase(fd);
    return SendAndClose(fd, 431, "Request Header Fields Too Large",
                        "the request's headers exceed " + std::to_string(options_.max_header_bytes) + " bytes");
  }
  // The header timeout runs from a request's first byte, not from each byte.
  const auto deadline = was_idle && connection.Pending() > 0
                            ? Clock::now() + std::chrono::milliseconds(options_.header_timeout_ms)
                            : connection.deadline;
  Wait(connection, deadline);
}

void HttpFront::Dispatch(Connection& connection) {
  connection.waiting = false;
  {
    std::lock_guard lock(mutex_);
    ready_.push_back(&connection);
  }
  ready_cv_.notify_one();
}

void HttpFront::Close(int fd) {
  ::epoll_ctl(epoll_fd_, EPOLL_CTL_DEL, fd, nullptr);
  ::close(fd);
  connections_.erase(fd);
}

void HttpFront::TakeReturned() {
  std::vector<Connection*> returned;
  {
    std::lock_guard lock(mutex_);
    returned.swap(returned_);
  }
  const auto now = Clock::now();
  for (Connection* connection : returned) {
    if (!connection->keep || stopping_) {
      Close(connection->fd);
    } else if (connection->HasHeader()) {
      Dispatch(*connection);
    } else {
      const int timeout_ms = connection->Pending() > 0 ? options_.header_timeout_ms : options_.idle_timeout_ms;
      Wait(*connection, now + std::chrono::milliseconds(timeout_ms));
    }
  }
}

void HttpFront::Work() {
  for (;;) {
    Connection* connection = nullptr;
    {
      std::unique_lock lock(mutex_);
      ready_cv_.wait(lock, [this] { return stopping_ || !ready_.empty(); });
      if (ready_.empty()) return;
      connection = ready_.front();
      ready_.pop_front();
    }
    Answer(*connection);
    {
      std::lock_guard lock(mutex_);
      returned_.push_back(connection);
    }
    Wake();
  }
}

void HttpFront::Wake() {
  const std::uint64_t one = 1;
  [[maybe_unused]] const ssize_t n = ::write(wake_fd_, &one, sizeof(one));
}

void HttpFront::Answer(Connection& connection) {
  ConnectionStream stream(connection.fd, connection.buffer, connection.start, connection.peer, connection.peer_size,
                          options_.io_timeout_ms, [&connection](std::size_t n) { connection.Consume(n); });
  // Requests already in whole (pipelined) are answered here; anything else
  // waits in the loop.
  do {
    bool client_closes = false;
    t_close_after_answer = false;
    const bool answered = process_request(stream, stopping_, client_closes, nullptr);
    connection.keep = answered && !client_closes && !t_close_after_answer && !stopping_;
  } while (connection.keep && connection.HasHeader());
}

std::string HttpFront::AnswerInMemory(const std::string& request) {
  MemoryStream stream(request);
  bool client_closes = false;
  t_close_after_answer = false;
  process_request(stream, true, client_closes, nullptr);
  return stream.answer();
}

}  // namespace photorig::daemon
