#include "photorig/daemon/capture/run_store.h"

#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/io/json_fields.h"
#include "photorig/daemon/io/lens_json.h"
#include "photorig/solvers/core/names.h"

#include <opencv2/imgproc.hpp>
#include <spdlog/fmt/fmt.h>

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace photorig::daemon {

bool IsBayerPattern(const std::string& mosaic) {
  for (const char* pattern : {"RGGB", "BGGR", "GRBG", "GBRG"})
    if (mosaic == pattern) return true;
  return false;
}

bool IsKnownMosaic(const std::string& mosaic) { return mosaic == "mono" || mosaic == "RGB" || IsBayerPattern(mosaic); }

int MosaicChannels(const std::string& mosaic) { return mosaic == "RGB" ? 3 : 1; }
namespace fs = std::filesystem;
using nlohmann::json;
namespace {

[[noreturn]] void FailIo(const std::string& what, const std::string& path) {
  throw std::runtime_error(what + " " + path + ": " + std::strerror(errno));
}

void WriteAll(int fd, const void* data, std::size_t size, const std::string& path) {
  const char* bytes = static_cast<const char*>(data);
  std::size_t written = 0;
  while (written < size) {
    const ssize_t n = ::write(fd, bytes + written, size - written);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) FailIo("cannot write", path);
    written += static_cast<std::size_t>(n);
  }
}

// Closes on every exit path, so a failed frame write leaks no descriptor.
struct ScopedFd {
  int fd;
  ~ScopedFd() { ::close(fd); }
};

}  // namespace

json ToJson(const FrameRecord& f) {
  json out = {{"index", f.index},
          {"file", f.file},
          {"kind", config::CaptureStepKindName(f.kind)},
          {"group", f.group},
          {"repeat", f.repeat},
          {"led", f.led},
          {"level", f.level},
          {"exposure_us", f.exposure_us},
          {"gain_db", f.gain_db},
          {"bit_depth", f.bit_depth},
          {"pixel_format", f.pixel_format},
          {"frame_id", f.frame_id},
          {"device_timestamp_ns", f.device_timestamp_ns},
          {"host_timestamp_ns", f.host_timestamp_ns},
          {"crc32", f.crc32}};
  if (f.pose)
    out["pose"] = {{"light_arm_deg", f.pose->light_arm_deg},
                   {"camera_arm_deg", f.pose->camera_arm_deg},
                   {"sample_rotation_deg", f.pose->sample_rotation_deg}};
  if (f.pose && f.pose->sample_changer_deg) out["pose"]["sample_changer_deg"] = *f.pose->sample_changer_deg;
  if (f.pass > 0) out["pass"] = f.pass;
  return out;
}

FrameRecord FrameRecordFromJson(const json& j) {
  FrameRecord f;
  f.index = IntegerIn<int>(j, "index", 0, std::numeric_limits<int>::max());
  f.file = j.at("file").get<std::string>();
  const std::string kind = j.at("kind").get<std::string>();
  const auto parsed = config::CaptureStepKindFromName(kind);
  if (!parsed) throw std::runtime_error("frame " + f.file + " has an unknown kind '" + kind + "'");
  f.kind = *parsed;
  f.group = j.value("group", "");  // absent in runs stored before groups existed
  f.group_kind = config::GroupKindOfLabel(f.group);
  f.repeat = IntegerOr(j, "repeat", 0, 0, std::numeric_limits<int>::max());
  f.led = IntegerIn<int>(j, "led", -1, std::numeric_limits<int>::max());  // checked against the lights by the manifest
  f.level = NumberIn(j, "level", 0.0, 1.0);
  f.exposure_us = NumberIn(j, "exposure_us", 0.0);
  f.gain_db = NumberIn(j, "gain_db");
  f.bit_depth = IntegerIn<int>(j, "bit_depth", 1, 16);
  f.pixel_format = j.value("pixel_format", "");  // absent in runs stored before it was recorded
  f.frame_id = IntegerAt<std::uint64_t>(j, "frame_id");
  f.device_timestamp_ns = IntegerAt<std::int64_t>(j, "device_timestamp_ns");
  f.host_timestamp_ns = IntegerAt<std::int64_t>(j, "host_timestamp_ns");
  f.crc32 = IntegerAt<std::uint32_t>(j, "crc32");
  if (j.contains("pose")) {
    const json& p = j.at("pose");
    f.pose = config::GonioPose{NumberIn(p, "light_arm_deg"), NumberIn(p, "camera_arm_deg"),
                               NumberIn(p, "sample_rotation_deg"), std::nullopt};
    if (p.contains("sample_changer_deg")) f.pose->sample_changer_deg = NumberIn(p, "sample_changer_deg");
  }
  f.pass = IntegerOr(j, "pass", 0, 0, std::numeric_limits<int>::max());
  return f;
}

