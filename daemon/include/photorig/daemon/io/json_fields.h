#pragma once
// Integer fields of the JSON files photorig reads (run manifests, journals,
// projection geometries). nlohmann's get<int> converts a number with a
// fraction or beyond the type's range with undefined behaviour (1e137 into an
// int); these refuse it, naming the field, so a corrupt file is an error.
// And the JSON library's messages as a person reads them.

#include <nlohmann/json.hpp>

#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

namespace photorig::daemon {

// object[key] as an Int; std::runtime_error naming the key when it is not an
// integer Int can hold (nlohmann's out_of_range when the key is missing).
template <typename Int>
Int IntegerAt(const nlohmann::json& object, const char* key) {
  const nlohmann::json& value = object.at(key);
  if (value.is_number_unsigned()) {
    const std::uint64_t v = value.get<std::uint64_t>();
    if (std::in_range<Int>(v)) return static_cast<Int>(v);
  } else if (value.is_number_integer()) {
    const std::int64_t v = value.get<std::int64_t>();
    if (std::in_range<Int>(v)) return static_cast<Int>(v);
  }
  throw std::runtime_error(std::string("'") + key + "' must be an integer from " +
                           std::to_string(std::numeric_limits<Int>::min()) + " to " +
                           std::to_string(std::numeric_limits<Int>::max()) + ", not " + value.dump());
}

// The JSON library's message without its "[json.exception.parse_error.101] "
// tag, which tells a reader nothing.
inline std::string WithoutJsonLibraryTag(const std::string& message) {
  if (message.rfind("[json.exception.", 0) != 0) return message;
  const std::size_t end = message.find("] ");
  return end == std::string::npos ? message : message.substr(end + 2);
}

// As IntegerAt, or `absent` when the object has no such key.
template <typename Int>
Int IntegerOr(const nlohmann::json& object, const char* key, Int absent) {
  return object.contains(key) ? IntegerAt<Int>(object, key) : absent;
}

}  // namespace photorig::daemon
