#include "photorig/config/yaml_node.h"

#include <algorithm>
#include <cmath>
#include <fstream>

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

// A map key as a string. YAML allows any node as a key (`? [a, b]`, `? {a: 1}`,
// an empty `? `); configuration keys are names, so anything else is an error.
std::string KeyName(const YAML::Node& key, const std::string& file, const std::string& parent) {
  if (!key.IsScalar()) YamlNode(key, file, parent).Fail("expected a name as a key, got " + Describe(key));
  return key.Scalar();
}

}  // namespace

ConfigError::ConfigError(const std::string& file, int line, int column, const std::string& key,
                         const std::string& message)
    : std::runtime_error(Position(file, line, column) + ": " + (key.empty() ? "" : key + ": ") + message),
      file_(file),
      key_(key),
      line_(line),
      column_(column) {}

YamlNode YamlNode::LoadFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError(path, 0, 0, "", "cannot open file");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return LoadString(text, path);
}

YamlNode YamlNode::LoadString(const std::string& text, const std::string& name) {
  try {
    YAML::Node root = YAML::Load(text);
    if (!root.IsMap()) throw ConfigError(name, 1, 1, "", "expected a map at the top level");
    return YamlNode(root, name, "");
  } catch (const YAML::ParserException& e) {
    throw ConfigError(name, e.mark.line + 1, e.mark.column + 1, "", "YAML syntax error: " + e.msg);
  }
}

YamlNode::YamlNode(YAML::Node node, std::string file, std::string key)
    : node_(std::move(node)), file_(std::move(file)), key_(std::move(key)) {}

void YamlNode::Fail(const std::string& message) const {
  const YAML::Mark mark = node_.Mark();
  const bool known = mark.line >= 0 && !mark.is_null();
  throw ConfigError(file_, known ? mark.line + 1 : 0, known ? mark.column + 1 : 0, key_, message);
}

bool YamlNode::Has(const std::string& child) const { return node_.IsMap() && node_[child].IsDefined(); }

YamlNode YamlNode::operator[](const std::string& child) const {
  if (!node_.IsMap()) Fail("expected a map with key '" + child + "', got " + Describe(node_));
  const YAML::Node value = node_[child];
  if (!value.IsDefined()) Fail("missing required key '" + child + "'");
  return YamlNode(value, file_, key_.empty() ? child : key_ + "." + child);
}

std::optional<YamlNode> YamlNode::Find(const std::string& child) const {
  if (!Has(child)) return std::nullopt;
  return (*this)[child];
}

std::vector<YamlNode> YamlNode::Items() const {
  if (!node_.IsSequence()) Fail("expected a list, got " + Describe(node_));
  std::vector<YamlNode> items;
  for (std::size_t i = 0; i < node_.size(); ++i)
    items.emplace_back(node_[i], file_, key_ + "[" + std::to_string(i) + "]");
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

std::string YamlNode::AsString() const {
  if (!node_.IsScalar()) Fail("expected a string, got " + Describe(node_));
  return node_.Scalar();
}

double YamlNode::AsDouble() const {
  if (node_.IsScalar()) {
    try {
      const double value = node_.as<double>();
      if (std::isfinite(value)) return value;
    } catch (const YAML::Exception&) {
    }
  }
  Fail("expected a number, got " + Describe(node_));
}

int YamlNode::AsInt() const {
  if (node_.IsScalar()) {
    try {
      return node_.as<int>();
    } catch (const YAML::Exception&) {
    }
  }
  Fail("expected an integer, got " + Describe(node_));
}

bool YamlNode::AsBool() const {
  if (node_.IsScalar()) {
    try {
      return node_.as<bool>();
    } catch (const YAML::Exception&) {
    }
  }
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
