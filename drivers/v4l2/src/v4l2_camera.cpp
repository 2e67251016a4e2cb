#include "photorig/drivers/v4l2/v4l2_camera.h"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>

namespace photorig::drivers {
namespace {

int Ioctl(int fd, unsigned long request, void* arg) {
  int result;
  do {
    result = ioctl(fd, request, arg);
  } while (result == -1 && errno == EINTR);
  return result;
}

std::int64_t MonotonicNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::int64_t RealtimeNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// Single-plane monochrome formats, YUYV (whose luma is used) and unpacked
// Bayer raws (one sample per pixel, stored as the mosaic; asked for by name
// only, never chosen for a bit depth, since they make the camera a colour one).
struct Format {
  std::uint32_t fourcc;
  const char* v4l2_name;
  const char* genicam_name;
  int bits;  // significant bits delivered per sample
  bool bayer = false;
};
constexpr Format kFormats[] = {
    {V4L2_PIX_FMT_GREY, "GREY", "Mono8", 8},   {V4L2_PIX_FMT_Y10, "Y10", "Mono10", 10},
    {V4L2_PIX_FMT_Y12, "Y12", "Mono12", 12},   {V4L2_PIX_FMT_Y16, "Y16", "Mono16", 16},
    {V4L2_PIX_FMT_YUYV, "YUYV", "YUV422_8", 8},
    {V4L2_PIX_FMT_SRGGB8, "RGGB", "BayerRG8", 8, true},     {V4L2_PIX_FMT_SGRBG8, "GRBG", "BayerGR8", 8, true},
    {V4L2_PIX_FMT_SGBRG8, "GBRG", "BayerGB8", 8, true},     {V4L2_PIX_FMT_SBGGR8, "BA81", "BayerBG8", 8, true},
    {V4L2_PIX_FMT_SRGGB12, "RG12", "BayerRG12", 12, true},  {V4L2_PIX_FMT_SGRBG12, "BA12", "BayerGR12", 12, true},
    {V4L2_PIX_FMT_SGBRG12, "GB12", "BayerGB12", 12, true},  {V4L2_PIX_FMT_SBGGR12, "BG12", "BayerBG12", 12, true},
    {V4L2_PIX_FMT_SRGGB16, "RG16", "BayerRG16", 16, true},  {V4L2_PIX_FMT_SGRBG16, "GR16", "BayerGR16", 16, true},
    {V4L2_PIX_FMT_SGBRG16, "GB16", "BayerGB16", 16, true},  {V4L2_PIX_FMT_SBGGR16, "BYR2", "BayerBG16", 16, true},
};

const Format* FindFormat(std::uint32_t fourcc) {
  for (const Format& f : kFormats)
    if (f.fourcc == fourcc) return &f;
  return nullptr;
}

const Format* FindFormat(const std::string& name) {
  for (const Format& f : kFormats)
    if (name == f.v4l2_name || name == f.genicam_name) return &f;
  return nullptr;
}

// "GREY", "Y10"; big-endian variants carry bit 31 ("Y16-BE"), so names stay
// printable ASCII (they end up in JSON).
std::string FourccName(std::uint32_t fourcc) {
  std::string name;
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((fourcc >> (8 * i)) & 0x7f);
    if (c != ' ') name += (c >= 0x21 && c <= 0x7e) ? c : '?';
  }
  if (fourcc & (1u << 31)) name += "-BE";
  return name;
}

std::vector<std::uint32_t> OfferedFormats(int fd) {
  std::vector<std::uint32_t> formats;
  for (std::uint32_t index = 0;; ++index) {
    v4l2_fmtdesc desc{};
    desc.index = index;
    desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (Ioctl(fd, VIDIOC_ENUM_FMT, &desc) != 0) break;
    formats.push_back(desc.pixelformat);
  }
  return formats;
}

std::string Join(const std::vector<std::uint32_t>& formats) {
  std::string out;
  for (std::uint32_t f : formats) out += (out.empty() ? "" : ", ") + FourccName(f);
  return out;
}

// A control's range, or nullopt-like `present = false`.
struct Control {
  bool present = false;
  v4l2_queryctrl query{};
};

Control QueryControl(int fd, std::uint32_t id) {
  Control control;
  control.query.id = id;
  control.present =
      Ioctl(fd, VIDIOC_QUERYCTRL, &control.query) == 0 && !(control.query.flags & V4L2_CTRL_FLAG_DISABLED);
  return control;
}

bool SetControl(int fd, std::uint32_t id, std::int32_t value) {
  v4l2_control control{id, value};
  return Ioctl(fd, VIDIOC_S_CTRL, &control) == 0;
}

bool GetControl(int fd, std::uint32_t id, std::int32_t* value) {
  v4l2_control control{id, 0};
  if (Ioctl(fd, VIDIOC_G_CTRL, &control) != 0) return false;
  *value = control.value;
  return true;
}

std::int32_t Quantise(const v4l2_queryctrl& q, double value) {
  const double step = std::max(1, q.step);
  const double snapped = q.minimum + std::round((value - q.minimum) / step) * step;
  return static_cast<std::int32_t>(std::clamp(snapped, double(q.minimum), double(q.maximum)));
}

bool IsCaptureDevice(const v4l2_capability& caps) {
  const std::uint32_t c = (caps.capabilities & V4L2_CAP_DEVICE_CAPS) ? caps.device_caps : caps.capabilities;
  return (c & V4L2_CAP_VIDEO_CAPTURE) && (c & V4L2_CAP_STREAMING);
}

}  // namespace

