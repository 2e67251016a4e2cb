#include "photorig/drivers/aravis/aravis_camera.h"

#include <arv.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstring>
#include <thread>

namespace photorig::drivers {
namespace {

// GigE Vision bootstrap register "Control Channel Privilege" (GigE Vision 2.0,
// table 28): bit 1 = control, bit 0 = exclusive. A camera that rebooted or
// gave control to another host reads 0 here.
constexpr guint64 kGvbsControlChannelPrivilege = 0x0a00;
constexpr guint32 kPrivilegeControlMask = 0x3;

// Owns a GError and turns it into text.
class GErrorBox {
 public:
  ~GErrorBox() { Clear(); }
  GError** out() {
    Clear();
    return &error_;
  }
  explicit operator bool() const { return error_ != nullptr; }
  std::string message() const { return error_ ? error_->message : ""; }
  void Clear() {
    if (error_) g_error_free(error_);
    error_ = nullptr;
  }

 private:
  GError* error_ = nullptr;
};

// A counted string array from Aravis (the array is ours to free, the strings are not).
std::vector<std::string> TakeStrings(const char** strings, guint n) {
  std::vector<std::string> out;
  if (!strings) return out;
  for (guint i = 0; i < n; ++i) out.emplace_back(strings[i]);
  g_free(strings);
  return out;
}

std::string Join(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& item : items) out += (out.empty() ? "" : ", ") + item;
  return out;
}

// Unpacked Mono/Bayer formats only: each sample is one byte (8 bits) or one
// little-endian 16-bit word holding `bits` significant bits. 0 = unsupported.
int FormatBits(const std::string& name) {
  if (name.rfind("Mono", 0) != 0 && name.rfind("Bayer", 0) != 0) return 0;
  if (name.find("Packed") != std::string::npos || name.back() == 'p') return 0;
  std::size_t digits = name.size();
  while (digits > 0 && std::isdigit(static_cast<unsigned char>(name[digits - 1]))) --digits;
  if (digits == name.size()) return 0;
  const int bits = std::stoi(name.substr(digits));
  return (bits == 8 || bits == 10 || bits == 12 || bits == 14 || bits == 16) ? bits : 0;
}

const char* BufferStatusName(ArvBufferStatus status) {
  switch (status) {
    case ARV_BUFFER_STATUS_SUCCESS: return "success";
    case ARV_BUFFER_STATUS_CLEARED: return "cleared";
    case ARV_BUFFER_STATUS_TIMEOUT: return "timeout (packets never arrived)";
    case ARV_BUFFER_STATUS_MISSING_PACKETS: return "missing packets";
    case ARV_BUFFER_STATUS_WRONG_PACKET_ID: return "wrong packet id";
    case ARV_BUFFER_STATUS_SIZE_MISMATCH: return "size mismatch";
    case ARV_BUFFER_STATUS_FILLING: return "still filling";
    case ARV_BUFFER_STATUS_ABORTED: return "aborted";
    default: return "unknown status";
  }
}

std::int64_t RealtimeNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

void OnControlLost(ArvDevice*, gpointer flag) { static_cast<std::atomic<bool>*>(flag)->store(true); }

struct DeviceEntry {
  std::string id, vendor, model, serial, address, physical_id;
};

std::vector<DeviceEntry> ListDevices() {
  arv_update_device_list();
  std::vector<DeviceEntry> devices;
  const unsigned n = arv_get_n_devices();
  auto text = [](const char* s) { return std::string(s ? s : ""); };
  for (unsigned i = 0; i < n; ++i)
    devices.push_back({text(arv_get_device_id(i)), text(arv_get_device_vendor(i)), text(arv_get_device_model(i)),
                       text(arv_get_device_serial_nbr(i)), text(arv_get_device_address(i)),
                       text(arv_get_device_physical_id(i))});
  return devices;
}

// Aravis opens by id only; labs name cameras by serial number or address too.
Result<std::string> ResolveDevice(const std::string& selector) {
  const std::vector<DeviceEntry> devices = ListDevices();
  std::vector<std::string> ids;
  for (const auto& d : devices) {
    ids.push_back(d.id);
    if (!selector.empty() &&
        (d.id == selector || d.serial == selector || d.address == selector || d.physical_id == selector))
      return d.id;
  }
  if (selector.empty() && devices.size() == 1) return devices.front().id;
  if (selector.empty() && devices.size() > 1)
    return Status{StatusCode::kInvalidArgument,
                  "several GenICam cameras found (" + Join(ids) + "); name one with options.device"};
  return Status{StatusCode::kUnavailable, selector.empty() ? std::string("no GenICam camera found")
                                                           : "no GenICam camera with id, serial or address '" +
                                                                 selector + "' (found: " +
                                                                 (ids.empty() ? "none" : Join(ids)) + ")"};
}

}  // namespace

