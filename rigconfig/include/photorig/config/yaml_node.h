#pragma once
// A YAML node that remembers where it came from, so that every configuration
// error names file:line:column and the dotted key at fault, e.g.
//   config/rigs/sim-dome.yaml:14:18: lights.leds[3].direction: expected 3 numbers, got 2

#include "photorig/solvers/core/names.h"

#include <yaml-cpp/yaml.h>

#include <Eigen/Core>

#include <initializer_list>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace photorig::config {

class ConfigError : public std::runtime_error {
 public:
  ConfigError(const std::string& file, int line, int column, const std::string& key, const std::string& message);
  const std::string& file() const { return file_; }
  int line() const { return line_; }      // 1-based; 0 when unknown
  int column() const { return column_; }  // 1-based; 0 when unknown
  const std::string& key() const { return key_; }

 private:
  std::string file_, key_;
  int line_, column_;
};

// True when `text` is well-formed UTF-8 (no overlong forms, surrogates or
// code points above U+10FFFF); `*bad_offset` is the first byte that is not.
bool IsValidUtf8(std::string_view text, std::size_t* bad_offset = nullptr);

class YamlNode {
 public:
  // Parses a file; syntax errors become ConfigError with the parser's position.
  // A path that is no readable regular file and text that is not UTF-8 are
  // errors too (the latter at the first bad byte).
  static YamlNode LoadFile(const std::string& path);
  static YamlNode LoadString(const std::string& text, const std::string& name);

  // This node and every node below it resolve relative paths against
  // `directory` and refuse any path that resolves outside it (after `..` and
  // symlinks). Without it a path resolves against the file's folder, unchecked.
  YamlNode ConfinedTo(const std::string& directory) const;
  // The node's string as a path: absolute ones as they are, relative ones
  // against the confining folder (or the file's). Outside the confining
  // folder it fails with a message that says nothing of what exists there.
  std::string AsPath() const;

  YamlNode(YAML::Node node, std::string file, std::string key);

  const std::string& key() const { return key_; }
  const std::string& file() const { return file_; }
  bool IsMap() const { return node_.IsMap(); }
  bool IsSequence() const { return node_.IsSequence(); }
  bool IsScalar() const { return node_.IsScalar(); }
  int line() const;    // 1-based; 0 when unknown
  int column() const;  // 1-based; 0 when unknown

  bool Has(const std::string& child) const;
  YamlNode operator[](const std::string& child) const;  // required: error if missing
  std::optional<YamlNode> Find(const std::string& child) const;
  std::vector<YamlNode> Items() const;  // required sequence
  std::vector<std::string> Keys() const;  // required map, in file order
  // Rejects keys not in `allowed`: catches typos that would otherwise be ignored.
  void ExpectKeys(std::initializer_list<const char*> allowed) const;

  std::string AsString() const;
  double AsDouble() const;
  int AsInt() const;
  bool AsBool() const;
  Eigen::Vector3d AsVector3() const;
  std::vector<int> AsIntList() const;

  // Shorthands for optional scalars with a default.
  double Double(const std::string& child, double fallback) const;
  int Int(const std::string& child, int fallback) const;
  bool Bool(const std::string& child, bool fallback) const;
  std::string String(const std::string& child, const std::string& fallback) const;
  // A number within [min, max]; otherwise an error naming the range.
  double AsDoubleIn(double min, double max) const;
  double DoubleIn(const std::string& child, double fallback, double min, double max) const;

  // The value the text of `child` names in `table`, or `fallback` when the key
  // is absent. Other text fails naming the names allowed.
  template <typename Enum, std::size_t N>
  Enum Choice(const std::string& child, const solvers::core::NameTable<Enum, N>& table, Enum fallback) const {
    const std::optional<YamlNode> node = Find(child);
    if (!node) return fallback;
    const std::string name = node->AsString();
    if (const std::optional<Enum> value = solvers::core::ParseName(table, name)) return *value;
    node->Fail("'" + name + "' is no " + child + " (expected " + solvers::core::NamesInProse(table) + ")");
  }
  [[noreturn]] void Fail(const std::string& message) const;

 private:
  YAML::Node node_;
  std::string file_;
  std::string key_;
  std::string path_root_;  // empty: not confined
};

}  // namespace photorig::config