bool V4l2CameraOptions::IsValid(std::string* why) const {
  if (device.empty()) return Refuse(why, "device is empty (e.g. /dev/video0)");
  if (buffer_count < 2 || buffer_count > 32) return Refuse(why, "buffer_count must be in [2, 32]");
  return true;
}

V4l2Camera::V4l2Camera(std::string id, V4l2CameraOptions options) : Camera(std::move(id)), options_(std::move(options)) {}

V4l2Camera::~V4l2Camera() { (void)Close(); }

Status V4l2Camera::Fail(StatusCode code, const std::string& what) const {
  return {code, "camera " + id() + " (" + options_.device + "): " + what};
}

Status V4l2Camera::Errno(StatusCode code, const std::string& what) const {
  return Fail(code, what + ": " + std::strerror(errno));
}

Status V4l2Camera::DoOpen() {
  std::string why;
  if (!options_.IsValid(&why)) return Fail(StatusCode::kInvalidArgument, why);
  fd_ = open(options_.device.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) return Errno(StatusCode::kUnavailable, "cannot open");
  v4l2_capability caps{};
  if (Ioctl(fd_, VIDIOC_QUERYCAP, &caps) != 0) {
    Status status = Errno(StatusCode::kUnavailable, "VIDIOC_QUERYCAP (not a V4L2 device?)");
    (void)DoClose();
    return status;
  }
  driver_name_ = reinterpret_cast<const char*>(caps.driver);
  card_ = reinterpret_cast<const char*>(caps.card);
  if (!IsCaptureDevice(caps)) {
    (void)DoClose();
    return Fail(StatusCode::kInvalidArgument, "not a streaming video capture device (" + driver_name_ + ")");
  }
  stats_ = {};
  return Status::Ok();
}