struct AravisCamera::Handles {
  ArvCamera* camera = nullptr;
  ArvStream* stream = nullptr;
  bool is_gv = false;
};

bool AravisCameraOptions::IsValid(std::string* why) const {
  if (buffer_count < 1 || buffer_count > 64) return Refuse(why, "buffer_count must be in [1, 64]");
  if (!(link_bandwidth_mbps > 0)) return Refuse(why, "link_bandwidth_mbps must be > 0");
  if (timeout_margin_ms < 0) return Refuse(why, "timeout_margin_ms must be >= 0");
  if (reconnect_attempts < 0) return Refuse(why, "reconnect_attempts must be >= 0");
  if (reconnect_delay_ms < 0) return Refuse(why, "reconnect_delay_ms must be >= 0");
  return true;
}

AravisCamera::AravisCamera(std::string id, AravisCameraOptions options)
    : Camera(std::move(id)),
      options_(std::move(options)),
      handles_(std::make_unique<Handles>()),
      control_lost_(std::make_shared<std::atomic<bool>>(false)) {}

AravisCamera::~AravisCamera() {
  (void)Close();
  for (std::thread& release : graveyard_) release.join();
}

Status AravisCamera::Error(StatusCode code, const std::string& what) const {
  return {code, "camera " + id() + (device_id_.empty() ? "" : " (" + device_id_ + ")") + ": " + what};
}

int AravisCamera::FrameTimeoutMs() const {
  const double readout_ms = static_cast<double>(payload_bytes_) * 8.0 / (options_.link_bandwidth_mbps * 1e3);
  return static_cast<int>(std::ceil(applied_.exposure_us / 1000.0 + readout_ms)) + options_.timeout_margin_ms;
}

Status AravisCamera::Connect() {
  auto resolved = ResolveDevice(options_.device);
  if (!resolved.ok()) return Error(resolved.status().code(), resolved.status().message());
  GErrorBox error;
  ArvCamera* camera = arv_camera_new(resolved.value().c_str(), error.out());
  if (!camera) return Error(StatusCode::kUnavailable, "cannot open " + resolved.value() + ": " + error.message());
  handles_->camera = camera;
  handles_->is_gv = arv_camera_is_gv_device(camera);
  device_id_ = resolved.value();
  control_lost_->store(false);
  g_signal_connect(arv_camera_get_device(camera), "control-lost", G_CALLBACK(OnControlLost), control_lost_.get());
  return Status::Ok();
}

void AravisCamera::Disconnect() {
  StopStream();
  if (handles_->camera) g_object_unref(handles_->camera);
  handles_->camera = nullptr;
}

void AravisCamera::Abandon() {
  // Releasing a GigE Vision device that no longer answers waits out its
  // control-channel retries (seconds); do it off the capture path.
  if (handles_->stream) g_object_unref(handles_->stream);
  handles_->stream = nullptr;
  if (ArvCamera* camera = handles_->camera) graveyard_.emplace_back([camera] { g_object_unref(camera); });
  handles_->camera = nullptr;
}

Status AravisCamera::DoOpen() {
  std::string why;
  if (!options_.IsValid(&why)) return Error(StatusCode::kInvalidArgument, why);
  configured_ = false;
  stats_ = {};
  return Connect();
}

