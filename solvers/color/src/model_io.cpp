#include "photorig/solvers/color/model_io.h"
#include "photorig/solvers/core/summary_json.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <iomanip>
#include <sstream>
#include <stdexcept>

namespace photorig::solvers::color {
namespace {

constexpr const char* kFormat = "photorig-color-model/1";

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

bool IsYamlPath(const std::string& path) { return EndsWith(path, ".yaml") || EndsWith(path, ".yml"); }

nlohmann::json NumberOrNull(double x) { return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr); }

// A model nests three levels deep; an alias that refers to the node holding
// it (`&a [*a]`) would nest without end.
constexpr int kMaxYamlDepth = 16;

// YAML -> JSON for the subset a model uses (maps, sequences, scalars).
nlohmann::json YamlToJson(const YAML::Node& node, int depth = 0) {
  if ((node.IsMap() || node.IsSequence()) && depth >= kMaxYamlDepth)
    throw std::invalid_argument("nested deeper than " + std::to_string(kMaxYamlDepth) +
                                " levels (an alias that refers to itself?)");
  if (node.IsMap()) {
    nlohmann::json out = nlohmann::json::object();
    for (const auto& item : node) out[item.first.as<std::string>()] = YamlToJson(item.second, depth + 1);
    return out;
  }
  if (node.IsSequence()) {
    nlohmann::json out = nlohmann::json::array();
    for (const auto& item : node) out.push_back(YamlToJson(item, depth + 1));
    return out;
  }
  if (node.IsScalar()) {
    const std::string text = node.Scalar();
    try {
      std::size_t used = 0;
      const double value = std::stod(text, &used);
      if (used == text.size()) return value;
    } catch (const std::exception&) {
    }
    return text;
  }
  return nullptr;
}

void JsonToYaml(const nlohmann::json& json, YAML::Emitter& out) {
  if (json.is_object()) {
    out << YAML::BeginMap;
    for (const auto& [key, value] : json.items()) {
      out << YAML::Key << key << YAML::Value;
      JsonToYaml(value, out);
    }
    out << YAML::EndMap;
  } else if (json.is_array()) {
    const bool numbers = !json.empty() && json[0].is_number();
    out << (numbers ? YAML::Flow : YAML::Block) << YAML::BeginSeq;
    for (const auto& value : json) JsonToYaml(value, out);
    out << YAML::EndSeq;
  } else if (json.is_number()) {
    out << json.get<double>();
  } else if (json.is_string()) {
    out << json.get<std::string>();
  } else {
    out << YAML::Null;
  }
}

}  // namespace

nlohmann::json ModelToJson(const ColorModel& model) {
  nlohmann::json coefficients = nlohmann::json::array();
  for (Eigen::Index t = 0; t < model.coefficients.rows(); ++t)
    coefficients.push_back({model.coefficients(t, 0), model.coefficients(t, 1), model.coefficients(t, 2)});
  return {{"format", kFormat},
          {"model", model.spec.Name()},
          {"loss", FitLossName(model.loss)},
          {"illuminant", IlluminantName(model.illuminant)},
          {"white_xyz", {model.white_xyz.x(), model.white_xyz.y(), model.white_xyz.z()}},
          {"input_scale", model.input_scale},
          {"coefficients", coefficients}};
}

ColorModel ModelFromJson(const nlohmann::json& json, const std::string& source) {
  auto fail = [&source](const std::string& key, const std::string& what) -> std::invalid_argument {
    return std::invalid_argument(source + ": " + key + ": " + what);
  };
  auto field = [&](const char* key) -> const nlohmann::json& {
    if (!json.is_object() || !json.contains(key)) throw fail(key, "missing");
    return json.at(key);
  };
  auto number = [&](const nlohmann::json& value, const std::string& key) {
    if (!value.is_number()) throw fail(key, "expected a number");
    return value.get<double>();
  };
  if (!field("format").is_string() || field("format").get<std::string>() != kFormat)
    throw fail("format", std::string("expected '") + kFormat + "'");
  ColorModel model;
  auto name = [&](const char* key) {
    if (!field(key).is_string()) throw fail(key, "expected a string");
    return field(key).get<std::string>();
  };
  const std::optional<ModelSpec> spec = ModelSpec::Parse(name("model"));
  if (!spec) throw fail("model", "unknown model (known: " + ModelSpec::KnownNames() + ")");
  const std::optional<FitLoss> loss = ParseFitLoss(name("loss"));
  if (!loss) throw fail("loss", "unknown fit loss (known: xyz, ciede2000)");
  const std::optional<Illuminant> illuminant = ParseIlluminant(name("illuminant"));
  if (!illuminant) throw fail("illuminant", "unknown illuminant (known: D50, D65, A)");
  model.spec = *spec;
  model.loss = *loss;
  model.illuminant = *illuminant;
  const auto& white = field("white_xyz");
  if (!white.is_array() || white.size() != 3) throw fail("white_xyz", "expected 3 numbers");
  for (int i = 0; i < 3; ++i) model.white_xyz[i] = number(white[static_cast<std::size_t>(i)], "white_xyz");
  model.input_scale = number(field("input_scale"), "input_scale");
  const auto& rows = field("coefficients");
  if (!rows.is_array()) throw fail("coefficients", "expected a list of [x, y, z] rows");
  model.coefficients.resize(static_cast<Eigen::Index>(rows.size()), 3);
  for (std::size_t t = 0; t < rows.size(); ++t) {
    const std::string key = "coefficients." + std::to_string(t);
    if (!rows[t].is_array() || rows[t].size() != 3) throw fail(key, "expected 3 numbers");
    for (int c = 0; c < 3; ++c) model.coefficients(static_cast<Eigen::Index>(t), c) = number(rows[t][static_cast<std::size_t>(c)], key);
  }
  std::string why;
  if (!model.IsValid(&why)) throw std::invalid_argument(source + ": " + why);
  return model;
}