namespace {

constexpr solvers::core::NameTable<CaptureStatus, 5> kCaptureStatusNames = {{
    {CaptureStatus::kRunning, "running"}, {CaptureStatus::kComplete, "complete"}, {CaptureStatus::kFailed, "failed"},
    {CaptureStatus::kAborted, "aborted"}, {CaptureStatus::kInterrupted, "interrupted"},
}};

CaptureStatus CaptureStatusFromJson(const json& j) {
  const std::string name = j.get<std::string>();
  const std::optional<CaptureStatus> status = CaptureStatusFromName(name);
  if (!status) throw std::runtime_error("unknown capture status '" + name + "'");
  return *status;
}

}  // namespace

const char* CaptureStatusName(CaptureStatus status) { return solvers::core::NameOf(kCaptureStatusNames, status); }

std::ostream& operator<<(std::ostream& out, CaptureStatus status) { return out << CaptureStatusName(status); }

std::optional<CaptureStatus> CaptureStatusFromName(const std::string& name) {
  return solvers::core::ParseName(kCaptureStatusNames, name);
}

json ToJson(const StopRecord& s) {
  return {{"status", CaptureStatusName(s.status)}, {"reason", s.reason},   {"frames", s.frames},
          {"steps_total", s.steps_total}, {"retries", s.retries}, {"dropped_frames", s.dropped_frames}};
}

StopRecord StopRecordFromJson(const json& j) {
  StopRecord s;
  s.status = CaptureStatusFromJson(j.at("status"));
  s.reason = j.value("reason", "");
  constexpr int kMost = std::numeric_limits<int>::max();
  s.frames = IntegerIn<int>(j, "frames", 0, kMost);
  s.steps_total = IntegerIn<int>(j, "steps_total", 0, kMost);
  s.retries = IntegerOr(j, "retries", 0, 0, kMost);
  s.dropped_frames = IntegerOr(j, "dropped_frames", 0, 0, kMost);
  return s;
}

json ToJson(const RunManifest& m) {
  json lights = json::array();
  for (const config::LedConfig& led : m.lights) {
    lights.push_back({{"id", led.id},
                      {"direction", {led.direction.x(), led.direction.y(), led.direction.z()}},
                      {"intensity", led.intensity},
                      {"rgb_intensity", {led.rgb_intensity.x(), led.rgb_intensity.y(), led.rgb_intensity.z()}}});
    if (led.position_mm) {
      const Eigen::Vector3d axis = led.EmissionAxis();
      lights.back()["position_mm"] = {led.position_mm->x(), led.position_mm->y(), led.position_mm->z()};
      lights.back()["axis"] = {axis.x(), axis.y(), axis.z()};
      lights.back()["cos_exponent"] = led.cos_exponent;
    }
  }
  json frames = json::array();
  for (const FrameRecord& f : m.frames) frames.push_back(ToJson(f));
  json out = {{"format", m.format},
          {"run_id", m.run_id},
          {"recipe", {{"path", m.recipe_path}, {"name", m.recipe_name}, {"solve", m.solve_stages}}},
          {"rig", {{"path", m.rig_path}, {"name", m.rig_name}}},
          {"status", CaptureStatusName(m.status)},
          {"status_reason", m.status_reason},
          {"sample", m.sample_name},
          {"camera",
           {{"id", m.camera_id},
            {"width", m.width},
            {"height", m.height},
            {"bit_depth", m.bit_depth},
            {"saturation_dn", m.saturation_dn},
            {"dn_per_radiance_per_us", m.dn_per_radiance_per_us},
            {"e_per_dn", m.e_per_dn},
            {"pixel_pitch_mm", m.pixel_pitch_mm},
            {"mosaic", m.mosaic},
            {"pixel_format", m.pixel_format}}},
          {"lights", lights},
          {"frames", frames},
          {"ground_truth", m.has_ground_truth}};
  if (m.projection == solvers::camera::Projection::kPinhole) {
    out["camera"]["projection"] = solvers::camera::ProjectionName(m.projection);
    out["camera"]["pinhole"] = PinholeLensJson(m.pinhole);
  }
  if (!m.color_model_path.empty())
    out["camera"]["color_model"] = {{"path", m.color_model_path}, {"hash", m.color_model_hash}};
  if (m.reference_albedo) out["reference_target"] = {{"albedo", *m.reference_albedo}};
  if (m.stop) out["stop"] = ToJson(*m.stop);
  return out;
}

