#pragma once
// The one table that names an enum's values. A solver family declares it
// beside its enum,
//
//   enum class Method { kArt, kSirt };
//   inline constexpr NameTable<Method, 2> kMethodNames = {{{Method::kArt, "art"}, {Method::kSirt, "sirt"}}};
//
// and everything that reads or writes the names goes through it: the YAML and
// command-line parsers (ParseName), reports (NameOf), the CLI's choice lists
// and help (NameMap, JoinNames). A method is a string only at those edges.

#include <array>
#include <cstddef>
#include <map>
#include <optional>
#include <string>
#include <string_view>

namespace photorig::solvers::core {

template <typename Enum>
struct NamedValue {
  Enum value;
  const char* name;
};

template <typename Enum, std::size_t N>
using NameTable = std::array<NamedValue<Enum>, N>;

// The value named `name` exactly; nullopt for any other text.
template <typename Enum, std::size_t N>
constexpr std::optional<Enum> ParseName(const NameTable<Enum, N>& table, std::string_view name) {
  for (const NamedValue<Enum>& entry : table)
    if (name == entry.name) return entry.value;
  return std::nullopt;
}

// The name of `value`; "unknown" for a value the table lacks (a cast integer).
template <typename Enum, std::size_t N>
constexpr const char* NameOf(const NameTable<Enum, N>& table, Enum value) {
  for (const NamedValue<Enum>& entry : table)
    if (entry.value == value) return entry.name;
  return "unknown";
}

// "a | b | c": the choices as help texts and error messages list them.
template <typename Enum, std::size_t N>
std::string JoinNames(const NameTable<Enum, N>& table, std::string_view separator = " | ") {
  std::string joined;
  for (const NamedValue<Enum>& entry : table) {
    if (!joined.empty()) joined += separator;
    joined += entry.name;
  }
  return joined;
}

// "a, b or c": the choices as an error message lists them.
template <typename Enum, std::size_t N>
std::string NamesInProse(const NameTable<Enum, N>& table) {
  std::string prose;
  for (std::size_t i = 0; i < N; ++i) {
    if (i > 0) prose += i + 1 == N ? " or " : ", ";
    prose += table[i].name;
  }
  return prose;
}

// name -> value, the shape CLI11's CheckedTransformer takes.
template <typename Enum, std::size_t N>
std::map<std::string, Enum> NameMap(const NameTable<Enum, N>& table) {
  std::map<std::string, Enum> map;
  for (const NamedValue<Enum>& entry : table) map.emplace(entry.name, entry.value);
  return map;
}

}  // namespace photorig::solvers::core