Result<std::vector<SettingAdjustment>> V4l2Camera::DoConfigure(CameraSettings* s) {
  std::vector<SettingAdjustment> adjustments;
  auto adjust = [&adjustments](const char* field, double requested, double applied, std::string reason) {
    if (std::abs(requested - applied) > 1e-9 * std::max(1.0, std::abs(requested)))
      adjustments.push_back({field, requested, applied, std::move(reason)});
  };
  if (s->trigger == TriggerMode::kHardware)
    return Fail(StatusCode::kInvalidArgument, "V4L2 devices have no hardware trigger input");

  // Format: named, or by bit depth; else the narrowest offered monochrome
  // format that holds the bits, else the widest, else YUYV luma.
  const std::vector<std::uint32_t> offered = OfferedFormats(fd_);
  auto is_offered = [&offered](const Format* f) {
    return f && std::find(offered.begin(), offered.end(), f->fourcc) != offered.end();
  };
  const std::string requested_name = s->pixel_format.empty() ? "Mono" + std::to_string(s->bit_depth) : s->pixel_format;
  const Format* requested = FindFormat(requested_name);
  if (!requested && !s->pixel_format.empty())
    return Fail(StatusCode::kInvalidArgument,
                "pixel format " + s->pixel_format +
                    " is not supported (GREY/Mono8, Y10, Y12, Y16/Mono16, YUYV, Bayer{RG,GR,GB,BG}{8,12,16})");
  const int wanted_bits = requested ? requested->bits : s->bit_depth;
  const Format* chosen = is_offered(requested) ? requested : nullptr;
  if (!chosen && s->pixel_format.empty()) {
    for (const Format& f : kFormats) {
      if (f.fourcc == V4L2_PIX_FMT_YUYV || f.bayer || !is_offered(&f)) continue;
      const bool holds = f.bits >= wanted_bits;
      if (!chosen || (holds && (chosen->bits < wanted_bits || f.bits < chosen->bits)) ||
          (!holds && chosen->bits < wanted_bits && f.bits > chosen->bits))
        chosen = &f;
    }
    if (!chosen && is_offered(FindFormat(V4L2_PIX_FMT_YUYV))) chosen = FindFormat(V4L2_PIX_FMT_YUYV);
  }
  if (!chosen)
    return Fail(StatusCode::kInvalidArgument, requested_name + " is not offered (device offers " + Join(offered) + ")");

  v4l2_format format{};
  format.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (Ioctl(fd_, VIDIOC_G_FMT, &format) != 0) return Errno(StatusCode::kUnavailable, "VIDIOC_G_FMT");
  const int width = s->width > 0 ? s->width : static_cast<int>(format.fmt.pix.width);
  const int height = s->height > 0 ? s->height : static_cast<int>(format.fmt.pix.height);
  format.fmt.pix.width = width;
  format.fmt.pix.height = height;
  format.fmt.pix.pixelformat = chosen->fourcc;
  format.fmt.pix.field = V4L2_FIELD_NONE;
  format.fmt.pix.bytesperline = 0;  // let the driver choose its stride
  if (Ioctl(fd_, VIDIOC_S_FMT, &format) != 0) {
    if (errno == EBUSY) return Errno(StatusCode::kUnavailable, "VIDIOC_S_FMT (busy: another handle is streaming)");
    return Errno(StatusCode::kInvalidArgument, "VIDIOC_S_FMT");
  }
  if (format.fmt.pix.pixelformat != chosen->fourcc)
    return Fail(StatusCode::kInvalidArgument, std::string("driver replaced ") + chosen->v4l2_name + " by " +
                                                  FourccName(format.fmt.pix.pixelformat));
  adjust("width", width, format.fmt.pix.width, "frame size the driver supports");
  adjust("height", height, format.fmt.pix.height, "frame size the driver supports");
  adjust("bit_depth", s->bit_depth, chosen->bits, requested_name + " not offered; using " + chosen->v4l2_name);
  s->width = static_cast<int>(format.fmt.pix.width);
  s->height = static_cast<int>(format.fmt.pix.height);
  s->bit_depth = chosen->bits;
  s->pixel_format = chosen->genicam_name;
  fourcc_ = chosen->fourcc;
  bytes_per_line_ = format.fmt.pix.bytesperline;

  // Exposure: manual mode, then V4L2_CID_EXPOSURE_ABSOLUTE in units of 100 us.
  const Control exposure = QueryControl(fd_, V4L2_CID_EXPOSURE_ABSOLUTE);
  has_exposure_control_ = exposure.present;
  if (exposure.present) {
    if (QueryControl(fd_, V4L2_CID_EXPOSURE_AUTO).present) SetControl(fd_, V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL);
    const std::int32_t units = Quantise(exposure.query, s->exposure_us / 100.0);
    std::int32_t applied = 0;
    if (!SetControl(fd_, V4L2_CID_EXPOSURE_ABSOLUTE, units) || !GetControl(fd_, V4L2_CID_EXPOSURE_ABSOLUTE, &applied))
      return Errno(StatusCode::kInvalidArgument, "setting V4L2_CID_EXPOSURE_ABSOLUTE");
    adjust("exposure_us", s->exposure_us, applied * 100.0,
           "100 us units, range [" + std::to_string(exposure.query.minimum * 100) + ", " +
               std::to_string(exposure.query.maximum * 100) + "] us");
    s->exposure_us = applied * 100.0;
  } else {
    // Reported every time: the frames' exposure is the device's own choice.
    adjustments.push_back({"exposure_us", s->exposure_us, s->exposure_us,
                           "device has no manual exposure control; the value is nominal"});
  }

  // Gain: V4L2_CID_GAIN in the device's own units, automatic gain off.
  const Control gain = QueryControl(fd_, V4L2_CID_GAIN);
  if (gain.present) {
    if (QueryControl(fd_, V4L2_CID_AUTOGAIN).present) SetControl(fd_, V4L2_CID_AUTOGAIN, 0);
    std::int32_t applied = 0;
    if (!SetControl(fd_, V4L2_CID_GAIN, Quantise(gain.query, s->gain_db)) || !GetControl(fd_, V4L2_CID_GAIN, &applied))
      return Errno(StatusCode::kInvalidArgument, "setting V4L2_CID_GAIN");
    adjust("gain_db", s->gain_db, applied,
           "device gain steps, range [" + std::to_string(gain.query.minimum) + ", " +
               std::to_string(gain.query.maximum) + "]");
    s->gain_db = applied;
  } else {
    adjust("gain_db", s->gain_db, 0.0, "device has no gain control");
    s->gain_db = 0.0;
  }
  return adjustments;
}

