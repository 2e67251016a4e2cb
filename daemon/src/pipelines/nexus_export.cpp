#include "photorig/daemon/pipelines/nexus_export.h"

#include "photorig/daemon/capture/run_store.h"
#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/io/utc_time.h"
#include "photorig/solvers/tomography/nrrd.h"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdio>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <limits>
#include <stdexcept>

namespace photorig::daemon {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string ReadBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// A note holding a file's text as it is (NXnote: type, file_name, data).
void Note(NexusWriter& out, const std::string& path, const std::string& type, const std::string& file_name,
          const std::string& description, const std::string& data) {
  out.Group(path, "NXnote");
  out.Text(path + "/type", type);
  if (!file_name.empty()) out.Text(path + "/file_name", file_name);
  out.Text(path + "/description", description);
  out.Text(path + "/data", data);
}

// An NXdata holding one float image (rows, columns[, channels]).
void DataGroup(NexusWriter& out, const std::string& path, const cv::Mat& image, const std::string& units) {
  out.Group(path, "NXdata");
  out.Attribute(path, "signal", std::string("data"));
  const cv::Mat values = image.isContinuous() ? image : image.clone();
  std::vector<std::uint64_t> dims = {static_cast<std::uint64_t>(values.rows), static_cast<std::uint64_t>(values.cols)};
  if (values.channels() > 1) dims.push_back(static_cast<std::uint64_t>(values.channels()));
  out.Attribute(path, "axes", std::vector<std::string>(dims.size(), "."));
  out.Floats(path + "/data", values.ptr<float>(), dims, units);
  if (values.channels() == 1) out.Attribute(path + "/data", "interpretation", std::string("image"));
}

// 0 a lit frame or projection, 1 a flat field, 2 a dark field: NXtomo's
// image_key, which silx and tomography tools read.
std::int64_t ImageKey(const FrameRecord& frame) {
  using Kind = config::CaptureStep::Kind;
  if (frame.kind == Kind::kDark) return 2;
  if (frame.kind == Kind::kFlat) return 1;
  const bool sample_out = frame.pose && frame.pose->sample_changer_deg && *frame.pose->sample_changer_deg != 0.0;
  const bool reference = frame.group_kind == config::Recipe::Group::Kind::kReferenceTarget;
  return sample_out && !reference ? 1 : 0;
}

void WriteInstrument(NexusWriter& out, const RunManifest& m, std::vector<std::string>* warnings) {
  const std::string instrument = "/entry/instrument";
  out.Group(instrument, "NXinstrument");
  out.Text(instrument + "/name", m.rig_name);
  const std::string rig_text = ReadBytes(m.rig_path);
  if (rig_text.empty())
    warnings->push_back("the rig file " + m.rig_path + " is gone or empty: the file holds no copy of it");
  else
    Note(out, instrument + "/rig", "text/x-yaml", m.rig_path, "the rig file when exported", rig_text);

  const std::string camera = instrument + "/camera";
  out.Group(camera, "NXdetector");
  out.Text(camera + "/local_name", m.camera_id);
  out.Text(camera + "/description", "mosaic " + m.mosaic + (m.pixel_format.empty() ? "" : ", " + m.pixel_format));
  out.Scalar(camera + "/bit_depth_readout", m.bit_depth);
  out.Scalar(camera + "/saturation_value", m.saturation_dn > 0 ? m.saturation_dn : std::ldexp(1.0, m.bit_depth) - 1);
  if (m.pixel_pitch_mm > 0) {
    out.Scalar(camera + "/x_pixel_size", m.pixel_pitch_mm, "mm");
    out.Scalar(camera + "/y_pixel_size", m.pixel_pitch_mm, "mm");
  }
  out.Text(camera + "/projection", solvers::camera::ProjectionName(m.projection));

  if (m.lights.empty()) return;
  const std::string lights = instrument + "/lights";
  out.Group(lights, "NXcollection");
  std::vector<std::int64_t> ids;
  std::vector<double> directions, intensities, positions;
  bool positioned = true;
  for (const config::LedConfig& led : m.lights) {
    ids.push_back(led.id);
    directions.insert(directions.end(), {led.direction.x(), led.direction.y(), led.direction.z()});
    intensities.push_back(led.intensity);
    positioned = positioned && led.position_mm.has_value();
    if (led.position_mm) positions.insert(positions.end(), {led.position_mm->x(), led.position_mm->y(), led.position_mm->z()});
  }
  const std::uint64_t n = m.lights.size();
  out.Ints(lights + "/id", ids);
  out.Doubles(lights + "/direction", directions, {n, 3});
  out.Attribute(lights + "/direction", "description",
                std::string("unit vector towards the LED, camera frame: x right, y up, z towards the camera"));
  out.Doubles(lights + "/intensity", intensities, {n});
  if (positioned) out.Doubles(lights + "/position", positions, {n, 3}, "mm");
}

// One NXpositioner per axis the frames record (arms, turntable, sample changer).
void WritePositioners(NexusWriter& out, const RunManifest& m) {
  struct Axis {
    const char* name;
    double (*value)(const config::GonioPose&);
  };
  static constexpr Axis kAxes[] = {
      {"light_arm", [](const config::GonioPose& p) { return p.light_arm_deg; }},
      {"camera_arm", [](const config::GonioPose& p) { return p.camera_arm_deg; }},
      {"sample_rotation", [](const config::GonioPose& p) { return p.sample_rotation_deg; }},
      {"sample_changer", [](const config::GonioPose& p) { return p.sample_changer_deg.value_or(kNaN); }}};
  bool any_pose = false;
  for (const FrameRecord& frame : m.frames) any_pose = any_pose || frame.pose.has_value();
  if (!any_pose) return;
  for (const Axis& axis : kAxes) {
    std::vector<double> values;
    for (const FrameRecord& frame : m.frames) values.push_back(frame.pose ? axis.value(*frame.pose) : kNaN);
    const std::string path = std::string("/entry/instrument/") + axis.name;
    out.Group(path, "NXpositioner");
    out.Text(path + "/name", axis.name);
    out.Doubles(path + "/value", values, {values.size()}, "deg");
    out.Attribute(path + "/value", "description", std::string("per frame; NaN where the frame has no pose"));
  }
  out.Link("/entry/instrument/sample_rotation/value", "/entry/sample/rotation_angle");
}

// The frames as one stack, and what each frame is along the first axis (the
// manifest note names each frame's file and group).
bool WriteFrames(NexusWriter& out, const std::string& run, const RunManifest& m, NexusExportSummary* summary) {
  const std::string data = "/entry/data";
  out.Group(data, "NXdata");
  out.Attribute(data, "signal", std::string("data"));
  const int channels = MosaicChannels(m.mosaic);
  std::vector<std::string> axes = {"frame_index", ".", "."};
  if (channels > 1) axes.emplace_back(".");
  out.Attribute(data, "axes", axes);
  out.Attribute(data, "frame_index_indices", std::int64_t{0});
  std::vector<std::uint64_t> frame_dims = {static_cast<std::uint64_t>(m.height), static_cast<std::uint64_t>(m.width)};
  if (channels > 1) frame_dims.push_back(static_cast<std::uint64_t>(channels));
  out.BeginFrameStack(data + "/data", m.frames.size(), frame_dims);
  out.Attribute(data + "/data", "units", std::string("DN"));
  out.Attribute(data + "/data", "interpretation", std::string(channels > 1 ? "rgb-image" : "image"));

  std::vector<std::int64_t> index, keys, leds, crcs;
  std::vector<double> exposures, levels;
  for (std::size_t i = 0; i < m.frames.size(); ++i) {
    const FrameRecord& frame = m.frames[i];
    cv::Mat pixels;
    try {
      pixels = LoadFrame(run, frame);
    } catch (const std::exception& e) {
      summary->End(solvers::core::Termination::kInvalidInput, e.what());  // LoadFrame says what to do
      return false;
    }
    if (pixels.rows != m.height || pixels.cols != m.width || pixels.channels() != channels) {
      summary->End(solvers::core::Termination::kInvalidInput,
                   run + "/" + frame.file + " is not the " + std::to_string(m.width) + " x " +
                       std::to_string(m.height) + " frame its manifest says");
      return false;
    }
    if (!pixels.isContinuous()) pixels = pixels.clone();
    out.WriteFrame(i, pixels.ptr<std::uint16_t>());
    summary->frame_bytes += fs::file_size(fs::path(run) / frame.file);
    index.push_back(frame.index);
    keys.push_back(ImageKey(frame));
    leds.push_back(frame.led);
    crcs.push_back(frame.crc32);
    exposures.push_back(frame.exposure_us);
    levels.push_back(frame.level);
  }
  out.Ints(data + "/frame_index", index);
  out.Ints(data + "/image_key", keys);
  out.Attribute(data + "/image_key", "description", std::string("0 lit frame or projection, 1 flat field, 2 dark field"));
  out.Ints(data + "/led", leds);
  out.Attribute(data + "/led", "description", std::string("the one LED lit (index into instrument/lights), else -1"));
  out.Doubles(data + "/exposure_time", exposures, {exposures.size()}, "us");
  out.Doubles(data + "/level", levels, {levels.size()});
  out.Ints(data + "/crc32", crcs);
  out.Link(data + "/data", "/entry/instrument/camera/data");
  out.Link(data + "/image_key", "/entry/instrument/camera/image_key");
  summary->frames = static_cast<int>(m.frames.size());
  return true;
}

// UTC of a time stamp in nanoseconds since the epoch (the frames' host_timestamp_ns).
std::string IsoTime(std::int64_t unix_ns) { return UtcIso8601(static_cast<std::time_t>(unix_ns / 1000000000)); }

std::string FileTime(const fs::path& path) {
  const auto written = fs::last_write_time(path);
  const auto system = std::chrono::time_point_cast<std::chrono::nanoseconds>(
      written - fs::file_time_type::clock::now() + std::chrono::system_clock::now());
  return IsoTime(system.time_since_epoch().count());
}

// The solve's outputs as NXdata groups beside its report.
void WriteOutputs(NexusWriter& out, const std::string& process, const fs::path& folder,
                  std::vector<std::string>* warnings) {
  struct Image {
    const char* file;
    const char* units;
  };
  static constexpr Image kImages[] = {
      {"normals.tiff", ""}, {"albedo.tiff", ""}, {"confidence.tiff", ""}, {"depth.tiff", "pixel pitch"}};
  for (const Image& image : kImages)
    if (fs::exists(folder / image.file))
      DataGroup(out, process + "/" + fs::path(image.file).stem().string(), ReadFloatTiff((folder / image.file).string()),
                image.units);
  if (fs::exists(folder / "volume.nrrd")) {
    solvers::tomography::VolumeGrid grid;
    Eigen::VectorXf sigma;
    if (const solvers::core::Summary read = solvers::tomography::ReadNrrd((folder / "volume.nrrd").string(), &grid, &sigma);
        !read.IsSolutionUsable()) {
      warnings->push_back(read.message);
    } else {
      const std::string volume = process + "/volume";
      out.Group(volume, "NXdata");
      out.Attribute(volume, "signal", std::string("data"));
      out.Attribute(volume, "axes", std::vector<std::string>{"z", "y", "x"});
      const std::uint64_t nz = grid.nz, ny = grid.ny, nx = grid.nx;
      out.Floats(volume + "/data", sigma.data(), {nz, ny, nx}, "1/mm");
      for (const auto& [name, n] : {std::pair<const char*, int>{"z", grid.nz}, {"y", grid.ny}, {"x", grid.nx}}) {
        std::vector<double> centres;
        for (int i = 0; i < n; ++i) centres.push_back((i + 0.5 - 0.5 * n) * grid.voxel_mm);
        out.Doubles(volume + "/" + name, centres, {centres.size()}, "mm");
      }
    }
  }
  if (fs::exists(folder / "samples.csv"))
    Note(out, process + "/samples", "text/csv", "samples.csv", "the calibrated BRDF samples the models were fitted to",
         ReadBytes(folder / "samples.csv"));
}

// The chosen BRDF model's parameters as fields, from its report.
void WriteBrdfParameters(NexusWriter& out, const std::string& process, const json& report) {
  if (!report.contains("chosen")) return;
  for (const json& fit : report.value("candidates", json::array())) {
    if (fit.value("model", "") != report["chosen"]) continue;
    const std::string parameters = process + "/parameters";
    out.Group(parameters, "NXparameters");
    out.Text(parameters + "/model", fit["model"].get<std::string>());
    for (const char* key : {"diffuse", "specular", "specular2"})
      out.Doubles(parameters + "/" + key, fit[key].get<std::vector<double>>(), {3});
    for (const char* key : {"shape", "fresnel_f0", "specular_scale", "shape2", "bic", "held_out_rms"})
      if (fit[key].is_number()) out.Scalar(parameters + "/" + key, fit[key].get<double>());
  }
}

// False, with a warning, when the report cannot be read: the solve is left out.
bool WriteProcess(NexusWriter& out, const fs::path& folder, const std::string& name, int sequence_index,
                  std::vector<std::string>* warnings) {
  const std::string report_text = ReadBytes(folder / "report.json");
  const json report = json::parse(report_text, nullptr, false);
  if (report.is_discarded()) {
    warnings->push_back((folder / "report.json").string() + " is not JSON: results/" + name + " left out");
    return false;
  }
  const std::string process = "/entry/" + name;
  out.Group(process, "NXprocess");
  const json provenance = report.value("provenance", json::object());
  out.Text(process + "/program", provenance.value("program", "photorig"));
  out.Text(process + "/version", provenance.value("version", "unrecorded"));
  out.Text(process + "/date", provenance.value("date", FileTime(folder / "report.json")));
  out.Integer(process + "/sequence_index", sequence_index);
  Note(out, process + "/report", "application/json", "report.json", "the solve's report as written", report_text);
  if (provenance.contains("options"))
    Note(out, process + "/options", "application/json", "", "the solve's exact options (photorig solve --from reads them)",
         provenance["options"].dump(2));
  if (provenance.contains("inputs"))
    Note(out, process + "/input_checksums", "application/json", "", "the run's manifest and frames the solve read",
         provenance["inputs"].dump(2));
  WriteOutputs(out, process, folder, warnings);
  WriteBrdfParameters(out, process, report);
  return true;
}

void WriteEntry(NexusWriter& out, const std::string& run, const RunManifest& m, const std::string& manifest_text) {
  out.Group("/entry", "NXentry");
  out.Attribute("/entry", "default", std::string("data"));
  out.Text("/entry/title", m.recipe_name + ": " + m.run_id);
  out.Text("/entry/experiment_identifier", m.run_id);
  out.Text("/entry/program_name", "photorig");
  if (!m.frames.empty()) {
    out.Text("/entry/start_time", IsoTime(m.frames.front().host_timestamp_ns));
    out.Text("/entry/end_time", IsoTime(m.frames.back().host_timestamp_ns));
  }
  Note(out, "/entry/manifest", "application/json", "manifest.json", "the run's manifest (docs/run-format.md), from " + run,
       manifest_text);
  out.Group("/entry/sample", "NXsample");
  out.Text("/entry/sample/name", m.sample_name);
}

}  // namespace