namespace {

// object[key] as three finite numbers; a direction must not be all zero.
Eigen::Vector3d Vector3At(const json& object, const char* key, bool direction) {
  const json& value = object.at(key);
  if (value.is_array() && value.size() == 3 && std::all_of(value.begin(), value.end(), [](const json& v) {
        return v.is_number() && std::isfinite(v.get<double>());
      })) {
    const Eigen::Vector3d v(value[0].get<double>(), value[1].get<double>(), value[2].get<double>());
    if (!direction || v.squaredNorm() > 0.0) return v;
  }
  throw std::runtime_error(std::string("'") + key + "' must be three finite numbers" +
                           (direction ? " not all zero" : "") + ", not " + value.dump());
}

config::LedConfig LedFromJson(const json& light) {
  config::LedConfig led;
  led.id = IntegerIn<int>(light, "id", 0, std::numeric_limits<int>::max());
  led.direction = Vector3At(light, "direction", true);
  led.intensity = NumberIn(light, "intensity", 0.0);
  // absent in runs stored before the field existed
  if (light.contains("rgb_intensity")) {
    led.rgb_intensity = Vector3At(light, "rgb_intensity", false);
    if (led.rgb_intensity.minCoeff() < 0.0)
      throw std::runtime_error("'rgb_intensity' must not be negative, not " + light.at("rgb_intensity").dump());
  }
  if (light.contains("position_mm")) {
    led.position_mm = Vector3At(light, "position_mm", false);
    // absent in runs stored before LED axes were recorded: aimed at the origin
    if (light.contains("axis")) led.axis = Vector3At(light, "axis", true);
    led.cos_exponent = NumberOr(light, "cos_exponent", 1.0, 0.0);
  }
  return led;
}

// Manifest `m` names frame `f`'s LED among its lights.
void CheckLedOfFrame(const RunManifest& m, const FrameRecord& f) {
  if (f.led >= static_cast<int>(m.lights.size()))
    throw std::runtime_error("frame " + f.file + " names LED " + std::to_string(f.led) + " but the run has " +
                             std::to_string(m.lights.size()) + " lights");
}

}  // namespace