void V4l2Camera::ReleaseBuffers() {
  for (const Mapping& m : buffers_)
    if (m.start && m.start != MAP_FAILED) munmap(m.start, m.length);
  buffers_.clear();
  if (fd_ >= 0) {
    v4l2_requestbuffers request{};
    request.count = 0;
    request.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    request.memory = V4L2_MEMORY_MMAP;
    Ioctl(fd_, VIDIOC_REQBUFS, &request);
  }
}

Status V4l2Camera::DoStart() {
  v4l2_requestbuffers request{};
  request.count = static_cast<std::uint32_t>(options_.buffer_count);
  request.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  request.memory = V4L2_MEMORY_MMAP;
  if (Ioctl(fd_, VIDIOC_REQBUFS, &request) != 0)
    return Errno(StatusCode::kUnavailable, errno == EBUSY ? "VIDIOC_REQBUFS (busy: another handle is streaming)"
                                                          : "VIDIOC_REQBUFS");
  if (request.count < 2) {
    ReleaseBuffers();
    return Fail(StatusCode::kUnavailable, "driver granted " + std::to_string(request.count) + " buffers (need 2)");
  }
  for (std::uint32_t i = 0; i < request.count; ++i) {
    v4l2_buffer buffer{};
    buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buffer.memory = V4L2_MEMORY_MMAP;
    buffer.index = i;
    if (Ioctl(fd_, VIDIOC_QUERYBUF, &buffer) != 0) {
      Status status = Errno(StatusCode::kUnavailable, "VIDIOC_QUERYBUF");
      ReleaseBuffers();
      return status;
    }
    void* start = mmap(nullptr, buffer.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, buffer.m.offset);
    if (start == MAP_FAILED) {
      Status status = Errno(StatusCode::kUnavailable, "mmap");
      ReleaseBuffers();
      return status;
    }
    buffers_.push_back({start, buffer.length});
    if (Ioctl(fd_, VIDIOC_QBUF, &buffer) != 0) {
      Status status = Errno(StatusCode::kUnavailable, "VIDIOC_QBUF");
      ReleaseBuffers();
      return status;
    }
  }
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (Ioctl(fd_, VIDIOC_STREAMON, &type) != 0) {
    Status status = Errno(StatusCode::kUnavailable, "VIDIOC_STREAMON");
    ReleaseBuffers();
    return status;
  }
  have_sequence_ = false;
  trigger_time_ns_ = -1;
  // Without an exposure control a frame may have exposed for its whole period.
  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  const v4l2_fract& interval = parm.parm.capture.timeperframe;
  frame_period_ns_ = Ioctl(fd_, VIDIOC_G_PARM, &parm) == 0 && interval.denominator > 0
                         ? std::int64_t{1000000000} * interval.numerator / interval.denominator
                         : 0;
  return Status::Ok();
}

Status V4l2Camera::DoTrigger() {
  trigger_time_ns_ = MonotonicNs();
  return Status::Ok();
}

