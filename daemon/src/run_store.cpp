#include "photorig/daemon/run_store.h"

#include "photorig/daemon/image_io.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace photorig::daemon {
namespace fs = std::filesystem;
using nlohmann::json;

json ToJson(const FrameRecord& f) {
  return {{"index", f.index},
          {"file", f.file},
          {"kind", f.kind},
          {"led", f.led},
          {"level", f.level},
          {"exposure_us", f.exposure_us},
          {"gain_db", f.gain_db},
          {"bit_depth", f.bit_depth},
          {"frame_id", f.frame_id},
          {"device_timestamp_ns", f.device_timestamp_ns},
          {"host_timestamp_ns", f.host_timestamp_ns},
          {"crc32", f.crc32}};
}

FrameRecord FrameRecordFromJson(const json& j) {
  FrameRecord f;
  f.index = j.at("index").get<int>();
  f.file = j.at("file").get<std::string>();
  f.kind = j.at("kind").get<std::string>();
  f.led = j.at("led").get<int>();
  f.level = j.at("level").get<double>();
  f.exposure_us = j.at("exposure_us").get<double>();
  f.gain_db = j.at("gain_db").get<double>();
  f.bit_depth = j.at("bit_depth").get<int>();
  f.frame_id = j.at("frame_id").get<std::uint64_t>();
  f.device_timestamp_ns = j.at("device_timestamp_ns").get<std::int64_t>();
  f.host_timestamp_ns = j.at("host_timestamp_ns").get<std::int64_t>();
  f.crc32 = j.at("crc32").get<std::uint32_t>();
  return f;
}

json ToJson(const RunManifest& m) {
  json lights = json::array();
  for (const LedConfig& led : m.lights)
    lights.push_back({{"id", led.id},
                      {"direction", {led.direction.x(), led.direction.y(), led.direction.z()}},
                      {"intensity", led.intensity}});
  json frames = json::array();
  for (const FrameRecord& f : m.frames) frames.push_back(ToJson(f));
  return {{"format", m.format},
          {"run_id", m.run_id},
          {"recipe", {{"path", m.recipe_path}, {"name", m.recipe_name}}},
          {"rig", {{"path", m.rig_path}, {"name", m.rig_name}}},
          {"status", m.status},
          {"status_reason", m.status_reason},
          {"sample", m.sample_name},
          {"camera",
           {{"id", m.camera_id},
            {"width", m.width},
            {"height", m.height},
            {"bit_depth", m.bit_depth},
            {"dn_per_radiance_per_us", m.dn_per_radiance_per_us}}},
          {"lights", lights},
          {"frames", frames},
          {"ground_truth", m.has_ground_truth}};
}

RunManifest RunManifestFromJson(const json& j) {
  RunManifest m;
  m.format = j.at("format").get<std::string>();
  if (m.format != "photorig-run/1") throw std::runtime_error("unsupported run format '" + m.format + "'");
  m.run_id = j.at("run_id").get<std::string>();
  m.recipe_path = j.at("recipe").at("path").get<std::string>();
  m.recipe_name = j.at("recipe").at("name").get<std::string>();
  m.rig_path = j.at("rig").at("path").get<std::string>();
  m.rig_name = j.at("rig").at("name").get<std::string>();
  m.status = j.at("status").get<std::string>();
  m.status_reason = j.value("status_reason", "");
  m.sample_name = j.value("sample", "");
  const json& camera = j.at("camera");
  m.camera_id = camera.at("id").get<std::string>();
  m.width = camera.at("width").get<int>();
  m.height = camera.at("height").get<int>();
  m.bit_depth = camera.at("bit_depth").get<int>();
  m.dn_per_radiance_per_us = camera.at("dn_per_radiance_per_us").get<double>();
  for (const json& light : j.at("lights")) {
    LedConfig led;
    led.id = light.at("id").get<int>();
    const auto d = light.at("direction").get<std::vector<double>>();
    if (d.size() != 3) throw std::runtime_error("light direction needs 3 components");
    led.direction = Eigen::Vector3d(d[0], d[1], d[2]);
    led.intensity = light.at("intensity").get<double>();
    m.lights.push_back(led);
  }
  for (const json& frame : j.at("frames")) m.frames.push_back(FrameRecordFromJson(frame));
  m.has_ground_truth = j.value("ground_truth", false);
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
  const std::string line = json{{"run", header_line}}.dump() + "\n";
  if (::write(journal_fd_, line.data(), line.size()) != static_cast<ssize_t>(line.size()) || ::fsync(journal_fd_) != 0)
    throw std::runtime_error("cannot write " + journal + ": " + std::strerror(errno));
}