RunManifest RunManifestFromJson(const json& j) {
  RunManifest m;
  m.format = j.at("format").get<std::string>();
  if (m.format != "photorig-run/1") throw std::runtime_error("unsupported run format '" + m.format + "'");
  m.run_id = j.at("run_id").get<std::string>();
  m.recipe_path = j.at("recipe").at("path").get<std::string>();
  m.recipe_name = j.at("recipe").at("name").get<std::string>();
  m.solve_stages = j.at("recipe").value("solve", std::vector<std::string>{});
  m.rig_path = j.at("rig").at("path").get<std::string>();
  m.rig_name = j.at("rig").at("name").get<std::string>();
  m.status = CaptureStatusFromJson(j.at("status"));
  m.status_reason = j.value("status_reason", "");
  m.sample_name = j.value("sample", "");
  const json& camera = j.at("camera");
  m.camera_id = camera.at("id").get<std::string>();
  // Each range as wide as any camera photorig stores frames of (16-bit PNGs).
  m.width = IntegerIn<int>(camera, "width", 1, 65535);
  m.height = IntegerIn<int>(camera, "height", 1, 65535);
  m.bit_depth = IntegerIn<int>(camera, "bit_depth", 1, 16);
  m.saturation_dn = NumberOr(camera, "saturation_dn", 0.0, 0.0, 65535.0);  // absent in runs of earlier versions
  m.dn_per_radiance_per_us = NumberIn(camera, "dn_per_radiance_per_us", 0.0);
  m.e_per_dn = NumberOr(camera, "e_per_dn", 0.0, 0.0);
  m.pixel_pitch_mm = NumberOr(camera, "pixel_pitch_mm", 0.0, 0.0);
  const std::string projection = camera.value("projection", "orthographic");
  const std::optional<solvers::camera::Projection> parsed = solvers::camera::ParseProjection(projection);
  if (!parsed) throw std::runtime_error("unknown camera projection '" + projection + "'");
  m.projection = *parsed;
  if (m.projection == solvers::camera::Projection::kPinhole) {
    m.pinhole = PinholeLensFromJson(camera.at("pinhole"));
    if (std::string why; !m.pinhole.IsValid(&why)) throw std::runtime_error("camera pinhole: " + why);
  }
  m.mosaic = camera.value("mosaic", "mono");  // runs stored before colour cameras are monochrome
  if (!IsKnownMosaic(m.mosaic)) throw std::runtime_error("unknown camera mosaic '" + m.mosaic + "'");
  m.pixel_format = camera.value("pixel_format", "");
  if (camera.contains("color_model")) {
    m.color_model_path = camera.at("color_model").at("path").get<std::string>();
    m.color_model_hash = camera.at("color_model").value("hash", "");
  }
  for (const json& light : j.at("lights")) {
    try {
      m.lights.push_back(LedFromJson(light));
    } catch (const std::exception& e) {
      throw std::runtime_error("light " + std::to_string(m.lights.size()) + ": " + WithoutJsonLibraryTag(e.what()));
    }
  }
  if (j.contains("reference_target")) {
    try {
      m.reference_albedo = NumberIn(j.at("reference_target"), "albedo", 0.0, 1.0);
    } catch (const std::exception& e) {
      throw std::runtime_error("reference_target: " + WithoutJsonLibraryTag(e.what()));
    }
  }
  for (const json& frame : j.at("frames")) {
    try {
      m.frames.push_back(FrameRecordFromJson(frame));
    } catch (const std::exception& e) {
      throw std::runtime_error("frame " + std::to_string(m.frames.size()) + ": " + WithoutJsonLibraryTag(e.what()));
    }
    CheckLedOfFrame(m, m.frames.back());
  }
  m.has_ground_truth = j.value("ground_truth", false);
  if (j.contains("stop")) m.stop = StopRecordFromJson(j.at("stop"));
  return m;
}