Result<std::vector<SettingAdjustment>> AravisCamera::DoConfigure(CameraSettings* s) {
  ArvCamera* camera = handles_->camera;
  std::vector<SettingAdjustment> adjustments;
  GErrorBox error;
  auto adjust = [&adjustments](const char* field, double requested, double applied, std::string reason) {
    if (std::abs(requested - applied) > 1e-9 * std::max(1.0, std::abs(requested)))
      adjustments.push_back({field, requested, applied, std::move(reason)});
  };
  auto failed = [&](const std::string& what) -> Status {
    return Error(StatusCode::kInvalidArgument, what + ": " + error.message());
  };

  // Geometry: a region at the sensor origin.
  gint sensor_width = 0, sensor_height = 0;
  arv_camera_get_sensor_size(camera, &sensor_width, &sensor_height, error.out());
  if (error) return failed("reading the sensor size");
  if (s->width == 0) s->width = sensor_width;
  if (s->height == 0) s->height = sensor_height;
  if (s->width < 0 || s->height < 0 || s->width > sensor_width || s->height > sensor_height)
    return Error(StatusCode::kInvalidArgument, "region " + std::to_string(s->width) + "x" + std::to_string(s->height) +
                                                   " does not fit the " + std::to_string(sensor_width) + "x" +
                                                   std::to_string(sensor_height) + " sensor");
  arv_camera_set_region(camera, 0, 0, s->width, s->height, error.out());
  if (error) return failed("setting the region");
  gint x = 0, y = 0, width = 0, height = 0;
  arv_camera_get_region(camera, &x, &y, &width, &height, error.out());
  if (error) return failed("reading the region back");
  adjust("width", s->width, width, "rounded to the camera's width step");
  adjust("height", s->height, height, "rounded to the camera's height step");
  s->width = width;
  s->height = height;

  // Pixel format: the named one, or MonoN for the bit depth, else the
  // narrowest unpacked Mono format that holds the requested bits.
  guint n_formats = 0;
  const char** formats = arv_camera_dup_available_pixel_formats_as_strings(camera, &n_formats, error.out());
  const std::vector<std::string> offered = TakeStrings(formats, n_formats);
  if (error) return failed("listing pixel formats");
  const std::string requested_format = s->pixel_format.empty() ? "Mono" + std::to_string(s->bit_depth) : s->pixel_format;
  const int requested_bits = FormatBits(requested_format);
  if (requested_bits == 0)
    return Error(StatusCode::kInvalidArgument, "pixel format '" + requested_format +
                                                   "' is not supported (unpacked Mono8/10/12/14/16 or Bayer*8/10/12/16)");
  std::string format;
  if (std::find(offered.begin(), offered.end(), requested_format) != offered.end()) {
    format = requested_format;
  } else if (requested_format.rfind("Mono", 0) == 0) {
    int best_bits = 0;
    for (const auto& candidate : offered) {
      const int bits = FormatBits(candidate);
      if (candidate.rfind("Mono", 0) != 0 || bits < requested_bits) continue;
      if (best_bits == 0 || bits < best_bits) {
        best_bits = bits;
        format = candidate;
      }
    }
  }
  if (format.empty())
    return Error(StatusCode::kInvalidArgument,
                 "pixel format " + requested_format + " is not offered (camera offers " + Join(offered) + ")");
  arv_camera_set_pixel_format_from_string(camera, format.c_str(), error.out());
  if (error) return failed("setting pixel format " + format);
  adjust("bit_depth", s->bit_depth, FormatBits(format), requested_format + " not offered; using " + format);
  s->pixel_format = format;
  s->bit_depth = FormatBits(format);

  // Exposure, in microseconds whatever the feature is called.
  if (arv_camera_is_exposure_auto_available(camera, nullptr)) arv_camera_set_exposure_time_auto(camera, ARV_AUTO_OFF, nullptr);
  double exposure_min = 0, exposure_max = 0;
  arv_camera_get_exposure_time_bounds(camera, &exposure_min, &exposure_max, error.out());
  if (error) return failed("reading the exposure range");
  const char* exposure_feature =
      arv_camera_is_feature_available(camera, "ExposureTime", nullptr) ? "ExposureTime" : "ExposureTimeAbs";
  double step = arv_camera_get_float_increment(camera, exposure_feature, nullptr);
  double exposure = std::clamp(s->exposure_us, exposure_min, exposure_max);
  if (step > 1e-9) exposure = std::clamp(std::round(exposure / step) * step, exposure_min, exposure_max);
  arv_camera_set_exposure_time(camera, exposure, error.out());
  if (error) return failed("setting the exposure");
  const double exposure_applied = arv_camera_get_exposure_time(camera, error.out());
  if (error) return failed("reading the exposure back");
  char range[96];
  std::snprintf(range, sizeof(range), "camera step and range [%g, %g] us", exposure_min, exposure_max);
  adjust("exposure_us", s->exposure_us, exposure_applied, range);
  s->exposure_us = exposure_applied;

  // Gain: the camera's Gain (dB) or GainRaw feature.
  if (arv_camera_is_gain_available(camera, nullptr)) {
    if (arv_camera_is_gain_auto_available(camera, nullptr)) arv_camera_set_gain_auto(camera, ARV_AUTO_OFF, nullptr);
    double gain_min = 0, gain_max = 0;
    arv_camera_get_gain_bounds(camera, &gain_min, &gain_max, error.out());
    if (error) return failed("reading the gain range");
    arv_camera_set_gain(camera, std::clamp(s->gain_db, gain_min, gain_max), error.out());
    if (error) return failed("setting the gain");
    const double gain_applied = arv_camera_get_gain(camera, error.out());
    if (error) return failed("reading the gain back");
    std::snprintf(range, sizeof(range), "camera step and range [%g, %g]", gain_min, gain_max);
    adjust("gain_db", s->gain_db, gain_applied, range);
    s->gain_db = gain_applied;
  } else {
    adjust("gain_db", s->gain_db, 0.0, "camera has no gain control");
    s->gain_db = 0.0;
  }

  // Trigger.
  arv_camera_set_acquisition_mode(camera, ARV_ACQUISITION_MODE_CONTINUOUS, error.out());
  if (error) return failed("setting continuous acquisition");
  if (s->trigger == TriggerMode::kFreeRun) {
    arv_camera_clear_triggers(camera, error.out());
    if (error) return failed("clearing triggers");
  } else {
    const std::string source = s->trigger == TriggerMode::kSoftware ? "Software" : s->trigger_line;
    if (source.empty()) return Error(StatusCode::kInvalidArgument, "hardware trigger needs trigger_line (e.g. Line1)");
    guint n_sources = 0;
    const char** names = arv_camera_dup_available_trigger_sources(camera, &n_sources, nullptr);
    const std::vector<std::string> sources = TakeStrings(names, n_sources);
    if (std::find(sources.begin(), sources.end(), source) == sources.end())
      return Error(StatusCode::kInvalidArgument,
                   "trigger source " + source + " is not offered (camera offers " + Join(sources) + ")");
    arv_camera_set_trigger(camera, source.c_str(), error.out());
    if (error) return failed("arming trigger source " + source);
  }

  payload_bytes_ = arv_camera_get_payload(camera, error.out());
  if (error) return failed("reading the payload size");
  applied_ = *s;
  configured_ = true;
  return adjustments;
}

