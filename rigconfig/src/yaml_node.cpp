#include "photorig/config/yaml_node.h"

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/parser.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <vector>

namespace photorig::config {
namespace {

std::string Position(const std::string& file, int line, int column) {
  if (line <= 0) return file;
  return file + ":" + std::to_string(line) + ":" + std::to_string(column);
}

std::string Describe(const YAML::Node& node) {
  if (!node.IsDefined() || node.IsNull()) return "nothing";
  if (node.IsScalar()) return "'" + node.Scalar() + "'";
  if (node.IsSequence()) return "a list";
  return "a map";
}

// A scalar as T; nullopt for a list, a map or text that is no T.
template <typename T>
std::optional<T> ScalarAs(const YAML::Node& node) {
  if (!node.IsScalar()) return std::nullopt;
  try {
    return node.as<T>();
  } catch (const YAML::Exception&) {
    return std::nullopt;
  }
}

// A map key as a string. YAML allows any node as a key (`? [a, b]`, `? {a: 1}`,
// an empty `? `); configuration keys are names, so anything else is an error.
std::string KeyName(const YAML::Node& key, const std::string& file, const std::string& parent) {
  if (!key.IsScalar()) YamlNode(key, file, parent).Fail("expected a name as a key, got " + Describe(key));
  return key.Scalar();
}

// Refuses a key given twice in one map. yaml-cpp keeps both entries and
// answers a lookup with the first, so the second (often a later edit) would
// be ignored without a word. Walks the parser's events, in which an alias is
// one event, not a copy of what it names: a file of nested aliases costs its
// length, not their expansion.
class DuplicateKeyCheck : public YAML::EventHandler {
 public:
  explicit DuplicateKeyCheck(std::string file) : file_(std::move(file)) {}

  void OnDocumentStart(const YAML::Mark&) override {}
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark& mark, YAML::anchor_t) override { Node(mark, nullptr); }
  void OnAlias(const YAML::Mark& mark, YAML::anchor_t) override { Node(mark, nullptr); }
  void OnScalar(const YAML::Mark& mark, const std::string&, YAML::anchor_t, const std::string& value) override {
    Node(mark, &value);
  }
  void OnSequenceStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    Node(mark, nullptr);
    levels_.push_back({});
  }
  void OnSequenceEnd() override { levels_.pop_back(); }
  void OnMapStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    Node(mark, nullptr);
    levels_.push_back({.map = true});
  }
  void OnMapEnd() override { levels_.pop_back(); }

 private:
  struct Level {
    bool map = false;
    bool at_key = true;              // a map's next node is a key
    std::string key;                 // a map's current key
    int index = -1;                  // a sequence's current item
    std::map<std::string, int> seen;  // a map's keys, with the line each first appeared on
  };

  // The dotted key of the innermost node, as YamlNode names it.
  std::string Path() const {
    std::string path;
    for (const Level& level : levels_) {
      if (level.map) {
        path += (path.empty() ? "" : ".") + level.key;
      } else {
        path += "[" + std::to_string(level.index) + "]";
      }
    }
    return path;
  }

  // A node begins at `mark`: a map's key (scalar: its text) or value, or a sequence's item.
  void Node(const YAML::Mark& mark, const std::string* scalar) {
    if (levels_.empty()) return;
    Level& level = levels_.back();
    if (!level.map) {
      ++level.index;
      return;
    }
    if (!level.at_key) {
      level.at_key = true;
      return;
    }
    level.at_key = false;
    level.key = scalar ? *scalar : "?";
    if (!scalar) return;  // not a name: YamlNode refuses it where it is read
    const auto [first, inserted] = level.seen.emplace(*scalar, mark.line + 1);
    if (inserted) return;
    level.key.clear();
    std::string parent = Path();
    if (!parent.empty() && parent.back() == '.') parent.pop_back();
    throw ConfigError(file_, mark.line + 1, mark.column + 1, parent,
                      "key '" + *scalar + "' is given twice in one map (first on line " +
                          std::to_string(first->second) + "); remove one of them");
  }

  std::string file_;
  std::vector<Level> levels_;
};

}  // namespace

ConfigError::ConfigError(const std::string& file, int line, int column, const std::string& key,
                         const std::string& message)
    : std::runtime_error(Position(file, line, column) + ": " + (key.empty() ? "" : key + ": ") + message),
      file_(file),
      key_(key),
      line_(line),
      column_(column) {}

