#include "photorig/sim/gige/gige_camera.h"

#include <arv.h>

#include <glib/gstdio.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstring>

namespace photorig::sim {
using solvers::core::Refuse;

namespace {

// Aravis' own GenICam description of its fake camera, with the Mono10 and
// Mono12 entries it lacks: the fake stores any pixel format code in its
// register and sizes the payload from the code, so only the enumeration needs
// the extra names. Returns the path of a temporary file ("" on failure).
std::string WriteGenicamWithWideMono() {
  ArvFakeCamera* reference = arv_fake_camera_new("XMLREF");
  size_t size = 0;
  const char* xml = arv_fake_camera_get_genicam_xml(reference, &size);
  std::string text(xml ? xml : "", xml ? size : 0);
  g_object_unref(reference);
  const std::string anchor = "<pValue>PixelFormatRegister</pValue>";
  const std::size_t at = text.find(anchor);
  if (at == std::string::npos) return "";
  const std::string entries = "<EnumEntry Name=\"Mono10\" NameSpace=\"Standard\"><Value>" +
                              std::to_string(ARV_PIXEL_FORMAT_MONO_10) +
                              "</Value></EnumEntry>\n\t\t<EnumEntry Name=\"Mono12\" NameSpace=\"Standard\"><Value>" +
                              std::to_string(ARV_PIXEL_FORMAT_MONO_12) + "</Value></EnumEntry>\n\t\t";
  text.insert(at, entries);
  char path[] = "/tmp/photorig-gige-XXXXXX";
  const int fd = mkstemp(path);
  if (fd < 0) return "";
  const bool written = write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size());
  close(fd);
  if (!written) {
    g_unlink(path);
    return "";
  }
  return path;
}

int SignificantBits(ArvPixelFormat format) {
  switch (format) {
    case ARV_PIXEL_FORMAT_MONO_10: return 10;
    case ARV_PIXEL_FORMAT_MONO_12: return 12;
    case ARV_PIXEL_FORMAT_MONO_16: return 16;
    default: return ARV_PIXEL_FORMAT_BIT_PER_PIXEL(format) == 8 ? 8 : 0;
  }
}

}  // namespace

struct GigeFakeCamera::Impl {
  std::shared_ptr<World> world;
  GigeFakeCameraOptions options;
  ArvGvFakeCamera* gv = nullptr;
  std::atomic<std::uint64_t> frames{0};
  std::uint64_t next_index = 0;  // noise key; only the fake's thread touches it

  // Runs on the fake camera's thread for every frame it sends.
  static void Fill(ArvBuffer* buffer, void* data, guint32 exposure_us, guint32 gain, ArvPixelFormat format) {
    auto* self = static_cast<Impl*>(data);
    ArvFakeCamera* fake = arv_gv_fake_camera_get_fake_camera(self->gv);
    guint32 width = 0, height = 0;
    arv_fake_camera_read_register(fake, ARV_FAKE_CAMERA_REGISTER_WIDTH, &width);
    arv_fake_camera_read_register(fake, ARV_FAKE_CAMERA_REGISTER_HEIGHT, &height);
    // Inside the callback the buffer reports a data size of 0: the payload is
    // width x height x bytes per sample, which the fake allocated.
    auto* out = static_cast<std::uint8_t*>(const_cast<void*>(arv_buffer_get_data(buffer, nullptr)));
    const int bits = SignificantBits(format);
    if (!out || bits == 0) return;
    SensorModel sensor = self->world->config().sensor;
    sensor.bit_depth = bits;
    const auto& geometry = self->world->config().camera;
    const std::vector<std::uint16_t> dn = ExposeFrame(sensor, self->world->RenderRadiance(), exposure_us,
                                                      static_cast<double>(gain), self->world->config().seed,
                                                      self->next_index++);
    const guint32 rows = std::min<guint32>(height, geometry.height);
    const guint32 cols = std::min<guint32>(width, geometry.width);
    const std::size_t bytes = bits == 8 ? 1 : 2;
    std::memset(out, 0, static_cast<std::size_t>(width) * height * bytes);
    for (guint32 y = 0; y < rows; ++y)
      for (guint32 x = 0; x < cols; ++x) {
        const std::uint16_t value = dn[static_cast<std::size_t>(y) * geometry.width + x];
        const std::size_t i = static_cast<std::size_t>(y) * width + x;
        if (bytes == 1) {
          out[i] = static_cast<std::uint8_t>(value);
        } else {
          out[2 * i] = static_cast<std::uint8_t>(value & 0xff);  // GenICam samples are little-endian
          out[2 * i + 1] = static_cast<std::uint8_t>(value >> 8);
        }
      }
    self->frames.fetch_add(1);
  }
};

