#pragma once
// Error reporting shared by every device interface: devices never throw across
// their interface, they return a Status (or a Result<T>) naming what failed.

#include <optional>
#include <string>
#include <utility>
#include <variant>

namespace photorig {

enum class StatusCode {
  kOk = 0,
  kInvalidArgument,    // caller passed something the device cannot accept
  kFailedPrecondition, // illegal state transition (e.g. trigger before start)
  kUnavailable,        // device unreachable / disconnected
  kTimeout,            // device did not answer in time
  kDataLoss,           // frame dropped, short or corrupt
  kInternal,
};

const char* StatusCodeName(StatusCode code);

// The refusal of an Options::IsValid: sets *why (when given) to `reason` and
// returns false, so each check is one line:
//   if (buffer_count < 1) return Refuse(why, "buffer_count must be >= 1");
bool Refuse(std::string* why, std::string reason);

class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}
  static Status Ok() { return {}; }

  bool ok() const { return code_ == StatusCode::kOk; }
  StatusCode code() const { return code_; }
  const std::string& message() const { return message_; }
  // "Timeout: camera sim-cam0: no frame within 250 ms"
  std::string ToString() const;

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string message_;
};

// A value or the Status explaining why there is none.
template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : value_(std::move(value)) {}
  Result(Status status) : status_(std::move(status)) {}

  bool ok() const { return value_.has_value(); }
  const Status& status() const { return status_; }
  T& value() & { return *value_; }
  const T& value() const& { return *value_; }
  T&& value() && { return std::move(*value_); }
  T* operator->() { return &*value_; }
  const T* operator->() const { return &*value_; }

 private:
  std::optional<T> value_;
  Status status_;
};

}  // namespace photorig