std::string SerializeModel(const ColorModel& model, const std::string& path_for_format) {
  const nlohmann::json json = ModelToJson(model);
  if (!IsYamlPath(path_for_format)) return json.dump(2) + "\n";
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  JsonToYaml(json, out);
  return std::string(out.c_str()) + "\n";
}

ColorModel ParseModel(const std::string& text, const std::string& path) {
  nlohmann::json json;
  try {
    json = IsYamlPath(path) ? YamlToJson(YAML::Load(text)) : nlohmann::json::parse(text);
  } catch (const std::exception& e) {
    throw std::invalid_argument(path + ": not a colour model: " + e.what());
  }
  return ModelFromJson(json, path);
}

nlohmann::json CalibrationReport(const CalibrationSummary& summary, const std::vector<PatchMeasurement>& measurements,
                                 const std::vector<std::string>& patch_names) {
  nlohmann::json report = solvers::core::ToJson(summary);
  report["patches_used"] = summary.patches_used;
  report["exposure_patch"] = summary.exposure_patch;
  report["chosen"] = summary.chosen >= 0 ? nlohmann::json(summary.models[static_cast<std::size_t>(summary.chosen)].spec.Name())
                                         : nlohmann::json(nullptr);
  nlohmann::json models = nlohmann::json::array();
  for (const auto& m : summary.models) {
    nlohmann::json entry = {{"model", m.spec.Name()},       {"terms", m.spec.TermCount()},
                            {"usable", m.usable},           {"note", m.note},
                            {"condition_number", NumberOrNull(m.condition_number)},
                            {"training_mean", NumberOrNull(m.training_mean)},
                            {"held_out_mean", NumberOrNull(m.held_out_mean)},
                            {"held_out_median", NumberOrNull(m.held_out_median)},
                            {"held_out_max", NumberOrNull(m.held_out_max)},
                            {"fit_ms", m.fit_ms},           {"loo_ms", m.loo_ms}};
    nlohmann::json training = nlohmann::json::array(), held_out = nlohmann::json::array();
    for (std::size_t p = 0; p < m.training_de.size(); ++p) {
      training.push_back(NumberOrNull(m.training_de[p]));
      held_out.push_back(NumberOrNull(m.held_out_de[p]));
    }
    entry["training_de"] = training;
    entry["held_out_de"] = held_out;
    if (m.usable) entry["coefficients"] = ModelToJson(m.model);
    models.push_back(entry);
  }
  report["models"] = models;
  nlohmann::json patches = nlohmann::json::array();
  for (std::size_t p = 0; p < measurements.size(); ++p) {
    const auto& m = measurements[p];
    patches.push_back({{"index", p + 1},
                       {"name", p < patch_names.size() ? patch_names[p] : ""},
                       {"rgb", {m.rgb.x(), m.rgb.y(), m.rgb.z()}},
                       {"stddev", {m.stddev.x(), m.stddev.y(), m.stddev.z()}},
                       {"pixels", m.pixels},
                       {"clipped_pixels", m.clipped_pixels},
                       {"flag", PatchFlagName(m.flag)}});
  }
  report["patches"] = patches;
  return report;
}

std::string FormatCalibrationReport(const CalibrationSummary& summary, const std::vector<std::string>& patch_names) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(2);
  out << "model         terms  train dE00  LOO mean  LOO median  LOO max   fit+LOO ms  note\n";
  for (std::size_t i = 0; i < summary.models.size(); ++i) {
    const auto& m = summary.models[i];
    out << std::left << std::setw(14) << m.spec.Name() << std::right << std::setw(5) << m.spec.TermCount();
    if (m.usable) {
      out << std::setw(12) << m.training_mean << std::setw(10) << m.held_out_mean << std::setw(12)
          << m.held_out_median << std::setw(9) << m.held_out_max << std::setw(13) << m.fit_ms + m.loo_ms;
    } else {
      out << std::setw(56) << "-";
    }
    out << "  " << (static_cast<int>(i) == summary.chosen ? "<- chosen" : m.note) << "\n";
  }
  if (summary.chosen >= 0) {
    const auto& m = summary.models[static_cast<std::size_t>(summary.chosen)];
    out << "\npatch  name                 train dE00  LOO dE00\n";
    for (std::size_t p = 0; p < m.training_de.size(); ++p) {
      out << std::setw(5) << p + 1 << "  " << std::left << std::setw(20)
          << (p < patch_names.size() ? patch_names[p] : "") << std::right;
      if (std::isfinite(m.training_de[p]))
        out << std::setw(11) << m.training_de[p] << std::setw(10) << m.held_out_de[p] << "\n";
      else
        out << std::setw(21) << "(not used)" << "\n";
    }
  }
  out << "\n" << summary.message << "\n";
  return out.str();
}

}  // namespace photorig::solvers::color
