#pragma once
// Integer fields of the JSON files photorig reads (run manifests, journals,
// projection geometries). nlohmann's get<int> converts a number with a
// fraction or beyond the type's range with undefined behaviour (1e137 into an
// int); these refuse it, naming the field, so a corrupt file is an error.
// And the JSON library's messages as a person reads them.

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

namespace photorig::daemon {

// The range [low, high] in words: "from 1 to 16", ">= 0", "<= 5" or "".
inline std::string RangeText(double low, double high) {
  auto number = [](double v) {
    std::string text = nlohmann::json(v).dump();  // shortest round-trip form
    if (text.size() > 2 && text.compare(text.size() - 2, 2, ".0") == 0) text.resize(text.size() - 2);
    return text;
  };
  const bool bounded_below = low > std::numeric_limits<double>::lowest();
  const bool bounded_above = high < std::numeric_limits<double>::max();
  if (bounded_below && bounded_above) return "from " + number(low) + " to " + number(high);
  if (bounded_below) return ">= " + number(low);
  if (bounded_above) return "<= " + number(high);
  return "";
}

// object[key] as an Int within [low, high]; std::runtime_error naming the key
// and the range when it is not such an integer (nlohmann's out_of_range when
// the key is missing).
template <typename Int>
Int IntegerIn(const nlohmann::json& object, const char* key, Int low, Int high) {
  const nlohmann::json& value = object.at(key);
  auto within = [&](auto v) { return std::in_range<Int>(v) && static_cast<Int>(v) >= low && static_cast<Int>(v) <= high; };
  if (value.is_number_unsigned()) {
    const std::uint64_t v = value.get<std::uint64_t>();
    if (within(v)) return static_cast<Int>(v);
  } else if (value.is_number_integer()) {
    const std::int64_t v = value.get<std::int64_t>();
    if (within(v)) return static_cast<Int>(v);
  }
  throw std::runtime_error(std::string("'") + key + "' must be an integer from " + std::to_string(low) + " to " +
                           std::to_string(high) + ", not " + value.dump());
}

// object[key] as any Int (IntegerIn over the type's range).
template <typename Int>
Int IntegerAt(const nlohmann::json& object, const char* key) {
  return IntegerIn<Int>(object, key, std::numeric_limits<Int>::min(), std::numeric_limits<Int>::max());
}

// object[key] as a finite number within [low, high]; std::runtime_error
// naming the key and the range otherwise.
inline double NumberIn(const nlohmann::json& object, const char* key, double low = std::numeric_limits<double>::lowest(),
                       double high = std::numeric_limits<double>::max()) {
  const nlohmann::json& value = object.at(key);
  if (value.is_number()) {
    const double v = value.get<double>();
    if (std::isfinite(v) && v >= low && v <= high) return v;
  }
  const std::string range = RangeText(low, high);
  throw std::runtime_error(std::string("'") + key + "' must be a finite number" + (range.empty() ? "" : " " + range) +
                           ", not " + value.dump());
}

// As NumberIn, or `absent` when the object has no such key.
inline double NumberOr(const nlohmann::json& object, const char* key, double absent,
                       double low = std::numeric_limits<double>::lowest(),
                       double high = std::numeric_limits<double>::max()) {
  return object.contains(key) ? NumberIn(object, key, low, high) : absent;
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
Int IntegerOr(const nlohmann::json& object, const char* key, Int absent, Int low = std::numeric_limits<Int>::min(),
              Int high = std::numeric_limits<Int>::max()) {
  return object.contains(key) ? IntegerIn<Int>(object, key, low, high) : absent;
}

}  // namespace photorig::daemon
