#pragma once
// A Summary as the JSON reports carry it: {"termination", "message",
// "timings_ms": {"setup", "solve", "total"}}, to which each stage adds its
// own figures. Header-only, so that solvers/core itself needs no JSON library;
// whoever includes this needs nlohmann/json (Debian's nlohmann-json3-dev).

#include "photorig/solvers/core/summary.h"

#include <nlohmann/json.hpp>

namespace photorig::solvers::core {

inline nlohmann::json ToJson(const Summary& summary) {
  return {{"termination", TerminationName(summary.termination)},
          {"message", summary.message},
          {"timings_ms", {{"setup", summary.setup_ms}, {"solve", summary.solve_ms}, {"total", summary.total_ms}}}};
}

}  // namespace photorig::solvers::core