Status AravisCamera::StartStream() {
  GErrorBox error;
  if (handles_->is_gv)
    arv_camera_gv_set_stream_options(handles_->camera, options_.packet_socket
                                                           ? ARV_GV_STREAM_OPTION_NONE
                                                           : ARV_GV_STREAM_OPTION_PACKET_SOCKET_DISABLED);
  ArvStream* stream = arv_camera_create_stream(handles_->camera, nullptr, nullptr, error.out());
  if (!stream) return Error(StatusCode::kUnavailable, "cannot create the stream: " + error.message());
  if (ARV_IS_GV_STREAM(stream)) {
    g_object_set(stream, "packet-resend",
                 options_.packet_resend ? ARV_GV_STREAM_PACKET_RESEND_ALWAYS : ARV_GV_STREAM_PACKET_RESEND_NEVER,
                 nullptr);
    // A camera sends a frame as one burst, faster than the stream's thread may
    // drain the socket: the kernel's default receive buffer (208 KiB) drops the
    // tail of a larger frame. Room for the pool's frames, at least 1 MiB (the
    // kernel caps it at net.core.rmem_max).
    const guint64 buffer_bytes = std::max<guint64>(1u << 20, payload_bytes_ * std::max(options_.buffer_count, 1));
    g_object_set(stream, "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_FIXED, "socket-buffer-size",
                 static_cast<gint>(std::min<guint64>(buffer_bytes, G_MAXINT)), nullptr);
  }
  for (int i = 0; i < options_.buffer_count; ++i) arv_stream_push_buffer(stream, arv_buffer_new_allocate(payload_bytes_));
  handles_->stream = stream;
  arv_camera_start_acquisition(handles_->camera, error.out());
  if (error) {
    StopStream();
    return Error(StatusCode::kUnavailable, "cannot start acquisition: " + error.message());
  }
  have_last_frame_id_ = false;
  return Status::Ok();
}