bool GigeFakeCameraOptions::IsValid(std::string* why) const {
  if (address.empty()) return Refuse(why, "address is empty");
  if (serial.empty() || serial.size() >= 16) return Refuse(why, "serial must have 1 to 15 characters");
  if (!(lost_packet_ratio >= 0.0 && lost_packet_ratio < 1.0)) return Refuse(why, "lost_packet_ratio must be in [0, 1)");
  if (!(trigger_poll_hz > 0.0 && trigger_poll_hz <= 10000.0)) return Refuse(why, "trigger_poll_hz must be in (0, 10000]");
  return true;
}

GigeFakeCamera::GigeFakeCamera(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

GigeFakeCamera::~GigeFakeCamera() {
  if (impl_->gv) g_object_unref(impl_->gv);  // joins the camera's threads and closes its sockets
}

const GigeFakeCameraOptions& GigeFakeCamera::options() const { return impl_->options; }
std::uint64_t GigeFakeCamera::frames_rendered() const { return impl_->frames.load(); }

Result<std::unique_ptr<GigeFakeCamera>> GigeFakeCamera::Start(std::shared_ptr<World> world,
                                                              GigeFakeCameraOptions options) {
  std::string why;
  if (!options.IsValid(&why)) return Status{StatusCode::kInvalidArgument, "GigE Vision fake camera: " + why};
  const std::string xml_path = WriteGenicamWithWideMono();
  if (xml_path.empty()) return Status{StatusCode::kInternal, "GigE Vision fake camera: cannot write its GenICam file"};
  auto impl = std::make_unique<Impl>();
  impl->world = std::move(world);
  impl->options = options;
  impl->gv = arv_gv_fake_camera_new_full(options.address.c_str(), options.serial.c_str(), xml_path.c_str());
  g_unlink(xml_path.c_str());  // read at construction
  if (!impl->gv || !arv_gv_fake_camera_is_running(impl->gv)) {
    if (impl->gv) g_object_unref(impl->gv);
    impl->gv = nullptr;
    return Status{StatusCode::kUnavailable, "GigE Vision fake camera " + options.serial + ": cannot listen on " +
                                                options.address +
                                                ":3956 (not a local interface address, or another camera is there)"};
  }
  ArvFakeCamera* fake = arv_gv_fake_camera_get_fake_camera(impl->gv);
  const auto& geometry = impl->world->config().camera;
  arv_fake_camera_write_register(fake, ARV_FAKE_CAMERA_REGISTER_SENSOR_WIDTH, geometry.width);
  arv_fake_camera_write_register(fake, ARV_FAKE_CAMERA_REGISTER_SENSOR_HEIGHT, geometry.height);
  arv_fake_camera_write_register(fake, ARV_FAKE_CAMERA_REGISTER_WIDTH, geometry.width);
  arv_fake_camera_write_register(fake, ARV_FAKE_CAMERA_REGISTER_HEIGHT, geometry.height);
  arv_fake_camera_set_trigger_frequency(fake, options.trigger_poll_hz);
  g_object_set(impl->gv, "gvsp-lost-ratio", options.lost_packet_ratio, nullptr);
  arv_fake_camera_set_fill_pattern(fake, &Impl::Fill, impl.get());
  return std::unique_ptr<GigeFakeCamera>(new GigeFakeCamera(std::move(impl)));
}

AravisCameraOnGigeFake::AravisCameraOnGigeFake(std::string id, drivers::AravisCameraOptions camera_options,
                                               std::shared_ptr<World> world, GigeFakeCameraOptions fake_options)
    : AravisCamera(std::move(id), std::move(camera_options)),
      world_(std::move(world)),
      fake_options_(std::move(fake_options)) {}

AravisCameraOnGigeFake::~AravisCameraOnGigeFake() {
  (void)Close();  // while the fake still answers
}

Status AravisCameraOnGigeFake::DoOpen() {
  if (!fake_) {
    auto fake = GigeFakeCamera::Start(world_, fake_options_);
    if (!fake.ok()) return fake.status();
    fake_ = std::move(fake).value();
  }
  return AravisCamera::DoOpen();
}

Status AravisCameraOnGigeFake::DoClose() {
  Status status = AravisCamera::DoClose();
  fake_.reset();
  return status;
}

}  // namespace photorig::sim
