// Parses the compiled-in CSV tables once, on first use.

#include "embedded_tables.h"
#include "photorig/solvers/color/spectrum.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <sstream>

namespace photorig::solvers::color {
namespace {

struct CsvTable {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
};

std::vector<std::string> SplitComma(const std::string& line) {
  std::vector<std::string> fields;
  std::stringstream stream(line);
  std::string field;
  while (std::getline(stream, field, ',')) fields.push_back(field);
  return fields;
}

// '#' lines are provenance comments; the first other line is the header.
CsvTable ParseCsv(std::string_view name) {
  const auto& tables = internal::EmbeddedTables();
  const auto it = tables.find(name);
  if (it == tables.end()) internal::BrokenTable("color table not compiled in: " + std::string(name));
  CsvTable table;
  std::stringstream stream{std::string(it->second)};
  std::string line;
  while (std::getline(stream, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    if (table.header.empty()) {
      table.header = SplitComma(line);
    } else {
      table.rows.push_back(SplitComma(line));
      if (table.rows.back().size() != table.header.size())
        internal::BrokenTable("color table " + std::string(name) + ": ragged row");
    }
  }
  return table;
}

// First column wavelength, the others one channel each.
SampledSpectra ParseSpectra(std::string_view name) {
  const CsvTable table = ParseCsv(name);
  SampledSpectra spectra;
  spectra.channels.resize(table.header.size() - 1);
  for (const auto& row : table.rows) {
    spectra.wavelength_nm.push_back(std::stod(row[0]));
    for (std::size_t c = 1; c < row.size(); ++c) spectra.channels[c - 1].push_back(std::stod(row[c]));
  }
  return spectra;
}

struct CameraEntry {
  const char* name;
  const char* table;
  const char* description;
};
constexpr CameraEntry kCameras[] = {
    {"nikon-5100", "camera_sensitivities_nikon_5100_npl", "Nikon 5100 (NPL, Darrodi et al. 2015)"},
    {"sigma-sdmerill", "camera_sensitivities_sigma_sdmerill_npl", "Sigma SD Merrill (NPL, Darrodi et al. 2015)"},
    {"canon-5d-mark-ii", "camera_sensitivities_canon_eos_5d_mark_ii_rawtoaces", "Canon EOS 5D Mark II (RAW to ACES)"},
};

const CameraEntry* FindCamera(const std::string& name) {
  for (const auto& camera : kCameras)
    if (name == camera.name) return &camera;
  return nullptr;
}

}  // namespace

void internal::BrokenTable(const std::string& what) {
  std::fprintf(stderr, "photorig: broken build: %s\n", what.c_str());
  std::abort();
}

double SampledSpectra::At(std::size_t channel, double wavelength) const {
  const auto& w = wavelength_nm;
  if (w.empty() || wavelength < w.front() || wavelength > w.back()) return 0.0;
  const auto upper = std::lower_bound(w.begin(), w.end(), wavelength);
  const std::size_t i = static_cast<std::size_t>(upper - w.begin());
  if (*upper == wavelength) return channels[channel][i];
  const double t = (wavelength - w[i - 1]) / (w[i] - w[i - 1]);
  return (1.0 - t) * channels[channel][i - 1] + t * channels[channel][i];
}

SampledSpectra SampledSpectra::Resampled(const std::vector<double>& grid_nm) const {
  SampledSpectra out;
  out.wavelength_nm = grid_nm;
  out.channels.assign(channels.size(), std::vector<double>(grid_nm.size()));
  for (std::size_t c = 0; c < channels.size(); ++c)
    for (std::size_t i = 0; i < grid_nm.size(); ++i) out.channels[c][i] = At(c, grid_nm[i]);
  return out;
}

std::vector<double> WavelengthGrid(double first_nm, double last_nm, double step_nm) {
  std::vector<double> grid;
  const int count = static_cast<int>(std::floor((last_nm - first_nm) / step_nm + 1e-9)) + 1;
  for (int i = 0; i < count; ++i) grid.push_back(first_nm + i * step_nm);
  return grid;
}

const SampledSpectra& Cie1931Observer() {
  static const SampledSpectra spectra = ParseSpectra("cie1931_2deg_cmf");
  return spectra;
}

const SampledSpectra& IlluminantSpd(Illuminant illuminant) {
  static const SampledSpectra d50 = ParseSpectra("illuminant_d50");
  static const SampledSpectra d65 = ParseSpectra("illuminant_d65");
  static const SampledSpectra a = ParseSpectra("illuminant_a");
  switch (illuminant) {
    case Illuminant::kD50: return d50;
    case Illuminant::kD65: return d65;
    case Illuminant::kA: return a;
  }
  return d65;
}

const SampledSpectra& ColorChecker24Reflectance() {
  static const SampledSpectra spectra = ParseSpectra("colorchecker24_babelcolor_reflectance");
  return spectra;
}

namespace {
struct ReferenceChart {
  std::array<Eigen::Vector3d, 24> lab;
  std::array<std::string, 24> names;
};
const ReferenceChart& LoadReferenceChart() {
  static const ReferenceChart chart = [] {
    ReferenceChart out;
    const CsvTable table = ParseCsv("colorchecker24_lab_d50");
    for (const auto& row : table.rows) {
      if (row[2] != "after_nov2014") continue;
      const int index = std::stoi(row[0]) - 1;
      out.names.at(static_cast<std::size_t>(index)) = row[1];
      out.lab.at(static_cast<std::size_t>(index)) = {std::stod(row[3]), std::stod(row[4]), std::stod(row[5])};
    }
    return out;
  }();
  return chart;
}
}  // namespace

const std::array<Eigen::Vector3d, 24>& ColorChecker24ReferenceLab() { return LoadReferenceChart().lab; }
const std::array<std::string, 24>& ColorChecker24Names() { return LoadReferenceChart().names; }

std::vector<std::string> CameraNames() {
  std::vector<std::string> names;
  for (const auto& camera : kCameras) names.emplace_back(camera.name);
  return names;
}

const SampledSpectra* CameraSensitivity(const std::string& name) {
  static const std::map<std::string, SampledSpectra> cache = [] {
    std::map<std::string, SampledSpectra> all;
    for (const auto& camera : kCameras) all[camera.name] = ParseSpectra(camera.table);
    return all;
  }();
  const CameraEntry* camera = FindCamera(name);
  return camera ? &cache.find(camera->name)->second : nullptr;
}

std::optional<std::string> CameraDescription(const std::string& name) {
  const CameraEntry* camera = FindCamera(name);
  if (!camera) return std::nullopt;
  return camera->description;
}

std::optional<Eigen::Matrix3d> NamedMatrix(const std::string& name) {
  static const CsvTable table = ParseCsv("rgb_xyz_matrices");
  Eigen::Matrix3d m;
  int rows = 0;
  for (const auto& row : table.rows) {
    if (row[0] != name) continue;
    const int r = std::stoi(row[1]);
    for (int c = 0; c < 3; ++c) m(r, c) = std::stod(row[static_cast<std::size_t>(2 + c)]);
    ++rows;
  }
  if (rows != 3) return std::nullopt;
  return m;
}

}  // namespace photorig::solvers::color