void AravisCamera::StopStream() {
  if (!handles_->stream) return;
  if (handles_->camera) arv_camera_stop_acquisition(handles_->camera, nullptr);
  g_object_unref(handles_->stream);
  handles_->stream = nullptr;
}

Status AravisCamera::DoStart() {
  trigger_pending_ = false;
  Status status = StartStream();
  streaming_ = status.ok();
  return status;
}

bool AravisCamera::LinkLost() {
  if (control_lost_->load()) return true;
  if (!handles_->camera) return true;
  if (!handles_->is_gv) return false;
  guint32 privilege = 0;
  if (!arv_device_read_register(arv_camera_get_device(handles_->camera), kGvbsControlChannelPrivilege, &privilege,
                                nullptr))
    return true;
  return (privilege & kPrivilegeControlMask) == 0;
}

Status AravisCamera::Reconnect() {
  Status last = Error(StatusCode::kUnavailable, "control link lost");
  Abandon();
  for (int attempt = 1; attempt <= options_.reconnect_attempts; ++attempt) {
    Disconnect();
    std::this_thread::sleep_for(std::chrono::milliseconds(options_.reconnect_delay_ms));
    last = Connect();
    if (!last.ok()) continue;
    CameraSettings settings = applied_;
    auto configured = DoConfigure(&settings);
    if (!configured.ok()) {
      last = configured.status();
      continue;
    }
    if (streaming_) {
      last = StartStream();
      if (!last.ok()) continue;
      if (trigger_pending_) {
        GErrorBox error;
        arv_camera_software_trigger(handles_->camera, error.out());
        if (error) {
          last = Error(StatusCode::kUnavailable, "software trigger after reconnect: " + error.message());
          continue;
        }
      }
    }
    ++stats_.reconnects;
    return Status::Ok();
  }
  return Error(StatusCode::kUnavailable, "control link lost; gave up after " +
                                             std::to_string(options_.reconnect_attempts) +
                                             " reconnect attempts (last: " + last.message() + ")");
}

Status AravisCamera::DoTrigger() {
  if (control_lost_->load()) {
    Status status = Reconnect();
    if (!status.ok()) return status;
  }
  GErrorBox error;
  arv_camera_software_trigger(handles_->camera, error.out());
  if (error) {
    // A command the device does not acknowledge means the control channel is gone.
    trigger_pending_ = true;  // Reconnect re-issues it
    return Reconnect();
  }
  trigger_pending_ = true;
  return Status::Ok();
}

Result<Frame> AravisCamera::DoWaitFrame(int timeout_ms) {
  // No frame can arrive before the exposure and its readout are over.
  const int wait_ms = std::max(timeout_ms, FrameTimeoutMs() - options_.timeout_margin_ms);
  auto frame = PopFrame(wait_ms);
  if (frame.ok() || frame.status().code() != StatusCode::kTimeout || !LinkLost()) return frame;
  Status reconnected = Reconnect();
  if (!reconnected.ok()) return reconnected;
  return PopFrame(wait_ms);
}