RunWriter::~RunWriter() {
  if (journal_fd_ >= 0) ::close(journal_fd_);
}

const FrameRecord& RunWriter::WriteFrame(const CaptureStep& step, const drivers::Frame& frame) {
  if (frame.width <= 0 || frame.height <= 0 ||
      frame.pixels.size() != static_cast<std::size_t>(frame.width) * frame.height)
    throw std::runtime_error("frame " + std::to_string(frame.frame_id) + " for step " + step.label +
                             " is short: " + std::to_string(frame.pixels.size()) + " samples for " +
                             std::to_string(frame.width) + "x" + std::to_string(frame.height));
  FrameRecord record;
  record.index = step.index;
  record.file = "frames/" + step.label + ".png";
  record.kind = step.kind == CaptureStep::Kind::kDark ? "dark" : "light";
  record.led = step.led;
  record.level = step.led >= 0 ? step.pattern.levels.at(step.led) : 0.0;
  record.exposure_us = frame.exposure_us;
  record.gain_db = frame.gain_db;
  record.bit_depth = frame.bit_depth;
  record.frame_id = frame.frame_id;
  record.device_timestamp_ns = frame.device_timestamp_ns;
  record.host_timestamp_ns = frame.host_timestamp_ns;
  record.crc32 = Crc32(frame.pixels.data(), frame.pixels.size() * sizeof(std::uint16_t));
  const cv::Mat image(frame.height, frame.width, CV_16U, const_cast<std::uint16_t*>(frame.pixels.data()));
  WriteImage((fs::path(directory_) / record.file).string(), image);
  const std::string line = ToJson(record).dump() + "\n";
  if (::write(journal_fd_, line.data(), line.size()) != static_cast<ssize_t>(line.size()) || ::fsync(journal_fd_) != 0)
    throw std::runtime_error("cannot append to the journal of " + directory_ + ": " + std::strerror(errno));
  manifest_.frames.push_back(record);
  return manifest_.frames.back();
}

void RunWriter::WriteGroundTruth(const cv::Mat& normals, const cv::Mat& albedo, const cv::Mat& mask) {
  const fs::path truth = fs::path(directory_) / "ground_truth";
  fs::create_directories(truth);
  WriteFloatTiff((truth / "normals.tiff").string(), normals);
  WriteFloatTiff((truth / "albedo.tiff").string(), albedo);
  WriteImage((truth / "mask.png").string(), mask);
  manifest_.has_ground_truth = true;
}

void RunWriter::Finish(const std::string& status, const std::string& reason) {
  manifest_.status = status;
  manifest_.status_reason = reason;
  WriteFileDurably((fs::path(directory_) / "manifest.json").string(), ToJson(manifest_).dump(2) + "\n");
}

RunManifest LoadRunManifest(const std::string& directory) {
  const std::string path = (fs::path(directory) / "manifest.json").string();
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open " + path + " (is " + directory + " a run directory?)");
  try {
    return RunManifestFromJson(json::parse(in));
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": corrupt manifest: " + e.what());
  }
}

cv::Mat LoadFrame(const std::string& directory, const FrameRecord& record) {
  const std::string path = (fs::path(directory) / record.file).string();
  cv::Mat image = ReadImage(path);
  if (image.type() != CV_16U) throw std::runtime_error(path + ": expected a 16-bit single-channel frame");
  if (!image.isContinuous()) image = image.clone();
  if (Crc32(image.data, image.total() * image.elemSize()) != record.crc32)
    throw std::runtime_error(path + ": pixel checksum does not match the manifest (corrupt frame)");
  return image;
}

}  // namespace photorig::daemon