bool IsValidUtf8(std::string_view text, std::size_t* bad_offset) {
  const auto* bytes = reinterpret_cast<const unsigned char*>(text.data());
  std::size_t i = 0;
  auto bad = [&] {
    if (bad_offset) *bad_offset = i;
    return false;
  };
  while (i < text.size()) {
    const unsigned char c = bytes[i];
    std::size_t length = 0;
    std::uint32_t code = 0, min = 0;
    if (c < 0x80) length = 1, code = c;
    else if ((c & 0xE0) == 0xC0) length = 2, code = c & 0x1F, min = 0x80;
    else if ((c & 0xF0) == 0xE0) length = 3, code = c & 0x0F, min = 0x800;
    else if ((c & 0xF8) == 0xF0) length = 4, code = c & 0x07, min = 0x10000;
    else return bad();
    if (i + length > text.size()) return bad();
    for (std::size_t k = 1; k < length; ++k) {
      if ((bytes[i + k] & 0xC0) != 0x80) return bad();
      code = (code << 6) | (bytes[i + k] & 0x3F);
    }
    if (code < min || code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF)) return bad();
    i += length;
  }
  return true;
}

YamlNode YamlNode::LoadFile(const std::string& path) {
  std::error_code error;
  if (std::filesystem::is_directory(path, error)) throw ConfigError(path, 0, 0, "", "is a directory, not a file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError(path, 0, 0, "", "cannot open file");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw ConfigError(path, 0, 0, "", "cannot read file");
  return LoadString(text, path);
}

YamlNode YamlNode::LoadString(const std::string& text, const std::string& name) {
  // Names and messages from the file end up in JSON, which must be UTF-8.
  if (std::size_t bad = 0; !IsValidUtf8(text, &bad)) {
    const std::size_t line_start = text.rfind('\n', bad == 0 ? 0 : bad - 1);
    const int line = 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(bad), '\n'));
    const int column = 1 + static_cast<int>(line_start == std::string::npos || bad == 0 ? bad : bad - line_start - 1);
    throw ConfigError(name, line, column, "", "not UTF-8 text (byte " + std::to_string(bad) + ")");
  }
  try {
    YAML::Node root = YAML::Load(text);
    if (!root.IsMap()) throw ConfigError(name, 1, 1, "", "expected a map at the top level");
    std::istringstream stream(text);
    DuplicateKeyCheck check(name);
    YAML::Parser(stream).HandleNextDocument(check);
    return YamlNode(root, name, "");
  } catch (const YAML::ParserException& e) {
    throw ConfigError(name, e.mark.line + 1, e.mark.column + 1, "", "YAML syntax error: " + e.msg);
  }
}

YamlNode::YamlNode(YAML::Node node, std::string file, std::string key)
    : node_(std::move(node)), file_(std::move(file)), key_(std::move(key)) {}

int YamlNode::line() const {
  const YAML::Mark mark = node_.Mark();
  return mark.line >= 0 && !mark.is_null() ? mark.line + 1 : 0;
}
int YamlNode::column() const { return line() > 0 ? node_.Mark().column + 1 : 0; }

void YamlNode::Fail(const std::string& message) const { throw ConfigError(file_, line(), column(), key_, message); }

bool YamlNode::Has(const std::string& child) const { return node_.IsMap() && node_[child].IsDefined(); }

YamlNode YamlNode::operator[](const std::string& child) const {
  if (!node_.IsMap()) Fail("expected a map with key '" + child + "', got " + Describe(node_));
  const YAML::Node value = node_[child];
  if (!value.IsDefined()) Fail("missing required key '" + child + "'");
  YamlNode found(value, file_, key_.empty() ? child : key_ + "." + child);
  found.path_root_ = path_root_;
  return found;
}

std::optional<YamlNode> YamlNode::Find(const std::string& child) const {
  if (!Has(child)) return std::nullopt;
  return (*this)[child];
}

std::vector<YamlNode> YamlNode::Items() const {
  if (!node_.IsSequence()) Fail("expected a list, got " + Describe(node_));
  std::vector<YamlNode> items;
  for (std::size_t i = 0; i < node_.size(); ++i) {
    items.emplace_back(node_[i], file_, key_ + "[" + std::to_string(i) + "]");
    items.back().path_root_ = path_root_;
  }
  return items;
}

