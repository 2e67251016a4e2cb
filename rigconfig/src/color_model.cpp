#include "photorig/config/color_model.h"

#include "photorig/solvers/color/model_io.h"
#include "photorig/config/yaml_node.h"

#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <tuple>

namespace photorig::config {
namespace fs = std::filesystem;
namespace {

std::string ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError(path, 0, 0, "", "cannot read the colour model file");
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// The line and column of a dotted key ("coefficients.2") in a YAML document;
// {0, 0} when it is not there.
std::pair<int, int> YamlKeyPosition(const std::string& text, const std::string& dotted) {
  try {
    YAML::Node node = YAML::Load(text);
    std::stringstream parts(dotted);
    std::string part;
    while (std::getline(parts, part, '.')) {
      if (!node) return {0, 0};
      if (node.IsSequence() && !part.empty() && std::isdigit(static_cast<unsigned char>(part[0])))
        node = node[std::stoul(part)];
      else if (node.IsMap())
        node = node[part];
      else
        return {0, 0};
    }
    if (!node) return {0, 0};
    return {node.Mark().line + 1, node.Mark().column + 1};
  } catch (const std::exception&) {
    return {0, 0};
  }
}

// The line of the first `"key"` in a JSON text; 0 when it is not there.
int JsonKeyLine(const std::string& text, const std::string& dotted) {
  const std::string top = dotted.substr(0, dotted.find('.'));
  const std::size_t at = text.find("\"" + top + "\"");
  if (at == std::string::npos) return 0;
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(at), '\n'));
}

bool IsYaml(const std::string& path) {
  const std::string ext = fs::path(path).extension().string();
  return ext == ".yaml" || ext == ".yml";
}

}  // namespace

std::string ContentHash(const std::string& bytes) {
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : bytes) {
    h ^= c;
    h *= 1099511628211ull;
  }
  char text[17];
  std::snprintf(text, sizeof(text), "%016llx", static_cast<unsigned long long>(h));
  return text;
}

LoadedColorModel LoadColorModelFile(const std::string& path) {
  const std::string text = ReadBytes(path);
  LoadedColorModel loaded;
  loaded.path = path;
  loaded.content_hash = ContentHash(text);
  // Syntax first, so a malformed file is placed by the parser's position.
  if (IsYaml(path)) {
    try {
      (void)YAML::Load(text);
    } catch (const YAML::Exception& e) {
      throw ConfigError(path, e.mark.line + 1, e.mark.column + 1, "", "not YAML: " + e.msg);
    }
  } else {
    try {
      [[maybe_unused]] const nlohmann::json document = nlohmann::json::parse(text);
    } catch (const nlohmann::json::parse_error& e) {
      const std::size_t at = std::min<std::size_t>(e.byte, text.size());
      const int line = 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(at), '\n'));
      throw ConfigError(path, line, 0, "", std::string("not JSON: ") + e.what());
    }
  }
  try {
    loaded.model = solvers::color::ParseModel(text, path);
  } catch (const std::invalid_argument& e) {
    // "path: key: what" from the model reader; place the key in the file.
    std::string message = e.what();
    if (message.rfind(path + ": ", 0) == 0) message = message.substr(path.size() + 2);
    const std::size_t colon = message.find(": ");
    std::string key = colon == std::string::npos ? "" : message.substr(0, colon);
    if (key.find(' ') != std::string::npos) key.clear();  // a sentence, not a key
    const std::string what = key.empty() ? message : message.substr(colon + 2);
    int line = 0, column = 0;
    if (!key.empty()) {
      if (IsYaml(path)) std::tie(line, column) = YamlKeyPosition(text, key);
      else line = JsonKeyLine(text, key);
    }
    throw ConfigError(path, line, column, key, what);
  }
  if (!loaded.model.spec.IsExposureInvariant())
    throw ConfigError(path, IsYaml(path) ? YamlKeyPosition(text, "model").first : JsonKeyLine(text, "model"), 0,
                      "model",
                      "a " + loaded.model.spec.Name() +
                          " model is not exposure invariant; photometric stereo scales every frame by its own "
                          "light, so it needs linear or a root-polynomial model (calibrate with --models)");
  return loaded;
}

}  // namespace photorig::config
