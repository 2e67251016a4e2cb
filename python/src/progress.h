#pragma once
// A Python callable as a solver's ProgressCallback. The solver calls it on
// its own thread with the GIL released; the bridge takes the GIL for the
// call. A callback that raises does not stop the solver (its callbacks must
// not throw): the first exception is kept and raised when the solve returns.

#include "photorig/solvers/core/progress.h"

#include <pybind11/pybind11.h>

#include <memory>
#include <optional>

namespace photorig::python {

class ProgressBridge {
 public:
  explicit ProgressBridge(pybind11::object callback) : callback_(std::move(callback)) {}

  // Empty when there is no callback (a solver's empty callback costs nothing).
  solvers::core::ProgressCallback Callback() {
    if (callback_.is_none()) return {};
    return [this](const solvers::core::Progress& progress) {
      pybind11::gil_scoped_acquire locked;
      if (error_) return;
      try {
        callback_(std::string(progress.stage), progress.done, progress.total);
      } catch (pybind11::error_already_set& e) {
        error_ = std::make_unique<pybind11::error_already_set>(std::move(e));
      }
    };
  }
  // Raises the callback's exception, if it raised one. Call with the GIL held.
  void RethrowIfFailed() {
    if (error_) throw std::move(*error_);
  }

 private:
  pybind11::object callback_;
  std::unique_ptr<pybind11::error_already_set> error_;
};

}  // namespace photorig::python