RunWriter::RunWriter(std::string directory, RunManifest header)
    : directory_(std::move(directory)), manifest_(std::move(header)) {
  if (fs::exists(directory_) && !fs::is_empty(directory_))
    throw std::runtime_error("run directory " + directory_ + " already exists and is not empty");
  fs::create_directories(fs::path(directory_) / "frames");
  const std::string journal = (fs::path(directory_) / "journal.jsonl").string();
  journal_fd_ = ::open(journal.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (journal_fd_ < 0) throw std::runtime_error("cannot create " + journal + ": " + std::strerror(errno));
  // The header first, so a journal alone describes the run.
  json header_line = ToJson(manifest_);
  header_line.erase("frames");
  try {
    AppendJournal(json{{"run", header_line}});
  } catch (...) {
    ::close(journal_fd_);  // no destructor runs for a constructor that throws
    throw;
  }
}

void RunWriter::AppendJournal(const json& entry) {
  AppendJournalUnsynced(entry);
  if (::fdatasync(journal_fd_) != 0)
    throw std::runtime_error("cannot fsync the journal of " + directory_ + ": " + std::strerror(errno));
}

void RunWriter::AppendJournalUnsynced(const json& entry) {
  const std::string line = entry.dump() + "\n";
  WriteAll(journal_fd_, line.data(), line.size(), (fs::path(directory_) / "journal.jsonl").string());
}

std::unique_ptr<RunWriter> RunWriter::Reopen(const std::string& directory, RecoveryReport* report) {
  RecoveryReport local;
  RecoveryReport& r = report ? *report : local;
  r = {};
  const fs::path journal = fs::path(directory) / "journal.jsonl";
  std::string text;
  {
    std::ifstream in(journal, std::ios::binary);
    if (!in) throw std::runtime_error("cannot open " + journal.string() + " (is " + directory + " a run directory?)");
    text.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  // A crash can leave a partly written last line; everything before the last
  // newline was fsynced whole.
  const std::size_t end = text.rfind('\n');
  const std::size_t complete = end == std::string::npos ? 0 : end + 1;
  r.journal_tail_torn = complete != text.size();
  text.resize(complete);

  auto writer = std::unique_ptr<RunWriter>(new RunWriter());
  writer->directory_ = directory;
  std::istringstream lines(text);
  std::string line;
  bool have_header = false;
  std::map<int, FrameRecord> frames;  // by step index: a retaken step replaces its earlier record
  for (int line_number = 1; std::getline(lines, line); ++line_number) {
    // A line that parses but is not a record (a number, a header that is not an
    // object, a field of the wrong type) is as corrupt as one that does not parse.
    try {
      const json entry = json::parse(line);
      if (entry.contains("run")) {
        json header = entry.at("run");
        header["frames"] = json::array();
        writer->manifest_ = RunManifestFromJson(header);
        have_header = true;
      } else if (entry.contains("stop")) {
        writer->manifest_.stop = StopRecordFromJson(entry.at("stop"));
      } else {
        const FrameRecord record = FrameRecordFromJson(entry);
        if (have_header) CheckLedOfFrame(writer->manifest_, record);
        frames[record.index] = record;
      }
    } catch (const std::exception& e) {
      throw std::runtime_error(journal.string() + ":" + std::to_string(line_number) + ": corrupt line: " + e.what());
    }
  }
  if (!have_header) throw std::runtime_error(journal.string() + ": no run header (journal is empty or torn)");

  std::set<std::string> vouched;
  for (const auto& [index, record] : frames) {
    try {
      LoadFrame(directory, record);
      writer->manifest_.frames.push_back(record);
      vouched.insert(fs::path(record.file).filename().string());
      ++r.frames_kept;
    } catch (const std::exception&) {
      ++r.frames_discarded;
    }
  }
  // Temp files from a write that never got renamed, and frames renamed into
  // place whose journal line never landed: the step is retaken.
  const fs::path frames_dir = fs::path(directory) / "frames";
  fs::create_directories(frames_dir);
  for (const auto& entry : fs::directory_iterator(frames_dir)) {
    if (vouched.count(entry.path().filename().string())) continue;
    fs::remove(entry.path());
    r.removed_files.push_back(entry.path().string());
  }
  for (const char* stale : {"manifest.json.tmp", "journal.jsonl.tmp"}) {
    if (fs::remove(fs::path(directory) / stale)) r.removed_files.push_back((fs::path(directory) / stale).string());
  }
  // Rewrite the journal so that it says exactly what is on disk.
  json header_line = ToJson(writer->manifest_);
  header_line.erase("frames");
  header_line.erase("stop");
  std::string clean = json{{"run", header_line}}.dump() + "\n";
  for (const FrameRecord& record : writer->manifest_.frames) clean += ToJson(record).dump() + "\n";
  WriteFileDurably(journal.string(), clean);
  writer->manifest_.stop.reset();
  writer->manifest_.status = CaptureStatus::kRunning;
  writer->journal_fd_ = ::open(journal.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC);
  if (writer->journal_fd_ < 0) throw std::runtime_error("cannot open " + journal.string() + ": " + std::strerror(errno));
  return writer;
}

bool RunWriter::HasFrame(int step_index) const {
  for (const FrameRecord& record : manifest_.frames)
    if (record.index == step_index) return true;
  return false;
}

RunWriter::~RunWriter() {
  if (journal_fd_ >= 0) ::close(journal_fd_);
}

const FrameRecord& RunWriter::WriteFrame(const config::CaptureStep& step, const drivers::Frame& frame) {
  // RGB frames carry three samples per pixel; raw Bayer mosaics are one-channel
  // frames and are stored as they came.
  const int channels = MosaicChannels(manifest_.mosaic);
  if (frame.width <= 0 || frame.height <= 0 ||
      frame.pixels.size() != static_cast<std::size_t>(frame.width) * frame.height * channels)
    throw std::runtime_error("frame " + std::to_string(frame.frame_id) + " for step " + step.label +
                             " is short: " + std::to_string(frame.pixels.size()) + " samples for " +
                             std::to_string(frame.width) + "x" + std::to_string(frame.height));
  FrameRecord record;
  record.index = step.index;
  record.file = "frames/" + step.label + ".png";
  record.kind = step.kind;
  record.group = step.group;
  record.group_kind = step.group_kind;
  record.repeat = step.repeat;
  record.led = step.led;
  record.level = step.led >= 0 ? step.pattern->levels.at(step.led) : 0.0;
  record.pose = step.pose;
  record.pass = step.pass;
  record.exposure_us = frame.exposure_us;
  record.gain_db = frame.gain_db;
  record.bit_depth = frame.bit_depth;
  record.pixel_format = frame.pixel_format;
  record.frame_id = frame.frame_id;
  record.device_timestamp_ns = frame.device_timestamp_ns;
  record.host_timestamp_ns = frame.host_timestamp_ns;
  // Temp file and rename, so the name only ever points at a whole frame.
  const std::string path = (fs::path(directory_) / record.file).string();
  const std::string temp = path + ".tmp";
  try {
    {
      const ScopedFd file{::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644)};
      if (file.fd < 0) FailIo("cannot create", temp);
      off_t offset = 0;
      record.crc32 = encoder_.Encode(frame.pixels.data(), frame.width, frame.height,
                                     [&](const std::uint8_t* data, std::size_t size) {
                                       WriteAll(file.fd, data, size, temp);
                                       // Writeback of each piece starts while the next is encoded,
                                       // so the sync below waits only for the tail.
                                       ::sync_file_range(file.fd, offset, static_cast<off_t>(size), SYNC_FILE_RANGE_WRITE);
                                       offset += static_cast<off_t>(size);
                                     },
                                     channels);
    }
    if (::rename(temp.c_str(), path.c_str()) != 0) FailIo("cannot rename into", path);
  } catch (...) {
    ::unlink(temp.c_str());  // on a full disk, the part written would hold the space
    throw;
  }
  AppendJournalUnsynced(ToJson(record));
  // One syncfs makes the frame's data, its name and its journal line durable
  // together. Separate fdatasyncs of the frame, the directory and the journal
  // cost the same on a quiet machine but each waits for the journal thread,
  // which on busy cores costs a scheduler tick apiece (16 ms against 4 ms).
  // Until it returns nothing is promised: a crash before may leave the journal
  // line without its frame, and Reopen drops any journalled frame that is
  // missing or fails its checksum.
  if (::syncfs(journal_fd_) != 0) FailIo("cannot sync the filesystem of", directory_);
  manifest_.frames.push_back(record);
  return manifest_.frames.back();
}

void RunWriter::WriteGroundTruth(const sim::SurfaceMaps& surface, const std::vector<sim::Light>& lights,
                                 const cv::Mat& albedo_rgb) {
  const fs::path truth = fs::path(directory_) / "ground_truth";
  fs::create_directories(truth);
  std::ostringstream directions, intensities;
  directions.precision(17);
  intensities.precision(17);
  for (const sim::Light& light : lights) {
    directions << light.direction.x() << ' ' << light.direction.y() << ' ' << light.direction.z() << '\n';
    intensities << light.irradiance << '\n';
  }
  WriteFileDurably((truth / "light_directions.txt").string(), directions.str());
  WriteFileDurably((truth / "light_intensities.txt").string(), intensities.str());
  // Near LEDs as built: what an LED-position calibration is scored against.
  if (!lights.empty() && std::all_of(lights.begin(), lights.end(), [](const sim::Light& l) { return l.position_mm.has_value(); })) {
    std::ostringstream positions;
    positions.precision(17);
    for (const sim::Light& light : lights)
      positions << light.position_mm->x() << ' ' << light.position_mm->y() << ' ' << light.position_mm->z() << '\n';
    WriteFileDurably((truth / "light_positions.txt").string(), positions.str());
  }
  WriteFloatTiff((truth / "normals.tiff").string(), surface.normals);
  WriteFloatTiff((truth / "albedo.tiff").string(), surface.albedo);
  if (!albedo_rgb.empty()) WriteFloatTiff((truth / "albedo_rgb.tiff").string(), albedo_rgb);
  WriteImage((truth / "mask.png").string(), surface.mask);
  if (!surface.material.empty()) WriteImage((truth / "material.png").string(), surface.material);
  if (!surface.height.empty()) WriteFloatTiff((truth / "height.tiff").string(), surface.height);
  if (!surface.brdf_params.empty()) {
    // (rho_s, shininess, f0): rho_d is albedo.tiff.
    std::vector<cv::Mat> channels;
    cv::split(surface.brdf_params, channels);
    cv::Mat specular;
    cv::merge(std::vector<cv::Mat>{channels[1], channels[2], channels[3]}, specular);
    WriteFloatTiff((truth / "specular.tiff").string(), specular);
  }
  manifest_.has_ground_truth = true;
}

void RunWriter::WriteVolumeGroundTruth(const cv::Mat& line_integrals, const std::string& phantom_json) {
  const fs::path truth = fs::path(directory_) / "ground_truth";
  fs::create_directories(truth);
  if (!line_integrals.empty()) WriteFloatTiff((truth / "line_integrals.tiff").string(), line_integrals);
  if (!phantom_json.empty()) WriteFileDurably((truth / "phantom.json").string(), phantom_json);
  manifest_.has_ground_truth = true;
}

void RunWriter::Finish(const StopRecord& stop) {
  manifest_.status = stop.status;
  manifest_.status_reason = stop.reason;
  manifest_.stop = stop;
  manifest_.stop->frames = static_cast<int>(manifest_.frames.size());
  AppendJournal(json{{"stop", ToJson(*manifest_.stop)}});
  WriteFileDurably((fs::path(directory_) / "manifest.json").string(), ToJson(manifest_).dump(2) + "\n");
}

RunManifest LoadRunManifest(const std::string& directory) {
  const std::string path = (fs::path(directory) / "manifest.json").string();
  std::ifstream in(path);
  if (!in) {
    if (!fs::exists(path))
      throw std::invalid_argument(directory + " is not a run directory: it has no manifest.json (a run's folder "
                                  "holds manifest.json and frames/; a run still capturing has only journal.jsonl)");
    throw std::runtime_error("cannot open " + path);
  }
  try {
    return RunManifestFromJson(json::parse(in));
  } catch (const std::exception& e) {
    throw DamagedRunError(path + ": corrupt manifest: " + WithoutJsonLibraryTag(e.what()) +
                          "; the run cannot be read: restore manifest.json from a copy or capture the run again");
  }
}

json CaptureVerdict::ToJson() const {
  return {{"status", CaptureStatusName(status)}, {"reasons", reasons}, {"accepted_failed_capture", accepted_failed_capture}};
}

CaptureVerdict CaptureVerdictOf(const RunManifest& manifest) {
  CaptureVerdict verdict;
  verdict.status = manifest.status;
  // The sequencer joins its findings with "; also " (FrameHealth::Describe).
  const std::string& reason = manifest.stop ? manifest.stop->reason : manifest.status_reason;
  static const std::string kAlso = "; also ";
  for (std::size_t begin = 0; !reason.empty();) {
    const std::size_t end = reason.find(kAlso, begin);
    verdict.reasons.push_back(reason.substr(begin, end == std::string::npos ? std::string::npos : end - begin));
    if (end == std::string::npos) break;
    begin = end + kAlso.size();
  }
  return verdict;
}

CaptureVerdict CheckCaptureForSolve(const std::string& directory, const RunManifest& manifest, FailedCapture failed) {
  CaptureVerdict verdict = CaptureVerdictOf(manifest);
  if (verdict.complete()) return verdict;
  if (failed == FailedCapture::kRefuse) {
    std::string why;
    for (const std::string& reason : verdict.reasons) why += "\n  - " + reason;
    const std::string ended = verdict.status == CaptureStatus::kFailed    ? "failed"
                              : verdict.status == CaptureStatus::kRunning ? "never finished"
                                                                          : std::string("was ") + CaptureStatusName(verdict.status);
    throw FailedCaptureError(fmt::format(
        "{}: the capture {} ({} of {} frames), so nothing solved from it can be trusted:{}\nFix what it names and "
        "capture again; or, to look at it anyway, solve with --accept-failed-capture: every result and report is "
        "then marked as from a failed capture",
        directory, ended, manifest.frames.size(),
        manifest.stop ? manifest.stop->steps_total : static_cast<int>(manifest.frames.size()),
        why.empty() ? " (no reason recorded)" : why));
  }
  verdict.accepted_failed_capture = true;
  return verdict;
}

cv::Mat LoadFrame(const std::string& directory, const FrameRecord& record) {
  // A manifest names its frames inside the run: never an absolute path or one through "..".
  const fs::path named(record.file);
  if (named.empty() || named.is_absolute() || std::any_of(named.begin(), named.end(), [](const fs::path& part) {
        return part == "..";
      }))
    throw DamagedRunError((fs::path(directory) / "manifest.json").string() + ": frame '" + record.file +
                          "' lies outside the run's folder: the manifest is damaged; capture the run again");
  const std::string path = (fs::path(directory) / record.file).string();
  static const std::string kNextStep = ": the run's frame is damaged; restore it from a copy or capture the run again";
  std::string why;
  cv::Mat image = TryReadImage(path, solvers::codecs::ReadMode::kAsStored, &why);
  if (image.empty()) throw DamagedRunError("cannot read image " + path + " (" + why + ")" + kNextStep);
  if (image.depth() != CV_16U || (image.channels() != 1 && image.channels() != 3))
    throw DamagedRunError(path + ": not a 16-bit frame of one or three channels" + kNextStep);
  // RGB frames are stored as RGB PNG; OpenCV reads them as B, G, R.
  if (image.channels() == 3) cv::cvtColor(image, image, cv::COLOR_BGR2RGB);
  if (!image.isContinuous()) image = image.clone();
  if (Crc32(image.data, image.total() * image.elemSize()) != record.crc32)
    throw DamagedRunError(path + ": pixel checksum does not match the manifest (corrupt frame)" + kNextStep);
  return image;
}

std::vector<std::string> VerifyRun(const std::string& directory) {
  std::vector<std::string> problems;
  RunManifest manifest;
  try {
    manifest = LoadRunManifest(directory);
  } catch (const std::exception& e) {
    return {e.what()};
  }
  std::set<int> indices;
  std::set<std::string> files;
  for (const FrameRecord& record : manifest.frames) {
    if (!indices.insert(record.index).second) problems.push_back("step " + std::to_string(record.index) + " stored twice");
    files.insert(fs::path(record.file).filename().string());
    try {
      LoadFrame(directory, record);
    } catch (const std::exception& e) {
      problems.push_back(e.what());
    }
  }
  if (manifest.stop && manifest.stop->status == CaptureStatus::kComplete) {
    // Counted from the frames present, so a damaged steps_total of 2^31 costs no
    // more than a small one; the first few missing steps are named.
    const int steps_total = manifest.stop->steps_total;
    const auto present = std::count_if(indices.begin(), indices.end(), [&](int i) { return i >= 0 && i < steps_total; });
    const std::int64_t missing = std::max<std::int64_t>(0, std::int64_t{steps_total} - present);
    constexpr std::int64_t kNamed = 20;
    std::int64_t named = 0;
    for (int i = 0; i < steps_total && named < std::min(missing, kNamed); ++i)
      if (!indices.count(i)) {
        problems.push_back("step " + std::to_string(i) + " missing");
        ++named;
      }
    if (missing > named) problems.push_back(std::to_string(missing - named) + " more steps missing");
  }
  const fs::path frames_dir = fs::path(directory) / "frames";
  if (fs::exists(frames_dir))
    for (const auto& entry : fs::directory_iterator(frames_dir))
      if (!files.count(entry.path().filename().string()))
        problems.push_back("unlisted file " + entry.path().string());
  return problems;
}

}  // namespace photorig::daemon