std::vector<std::string> YamlNode::Keys() const {
  if (!node_.IsMap()) Fail("expected a map, got " + Describe(node_));
  std::vector<std::string> keys;
  for (const auto& entry : node_) keys.push_back(KeyName(entry.first, file_, key_));
  return keys;
}

void YamlNode::ExpectKeys(std::initializer_list<const char*> allowed) const {
  if (!node_.IsMap()) Fail("expected a map, got " + Describe(node_));
  for (const auto& entry : node_) {
    const std::string name = KeyName(entry.first, file_, key_);
    if (std::none_of(allowed.begin(), allowed.end(), [&](const char* a) { return name == a; })) {
      std::string list;
      for (const char* a : allowed) list += std::string(list.empty() ? "" : ", ") + a;
      YamlNode(entry.first, file_, key_.empty() ? name : key_ + "." + name)
          .Fail("unknown key '" + name + "' (expected one of: " + list + ")");
    }
  }
}

YamlNode YamlNode::ConfinedTo(const std::string& directory) const {
  YamlNode confined = *this;
  confined.path_root_ = std::filesystem::weakly_canonical(std::filesystem::absolute(directory)).string();
  return confined;
}

std::string YamlNode::AsPath() const {
  namespace fs = std::filesystem;
  const fs::path path = AsString();
  if (path.empty()) Fail("expected a path, got an empty string");
  const fs::path base = path_root_.empty() ? fs::path(file_).parent_path() : fs::path(path_root_);
  const fs::path resolved = (path.is_absolute() ? path : base / path).lexically_normal();
  if (path_root_.empty()) return resolved.string();
  std::error_code error;
  const fs::path real = fs::weakly_canonical(resolved, error);
  const fs::path root = path_root_;
  const auto mismatch = std::mismatch(root.begin(), root.end(), real.begin(), real.end());
  if (error || mismatch.first != root.end() || path.string().find('\0') != std::string::npos)
    Fail("must lie inside " + path_root_ + " (paths a recipe names stay in its folder)");
  return real.string();
}

std::string YamlNode::AsString() const {
  if (!node_.IsScalar()) Fail("expected a string, got " + Describe(node_));
  return node_.Scalar();
}

double YamlNode::AsDouble() const {
  if (const std::optional<double> value = ScalarAs<double>(node_); value && std::isfinite(*value)) return *value;
  Fail("expected a number, got " + Describe(node_));
}

int YamlNode::AsInt() const {
  if (const std::optional<int> value = ScalarAs<int>(node_)) return *value;
  Fail("expected an integer, got " + Describe(node_));
}

bool YamlNode::AsBool() const {
  if (const std::optional<bool> value = ScalarAs<bool>(node_)) return *value;
  Fail("expected true or false, got " + Describe(node_));
}

Eigen::Vector3d YamlNode::AsVector3() const {
  if (!node_.IsSequence() || node_.size() != 3)
    Fail("expected a list of 3 numbers, got " +
         (node_.IsSequence() ? std::to_string(node_.size()) + " items" : Describe(node_)));
  const auto items = Items();
  return {items[0].AsDouble(), items[1].AsDouble(), items[2].AsDouble()};
}

std::vector<int> YamlNode::AsIntList() const {
  std::vector<int> values;
  for (const YamlNode& item : Items()) values.push_back(item.AsInt());
  return values;
}

double YamlNode::AsDoubleIn(double min, double max) const {
  const double value = AsDouble();
  if (!(value >= min && value <= max)) {
    char range[80];
    std::snprintf(range, sizeof(range), "must lie in [%g, %g]", min, max);
    Fail(range);
  }
  return value;
}

double YamlNode::DoubleIn(const std::string& child, double fallback, double min, double max) const {
  const auto node = Find(child);
  return node ? node->AsDoubleIn(min, max) : fallback;
}

double YamlNode::Double(const std::string& child, double fallback) const {
  const auto node = Find(child);
  return node ? node->AsDouble() : fallback;
}
int YamlNode::Int(const std::string& child, int fallback) const {
  const auto node = Find(child);
  return node ? node->AsInt() : fallback;
}
bool YamlNode::Bool(const std::string& child, bool fallback) const {
  const auto node = Find(child);
  return node ? node->AsBool() : fallback;
}
std::string YamlNode::String(const std::string& child, const std::string& fallback) const {
  const auto node = Find(child);
  return node ? node->AsString() : fallback;
}

}  // namespace photorig::config