Result<Frame> AravisCamera::PopFrame(int timeout_ms) {
  ArvStream* stream = handles_->stream;
  if (!stream) return Error(StatusCode::kUnavailable, "no stream");
  ArvBuffer* buffer = arv_stream_timeout_pop_buffer(stream, static_cast<guint64>(timeout_ms) * 1000);
  if (!buffer) {
    ++stats_.timeouts;
    return Error(StatusCode::kTimeout, "no frame within " + std::to_string(timeout_ms) + " ms" +
                                           (applied_.trigger == TriggerMode::kHardware
                                                ? " (no pulse on " + applied_.trigger_line + "?)"
                                                : trigger_pending_ ? "" : " (was it triggered?)"));
  }
  // Hands the buffer back to the pool on every path.
  struct Requeue {
    ArvStream* stream;
    ArvBuffer* buffer;
    ~Requeue() { arv_stream_push_buffer(stream, buffer); }
  } requeue{stream, buffer};
  trigger_pending_ = false;

  const std::uint64_t frame_id = arv_buffer_get_frame_id(buffer);
  std::uint64_t dropped = 0;
  if (have_last_frame_id_) {
    if (handles_->is_gv && frame_id <= 0xffff && last_frame_id_ <= 0xffff) {
      // GigE Vision 1.x block ids: 16 bits, wrapping from 65535 to 1 (0 is never used).
      const std::uint64_t step = (frame_id + 65535 - last_frame_id_) % 65535;
      dropped = step > 0 ? step - 1 : 0;
    } else if (frame_id > last_frame_id_) {
      dropped = frame_id - last_frame_id_ - 1;
    }
  }
  have_last_frame_id_ = true;
  last_frame_id_ = frame_id;
  stats_.dropped += dropped;

  const ArvBufferStatus status = arv_buffer_get_status(buffer);
  if (status != ARV_BUFFER_STATUS_SUCCESS) {
    ++stats_.incomplete;
    return Error(StatusCode::kDataLoss, "frame " + std::to_string(frame_id) + " incomplete: " + BufferStatusName(status));
  }
  size_t size = 0;
  const auto* data = static_cast<const std::uint8_t*>(arv_buffer_get_image_data(buffer, &size));
  const int width = arv_buffer_get_image_width(buffer);
  const int height = arv_buffer_get_image_height(buffer);
  const int bits_per_pixel = ARV_PIXEL_FORMAT_BIT_PER_PIXEL(arv_buffer_get_image_pixel_format(buffer));
  if (bits_per_pixel != 8 && bits_per_pixel != 16)
    return Error(StatusCode::kDataLoss, "frame " + std::to_string(frame_id) + " has " +
                                            std::to_string(bits_per_pixel) + " bits per pixel (expected 8 or 16)");
  const std::size_t count = static_cast<std::size_t>(width) * height;
  if (!data || size < count * (bits_per_pixel / 8)) {
    ++stats_.incomplete;
    return Error(StatusCode::kDataLoss, "frame " + std::to_string(frame_id) + " is short (" + std::to_string(size) +
                                            " bytes for " + std::to_string(width) + "x" + std::to_string(height) + ")");
  }

  Frame frame = FrameTakenWith(applied_, width, height);
  frame.frame_id = frame_id;
  frame.dropped_before = dropped;
  frame.device_timestamp_ns = static_cast<std::int64_t>(arv_buffer_get_timestamp(buffer));
  frame.host_timestamp_ns = RealtimeNs();
  frame.pixels.resize(count);
  if (bits_per_pixel == 8) {
    std::copy(data, data + count, frame.pixels.begin());
  } else {
    std::memcpy(frame.pixels.data(), data, count * 2);  // GenICam 16-bit samples are little-endian, as is the host
  }
  ++stats_.frames;
  return frame;
}

Status AravisCamera::DoStop() {
  StopStream();
  streaming_ = false;
  trigger_pending_ = false;
  return Status::Ok();
}

Status AravisCamera::DoClose() {
  Disconnect();
  streaming_ = false;
  configured_ = false;
  device_id_.clear();
  return Status::Ok();
}

std::vector<CameraInfo> DiscoverAravisCameras(bool details) {
  std::vector<CameraInfo> cameras;
  for (const DeviceEntry& d : ListDevices()) {
    CameraInfo info;
    info.driver = "aravis";
    info.id = d.id;
    info.vendor = d.vendor;
    info.model = d.model;
    info.serial = d.serial;
    info.address = d.address;
    if (details) {
      GErrorBox error;
      ArvCamera* camera = arv_camera_new(d.id.c_str(), error.out());
      if (!camera) {
        info.error = "cannot open: " + error.message();
      } else {
        arv_camera_get_sensor_size(camera, &info.sensor_width, &info.sensor_height, nullptr);
        guint n = 0;
        const char** formats = arv_camera_dup_available_pixel_formats_as_strings(camera, &n, nullptr);
        info.pixel_formats = TakeStrings(formats, n);
        arv_camera_get_exposure_time_bounds(camera, &info.exposure_min_us, &info.exposure_max_us, nullptr);
        g_object_unref(camera);
      }
    }
    cameras.push_back(std::move(info));
  }
  return cameras;
}

}  // namespace photorig::drivers