Result<Frame> V4l2Camera::DoWaitFrame(int timeout_ms) {
  const std::int64_t deadline = MonotonicNs() + static_cast<std::int64_t>(timeout_ms) * 1000000;
  const bool software = settings().trigger == TriggerMode::kSoftware;
  std::uint64_t dropped = 0;
  for (;;) {
    const std::int64_t remaining_ms = (deadline - MonotonicNs()) / 1000000;
    if (remaining_ms <= 0) {
      ++stats_.timeouts;
      return Fail(StatusCode::kTimeout, "no frame within " + std::to_string(timeout_ms) + " ms" +
                                            (software && trigger_time_ns_ < 0 ? " (was it triggered?)" : ""));
    }
    pollfd p{fd_, POLLIN, 0};
    const int ready = poll(&p, 1, static_cast<int>(remaining_ms));
    if (ready < 0 && errno == EINTR) continue;
    if (ready < 0) return Errno(StatusCode::kUnavailable, "poll");
    if (ready == 0) continue;  // the deadline check reports the timeout
    if (p.revents & (POLLERR | POLLHUP)) return Fail(StatusCode::kUnavailable, "device reported an error or hung up");

    v4l2_buffer buffer{};
    buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buffer.memory = V4L2_MEMORY_MMAP;
    if (Ioctl(fd_, VIDIOC_DQBUF, &buffer) != 0) {
      if (errno == EAGAIN) continue;
      return Errno(StatusCode::kUnavailable, "VIDIOC_DQBUF");
    }
    // Back to the driver on every path.
    struct Requeue {
      int fd;
      v4l2_buffer* buffer;
      ~Requeue() { Ioctl(fd, VIDIOC_QBUF, buffer); }
    } requeue{fd_, &buffer};

    if (have_sequence_) {
      const std::uint32_t gap = buffer.sequence - last_sequence_ - 1;  // wraps as the counter does
      if (gap < 0x80000000u) dropped += gap;
    }
    have_sequence_ = true;
    last_sequence_ = buffer.sequence;

    const std::int64_t stamp_ns =
        static_cast<std::int64_t>(buffer.timestamp.tv_sec) * 1000000000 + buffer.timestamp.tv_usec * 1000;
    if (software) {
      // The frame must have started exposing after the trigger: timestamps
      // taken at the end of the frame are moved back by the exposure, or by
      // the frame period when the exposure is only nominal.
      const bool end_of_frame = (buffer.flags & V4L2_BUF_FLAG_TSTAMP_SRC_MASK) == V4L2_BUF_FLAG_TSTAMP_SRC_EOF;
      const std::int64_t exposure_ns = has_exposure_control_ || frame_period_ns_ <= 0
                                           ? static_cast<std::int64_t>(settings().exposure_us * 1000.0)
                                           : frame_period_ns_;
      const std::int64_t start_ns = stamp_ns - (end_of_frame ? exposure_ns : 0);
      if (trigger_time_ns_ < 0 || start_ns < trigger_time_ns_) {
        ++stats_.stale;
        continue;
      }
    }
    stats_.dropped += dropped;
    const std::uint32_t sequence = buffer.sequence;
    if (buffer.flags & V4L2_BUF_FLAG_ERROR) {
      ++stats_.corrupt;
      trigger_time_ns_ = -1;
      return Fail(StatusCode::kDataLoss, "frame " + std::to_string(sequence) + " flagged as damaged by the driver");
    }
    const CameraSettings& s = settings();
    const bool one_byte = fourcc_ == V4L2_PIX_FMT_GREY || FindFormat(fourcc_)->bits == 8;  // YUYV: 2 bytes a pixel
    const std::size_t bytes_per_sample = one_byte && fourcc_ != V4L2_PIX_FMT_YUYV ? 1 : 2;
    const std::size_t row_bytes = static_cast<std::size_t>(s.width) * bytes_per_sample;
    const std::size_t stride = std::max<std::size_t>(bytes_per_line_, row_bytes);
    if (buffer.bytesused < stride * (s.height - 1) + row_bytes) {
      ++stats_.corrupt;
      trigger_time_ns_ = -1;
      return Fail(StatusCode::kDataLoss, "frame " + std::to_string(sequence) + " is short (" +
                                             std::to_string(buffer.bytesused) + " bytes)");
    }
    Frame frame = FrameTakenWith(s, s.width, s.height);
    frame.frame_id = sequence;
    frame.dropped_before = dropped;
    frame.device_timestamp_ns = stamp_ns;
    frame.host_timestamp_ns = RealtimeNs();
    frame.pixels.resize(static_cast<std::size_t>(s.width) * s.height);
    const auto* base = static_cast<const std::uint8_t*>(buffers_.at(buffer.index).start);
    for (int y = 0; y < s.height; ++y) {
      const std::uint8_t* row = base + static_cast<std::size_t>(y) * stride;
      std::uint16_t* out = frame.pixels.data() + static_cast<std::size_t>(y) * s.width;
      if (bytes_per_sample == 1) {  // GREY and 8-bit Bayer
        std::copy(row, row + s.width, out);
      } else if (fourcc_ == V4L2_PIX_FMT_YUYV) {
        for (int x = 0; x < s.width; ++x) out[x] = row[2 * x];  // Y0 U Y1 V: luma at even bytes
      } else {
        for (int x = 0; x < s.width; ++x) out[x] = static_cast<std::uint16_t>(row[2 * x] | (row[2 * x + 1] << 8));
      }
    }
    ++stats_.frames;
    trigger_time_ns_ = -1;
    return frame;
  }
}

