#pragma once
// A solver's per-item flag word (a light's, an LED's) as text for reports.

#include <array>
#include <cstddef>
#include <string>
#include <utility>

namespace photorig::solvers::core {

// "a,b": the names of the bits set in `flags`, in the table's order; "ok"
// when none is. The table's values are single bits.
template <std::size_t N>
std::string FlagNames(unsigned flags, const std::array<std::pair<unsigned, const char*>, N>& table) {
  std::string text;
  for (const auto& [bit, name] : table) {
    if (!(flags & bit)) continue;
    if (!text.empty()) text += ',';
    text += name;
  }
  return text.empty() ? "ok" : text;
}

}  // namespace photorig::solvers::core