nlohmann::json NexusExportSummary::ToJson() const {
  return {{"out", path},
          {"frames", frames},
          {"processes", processes},
          {"warnings", warnings},
          {"file_bytes", file_bytes},
          {"frame_bytes", frame_bytes},
          {"total_ms", total_ms}};
}

std::string NexusExportSummary::Line() const {
  std::string solves = "no solves";
  for (std::size_t i = 0; i < processes.size(); ++i) solves = (i == 0 ? "solves: " : solves + ", ") + processes[i];
  char sizes[128];
  std::snprintf(sizes, sizeof(sizes), "%.1f MB (the frames' PNGs %.1f MB), %.0f ms", file_bytes / 1e6,
                frame_bytes / 1e6, total_ms);
  return "wrote " + path + ": " + std::to_string(frames) + " frames, " + solves + ", " + sizes;
}

bool NexusExportOptions::IsValid(std::string* why) const {
  if (!writer.IsValid(why)) return false;
  for (const std::string& name : results)
    if (name.empty() || name.find('/') != std::string::npos)
      return solvers::core::Refuse(why, "results names a folder of results/, not a path: '" + name + "'");
  return true;
}

NexusExportSummary ExportNexus(const std::string& run_directory, const std::string& path,
                               const NexusExportOptions& options) {
  const solvers::core::SolveTimer timer;
  NexusExportSummary summary;
  summary.path = path;
  if (std::string why; !options.IsValid(&why)) {
    summary.End(solvers::core::Termination::kInvalidOptions, why);
    return summary;
  }
  try {
    const RunManifest manifest = LoadRunManifest(run_directory);
    NexusWriter out(path, "photorig " PHOTORIG_VERSION, "entry", options.writer);
    WriteEntry(out, run_directory, manifest, ReadBytes(fs::path(run_directory) / "manifest.json"));
    WriteInstrument(out, manifest, &summary.warnings);
    WritePositioners(out, manifest);
    if (!WriteFrames(out, run_directory, manifest, &summary)) {
      out.Abandon(summary.message);
      return summary;
    }
    int sequence_index = 1;
    for (const std::string& name : options.results) {
      const fs::path folder = fs::path(run_directory) / "results" / name;
      if (fs::exists(folder / "report.json") && WriteProcess(out, folder, name, sequence_index, &summary.warnings)) {
        summary.processes.push_back(name);
        ++sequence_index;
      }
    }
    if (!out.Close()) {
      summary.End(solvers::core::Termination::kFailure, out.error());
      return summary;
    }
  } catch (const std::exception& e) {
    // No manifest, an unreadable result file: the writer, gone with its scope, left no file.
    summary.End(solvers::core::Termination::kInvalidInput, e.what());
    return summary;
  }
  summary.file_bytes = fs::file_size(path);
  summary.termination = solvers::core::Termination::kSuccess;
  summary.total_ms = timer.ElapsedMs();
  return summary;
}

}  // namespace photorig::daemon