Status V4l2Camera::DoStop() {
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  const bool stopped = Ioctl(fd_, VIDIOC_STREAMOFF, &type) == 0;
  Status status = stopped ? Status::Ok() : Errno(StatusCode::kUnavailable, "VIDIOC_STREAMOFF");
  ReleaseBuffers();
  return status;
}

Status V4l2Camera::DoClose() {
  ReleaseBuffers();
  if (fd_ >= 0) close(fd_);
  fd_ = -1;
  return Status::Ok();
}

std::vector<CameraInfo> DiscoverV4l2Cameras(const std::string& device_directory) {
  std::vector<std::string> paths;
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator(device_directory, error)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("video", 0) == 0) paths.push_back(entry.path().string());
  }
  std::sort(paths.begin(), paths.end());
  std::vector<CameraInfo> cameras;
  for (const std::string& path : paths) {
    CameraInfo info;
    info.driver = "v4l2";
    info.id = path;
    const int fd = open(path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
      info.error = std::string("cannot open: ") + std::strerror(errno);
      cameras.push_back(std::move(info));
      continue;
    }
    v4l2_capability caps{};
    const bool queried = Ioctl(fd, VIDIOC_QUERYCAP, &caps) == 0;
    if (!queried || !IsCaptureDevice(caps)) {
      close(fd);  // metadata or output nodes are not cameras
      continue;
    }
    info.vendor = reinterpret_cast<const char*>(caps.driver);
    info.model = reinterpret_cast<const char*>(caps.card);
    info.address = reinterpret_cast<const char*>(caps.bus_info);
    const std::vector<std::uint32_t> formats = OfferedFormats(fd);
    for (std::uint32_t f : formats) info.pixel_formats.push_back(FourccName(f));
    for (std::uint32_t f : formats) {
      v4l2_frmsizeenum size{};
      size.pixel_format = f;
      for (size.index = 0; Ioctl(fd, VIDIOC_ENUM_FRAMESIZES, &size) == 0; ++size.index) {
        const int w = size.type == V4L2_FRMSIZE_TYPE_DISCRETE ? size.discrete.width : size.stepwise.max_width;
        const int h = size.type == V4L2_FRMSIZE_TYPE_DISCRETE ? size.discrete.height : size.stepwise.max_height;
        if (w * h > info.sensor_width * info.sensor_height) {
          info.sensor_width = w;
          info.sensor_height = h;
        }
        if (size.type != V4L2_FRMSIZE_TYPE_DISCRETE) break;
      }
    }
    const Control exposure = QueryControl(fd, V4L2_CID_EXPOSURE_ABSOLUTE);
    if (exposure.present) {
      info.exposure_min_us = exposure.query.minimum * 100.0;
      info.exposure_max_us = exposure.query.maximum * 100.0;
    }
    close(fd);
    cameras.push_back(std::move(info));
  }
  return cameras;
}

}  // namespace photorig::drivers
