// The V4L2 driver against the kernel's vivid test driver. Runs inside the VM
// that scripts/v4l2-vm-test.sh boots: /dev/video0 is a single-planar vivid
// capture node with one webcam input, /dev/video1 a multi-planar-only one
// (PHOTORIG_V4L2_DEVICE and PHOTORIG_V4L2_MPLANE_DEVICE override the paths).
//
// vivid's frames come from the kernel's test pattern generator (75% colour
// bars under a text overlay with running counters); its buffer timestamps are
// CLOCK_MONOTONIC, taken by a kernel thread that runs on the frame clock and
// skips sequence numbers when it falls behind. Its test controls inject
// dropped buffers, damaged buffers and fatal queue errors.

#include "photorig/drivers/v4l2/v4l2_camera.h"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <set>

namespace photorig {
namespace {

using drivers::Camera;
using drivers::CameraSettings;
using drivers::Frame;
using drivers::TriggerMode;
using drivers::V4l2Camera;
using drivers::V4l2CameraOptions;

std::string DevicePath(const char* variable, const char* fallback) {
  const char* value = std::getenv(variable);
  return value && *value ? value : fallback;
}
const std::string kDevice = DevicePath("PHOTORIG_V4L2_DEVICE", "/dev/video0");
const std::string kMplaneDevice = DevicePath("PHOTORIG_V4L2_MPLANE_DEVICE", "/dev/video1");

std::int64_t MonotonicNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// A second handle on the device for what the driver does not expose: the
// format list, sizes, frame interval and vivid's own test controls.
class RawDevice {
 public:
  explicit RawDevice(const std::string& path) : fd_(open(path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC)) {}
  ~RawDevice() {
    if (fd_ >= 0) close(fd_);
  }
  bool ok() const { return fd_ >= 0; }

  std::vector<std::uint32_t> Formats() const {
    std::vector<std::uint32_t> formats;
    v4l2_fmtdesc desc{};
    desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    for (desc.index = 0; ioctl(fd_, VIDIOC_ENUM_FMT, &desc) == 0; ++desc.index) formats.push_back(desc.pixelformat);
    return formats;
  }
  bool Offers(std::uint32_t fourcc) const {
    const auto formats = Formats();
    return std::find(formats.begin(), formats.end(), fourcc) != formats.end();
  }

  // The smallest frame size offered for GREY, to keep the VM's work small.
  std::pair<int, int> SmallestSize() const {
    std::pair<int, int> best{0, 0};
    v4l2_frmsizeenum size{};
    size.pixel_format = V4L2_PIX_FMT_GREY;
    for (size.index = 0; ioctl(fd_, VIDIOC_ENUM_FRAMESIZES, &size) == 0; ++size.index) {
      const bool discrete = size.type == V4L2_FRMSIZE_TYPE_DISCRETE;
      const int w = discrete ? size.discrete.width : size.stepwise.min_width;
      const int h = discrete ? size.discrete.height : size.stepwise.min_height;
      if (best.first == 0 || w * h < best.first * best.second) best = {w, h};
      if (!discrete) break;
    }
    return best;
  }

  // Asks for a frame period; the driver picks the nearest it supports.
  void SetFramePeriod(std::uint32_t numerator, std::uint32_t denominator) const {
    v4l2_streamparm parm{};
    parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    parm.parm.capture.timeperframe = {numerator, denominator};
    EXPECT_EQ(ioctl(fd_, VIDIOC_S_PARM, &parm), 0) << std::strerror(errno);
  }

  // The current capture frame period.
  std::int64_t FramePeriodNs() const {
    v4l2_streamparm parm{};
    parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (ioctl(fd_, VIDIOC_G_PARM, &parm) != 0 || parm.parm.capture.timeperframe.denominator == 0) return 0;
    return std::int64_t{1000000000} * parm.parm.capture.timeperframe.numerator /
           parm.parm.capture.timeperframe.denominator;
  }

  // Control id by its name ("Percentage of Dropped Buffers"), 0 if absent.
  std::uint32_t ControlId(const std::string& name) const {
    v4l2_query_ext_ctrl query{};
    query.id = V4L2_CTRL_FLAG_NEXT_CTRL | V4L2_CTRL_FLAG_NEXT_COMPOUND;
    while (ioctl(fd_, VIDIOC_QUERY_EXT_CTRL, &query) == 0) {
      if (name == query.name) return query.id;
      query.id |= V4L2_CTRL_FLAG_NEXT_CTRL | V4L2_CTRL_FLAG_NEXT_COMPOUND;
    }
    return 0;
  }
  std::vector<std::string> ControlNames() const {
    std::vector<std::string> names;
    v4l2_query_ext_ctrl query{};
    query.id = V4L2_CTRL_FLAG_NEXT_CTRL;
    while (ioctl(fd_, VIDIOC_QUERY_EXT_CTRL, &query) == 0) {
      if (query.type != V4L2_CTRL_TYPE_CTRL_CLASS) names.push_back(query.name);
      query.id |= V4L2_CTRL_FLAG_NEXT_CTRL;
    }
    return names;
  }
  // The control's range; flags say V4L2_CTRL_FLAG_DISABLED when absent.
  v4l2_queryctrl Query(std::uint32_t id) const {
    v4l2_queryctrl query{};
    query.id = id;
    if (ioctl(fd_, VIDIOC_QUERYCTRL, &query) != 0) query.flags = V4L2_CTRL_FLAG_DISABLED;
    return query;
  }
  bool Has(std::uint32_t id) const { return !(Query(id).flags & V4L2_CTRL_FLAG_DISABLED); }
  // Index of a menu control's entry by name, -1 if absent.
  int MenuIndex(std::uint32_t id, const std::string& entry) const {
    const v4l2_queryctrl range = Query(id);
    for (int i = range.minimum; i <= range.maximum; ++i) {
      v4l2_querymenu menu{};
      menu.id = id;
      menu.index = static_cast<std::uint32_t>(i);
      if (ioctl(fd_, VIDIOC_QUERYMENU, &menu) == 0 && entry == reinterpret_cast<const char*>(menu.name)) return i;
    }
    return -1;
  }
  bool Set(std::uint32_t id, std::int32_t value) const {
    v4l2_control control{id, value};
    return ioctl(fd_, VIDIOC_S_CTRL, &control) == 0;
  }
  std::int32_t Get(std::uint32_t id) const {
    v4l2_control control{id, -1};
    return ioctl(fd_, VIDIOC_G_CTRL, &control) == 0 ? control.value : -1;
  }

 private:
  int fd_;
};

std::string Fourcc(std::uint32_t f) {
  return {static_cast<char>(f & 0xff), static_cast<char>((f >> 8) & 0xff), static_cast<char>((f >> 16) & 0xff),
          static_cast<char>((f >> 24) & 0xff)};
}

// One of vivid's test controls, by name, set for a scope (buttons have no
// value to restore).
class ScopedControl {
 public:
  ScopedControl(const RawDevice& device, const std::string& name, std::int32_t value)
      : device_(device), id_(device.ControlId(name)), previous_(id_ ? device.Get(id_) : 0) {
    EXPECT_NE(id_, 0u) << "vivid has no '" << name << "' control";
    EXPECT_TRUE(id_ && device_.Set(id_, value)) << name;
  }
  ~ScopedControl() {
    if (id_ && device_.Query(id_).type != V4L2_CTRL_TYPE_BUTTON) device_.Set(id_, previous_);
  }

 private:
  const RawDevice& device_;
  std::uint32_t id_;
  std::int32_t previous_;
};

class VividTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(raw_.ok()) << kDevice << ": " << std::strerror(errno) << " (these tests run in the vivid VM)";
    std::tie(width_, height_) = raw_.SmallestSize();
    ASSERT_GT(width_ * height_, 0);
  }

  CameraSettings Settings(const std::string& pixel_format, TriggerMode trigger = TriggerMode::kFreeRun) const {
    CameraSettings s;
    s.width = width_;
    s.height = height_;
    s.pixel_format = pixel_format;
    s.trigger = trigger;
    return s;
  }

  // Opens, configures and starts; the camera is streaming on success.
  void StartCamera(V4l2Camera* camera, const CameraSettings& settings) {
    ASSERT_TRUE(camera->Open().ok());
    const auto adjustments = camera->Configure(settings);
    ASSERT_TRUE(adjustments.ok()) << adjustments.status().ToString();
    // vivid's webcam input defaults to 5 fps at its smallest size.
    raw_.SetFramePeriod(1, 30);
    const Status started = camera->Start();
    ASSERT_TRUE(started.ok()) << started.ToString();
  }

  static V4l2CameraOptions Options(const std::string& device = kDevice) {
    V4l2CameraOptions options;
    options.device = device;
    return options;
  }

  RawDevice raw_{kDevice};
  int width_ = 0, height_ = 0;
};

TEST_F(VividTest, QueryCapabilitiesNamesTheVividDriver) {
  V4l2Camera camera("vivid", Options());
  ASSERT_TRUE(camera.Open().ok());
  EXPECT_EQ(camera.driver_name(), "vivid");
  EXPECT_FALSE(camera.card().empty());
  EXPECT_EQ(camera.state(), Camera::State::kOpen);

  // For the log: what this kernel's vivid offers.
  std::string formats, controls;
  for (std::uint32_t f : raw_.Formats()) formats += Fourcc(f) + " ";
  for (const std::string& name : raw_.ControlNames()) controls += "'" + name + "' ";
  std::cout << "vivid card '" << camera.card() << "', smallest size " << width_ << "x" << height_ << ", period "
            << raw_.FramePeriodNs() << " ns\n  formats: " << formats << "\n  controls: " << controls << "\n";

  const auto cameras = drivers::DiscoverV4l2Cameras();
  const auto it = std::find_if(cameras.begin(), cameras.end(), [](const auto& c) { return c.id == kDevice; });
  ASSERT_NE(it, cameras.end());
  EXPECT_EQ(it->vendor, "vivid");
  EXPECT_GT(it->sensor_width, 0);
  EXPECT_NE(std::find(it->pixel_formats.begin(), it->pixel_formats.end(), "GREY"), it->pixel_formats.end());
  EXPECT_NE(std::find(it->pixel_formats.begin(), it->pixel_formats.end(), "Y16-BE"), it->pixel_formats.end());
  for (const std::string& name : it->pixel_formats)  // they end up in JSON
    EXPECT_TRUE(std::all_of(name.begin(), name.end(), [](char c) { return c > 0x20 && c < 0x7f; })) << name;
  // The multi-planar-only node is no camera for this driver.
  EXPECT_EQ(std::find_if(cameras.begin(), cameras.end(), [](const auto& c) { return c.id == kMplaneDevice; }),
            cameras.end());
}

TEST_F(VividTest, MultiplanarOnlyNodeIsRefusedByName) {
  V4l2Camera camera("mplane", Options(kMplaneDevice));
  const Status status = camera.Open();
  EXPECT_EQ(status.code(), StatusCode::kInvalidArgument) << status.ToString();
  EXPECT_NE(status.message().find(kMplaneDevice), std::string::npos) << status.message();
  EXPECT_NE(status.message().find("not a streaming video capture device"), std::string::npos) << status.message();
  EXPECT_EQ(camera.state(), Camera::State::kClosed);
}

TEST_F(VividTest, StateMachineRefusesIllegalTransitions) {
  V4l2Camera camera("vivid", Options());
  const auto refused = [](const Status& s) { return s.code() == StatusCode::kFailedPrecondition; };
  EXPECT_TRUE(refused(camera.Configure(Settings("Mono8")).status()));
  EXPECT_TRUE(refused(camera.Start()));
  EXPECT_TRUE(refused(camera.Trigger()));
  EXPECT_TRUE(refused(camera.WaitFrame(100).status()));
  EXPECT_TRUE(refused(camera.Stop()));

  ASSERT_TRUE(camera.Open().ok());
  EXPECT_TRUE(refused(camera.Open()));
  EXPECT_TRUE(refused(camera.Start()));
  ASSERT_TRUE(camera.Configure(Settings("Mono8", TriggerMode::kSoftware)).ok());
  EXPECT_TRUE(refused(camera.Trigger()));
  EXPECT_TRUE(refused(camera.WaitFrame(100).status()));
  EXPECT_TRUE(refused(camera.Stop()));
  EXPECT_EQ(camera.state(), Camera::State::kConfigured);

  ASSERT_TRUE(camera.Start().ok());
  EXPECT_TRUE(refused(camera.Start()));
  EXPECT_TRUE(refused(camera.Configure(Settings("Mono16")).status()));
  EXPECT_TRUE(refused(camera.Open()));
  EXPECT_EQ(camera.state(), Camera::State::kStreaming);
  EXPECT_EQ(camera.settings().pixel_format, "Mono8");

  // Close from streaming releases the buffers: the device can be streamed again.
  EXPECT_TRUE(camera.Close().ok());
  EXPECT_EQ(camera.state(), Camera::State::kClosed);
  V4l2Camera again("vivid-again", Options());
  StartCamera(&again, Settings("Mono8"));
  EXPECT_TRUE(again.WaitFrame(3000).ok());
  EXPECT_TRUE(again.Stop().ok());
  EXPECT_TRUE(refused(again.Stop()));
  // Reconfigure after a stop (buffers released, so the format may change).
  ASSERT_TRUE(again.Configure(Settings("Mono16")).ok());
  ASSERT_TRUE(again.Start().ok());
  const auto frame = again.WaitFrame(3000);
  ASSERT_TRUE(frame.ok()) << frame.status().ToString();
  EXPECT_EQ(frame->pixel_format, "Mono16");
}

TEST_F(VividTest, SecondUserOfABusyDeviceIsUnavailableAndNamed) {
  V4l2Camera first("first", Options());
  StartCamera(&first, Settings("Mono8"));
  V4l2Camera second("second", Options());
  ASSERT_TRUE(second.Open().ok());  // V4L2 allows several opens; the stream has one owner
  const auto configured = second.Configure(Settings("Mono16"));
  ASSERT_FALSE(configured.ok());
  EXPECT_EQ(configured.status().code(), StatusCode::kUnavailable) << configured.status().ToString();
  EXPECT_NE(configured.status().message().find(kDevice), std::string::npos);
  EXPECT_NE(configured.status().message().find("busy"), std::string::npos) << configured.status().message();
  EXPECT_TRUE(first.WaitFrame(3000).ok());
}

// Every monochrome format vivid offers carries the same test pattern (text
// overlay off, so every row crosses the eight bars): the
// luma of one row, scaled to 8 bits, matches GREY's; samples stay within
// the format's bits, and the colour bars give distinct levels.
TEST_F(VividTest, MonochromeFormatsDeliverTheSamePatternWithinTheirBits) {
  struct Case {
    std::uint32_t fourcc;
    const char* name;
    int bits;
  };
  const Case cases[] = {{V4L2_PIX_FMT_GREY, "Mono8", 8},
                        {V4L2_PIX_FMT_Y10, "Y10", 10},
                        {V4L2_PIX_FMT_Y12, "Y12", 12},
                        {V4L2_PIX_FMT_Y16, "Mono16", 16}};
  ASSERT_TRUE(raw_.Offers(V4L2_PIX_FMT_GREY));
  ASSERT_TRUE(raw_.Offers(V4L2_PIX_FMT_Y16));
  const std::uint32_t osd = raw_.ControlId("OSD Text Mode");
  ScopedControl no_text(raw_, "OSD Text Mode", raw_.MenuIndex(osd, "None"));
  std::vector<int> reference;  // GREY row at 3/4 of the height
  int tested = 0;
  for (const Case& c : cases) {
    if (!raw_.Offers(c.fourcc)) continue;
    SCOPED_TRACE(c.name);
    V4l2Camera camera("vivid", Options());
    StartCamera(&camera, Settings(c.name));
    const auto frame = camera.WaitFrame(3000);
    ASSERT_TRUE(frame.ok()) << frame.status().ToString();
    ASSERT_EQ(frame->width, width_);
    ASSERT_EQ(frame->height, height_);
    ASSERT_EQ(frame->pixels.size(), static_cast<std::size_t>(width_) * height_);
    EXPECT_EQ(frame->bit_depth, c.bits);
    const std::uint16_t max = *std::max_element(frame->pixels.begin(), frame->pixels.end());
    EXPECT_LT(max, 1u << c.bits);
    if (c.bits > 8) {
      EXPECT_GT(max, 255) << "upper byte of the samples lost";
    }

    const std::uint16_t* row = frame->pixels.data() + static_cast<std::size_t>(height_) * 3 / 4 * width_;
    std::vector<int> luma8(row, row + width_);
    for (int& v : luma8) v >>= (c.bits - 8);
    EXPECT_GE(std::set<int>(luma8.begin(), luma8.end()).size(), 6u) << "expected colour bars";
    if (reference.empty()) {
      reference = luma8;
    } else {
      int worst = 0;
      for (int x = 0; x < width_; ++x) worst = std::max(worst, std::abs(luma8[x] - reference[x]));
      EXPECT_LE(worst, 1) << "row differs from GREY's";
    }
    ++tested;
  }
  EXPECT_GE(tested, 2);
}

TEST_F(VividTest, YuyvDeliversLumaWithColourBars) {
  ASSERT_TRUE(raw_.Offers(V4L2_PIX_FMT_YUYV));
  const std::uint32_t osd = raw_.ControlId("OSD Text Mode");
  ScopedControl no_text(raw_, "OSD Text Mode", raw_.MenuIndex(osd, "None"));
  V4l2Camera camera("vivid", Options());
  StartCamera(&camera, Settings("YUYV"));
  const auto frame = camera.WaitFrame(3000);
  ASSERT_TRUE(frame.ok()) << frame.status().ToString();
  EXPECT_EQ(frame->bit_depth, 8);
  const std::uint16_t* row = frame->pixels.data() + static_cast<std::size_t>(height_) * 3 / 4 * width_;
  const std::set<int> levels(row, row + width_);
  EXPECT_GE(levels.size(), 6u);
  EXPECT_LE(*levels.rbegin(), 255);
  // Bars run from light (left) to dark (right): luma, not interleaved chroma.
  EXPECT_GT(row[width_ / 16], row[width_ - 1 - width_ / 16] + 64);
}

TEST_F(VividTest, UnsupportedSizeAndDepthAreAdjustedAndReported) {
  V4l2Camera camera("vivid", Options());
  ASSERT_TRUE(camera.Open().ok());
  CameraSettings s = Settings("");
  s.width = width_ + 3;  // vivid's webcam input has discrete sizes only
  s.height = height_ + 5;
  s.bit_depth = 14;  // no 14-bit format: the narrowest one holding 14 bits
  const auto adjustments = camera.Configure(s);
  ASSERT_TRUE(adjustments.ok()) << adjustments.status().ToString();
  std::set<std::string> fields;
  for (const auto& a : adjustments.value()) fields.insert(a.field);
  EXPECT_TRUE(fields.count("width") && fields.count("height") && fields.count("bit_depth"));
  EXPECT_EQ(camera.settings().width, width_);
  EXPECT_EQ(camera.settings().height, height_);
  EXPECT_EQ(camera.settings().bit_depth, 16);
  EXPECT_EQ(camera.settings().pixel_format, "Mono16");

  s.pixel_format = "RGB8";  // RGB frames are not decoded by this driver
  const auto refused = camera.Configure(s);
  EXPECT_EQ(refused.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(refused.status().message().find("RGB8"), std::string::npos);
  EXPECT_EQ(camera.settings().pixel_format, "Mono16") << "a refused Configure changes nothing";

  s.trigger = TriggerMode::kHardware;
  s.pixel_format = "";
  EXPECT_EQ(camera.Configure(s).status().code(), StatusCode::kInvalidArgument);
}

// A Bayer raw asked for by name arrives as the one-channel mosaic, 8 bits a sample.
TEST_F(VividTest, BayerRawArrivesAsTheMosaic) {
  V4l2Camera camera("vivid", Options());
  StartCamera(&camera, Settings("BayerRG8"));
  EXPECT_EQ(camera.settings().pixel_format, "BayerRG8");
  EXPECT_EQ(camera.settings().bit_depth, 8);
  const auto frame = camera.WaitFrame(3000);
  ASSERT_TRUE(frame.ok()) << frame.status().ToString();
  EXPECT_EQ(frame.value().pixel_format, "BayerRG8");
  ASSERT_EQ(frame.value().pixels.size(), static_cast<std::size_t>(frame.value().width) * frame.value().height);
  // vivid's colour bars through an RGGB filter: the four sites of a 2 x 2 block differ somewhere.
  const auto& p = frame.value().pixels;
  const int w = frame.value().width;
  bool sites_differ = false;
  for (int x = 0; x + 1 < w && !sites_differ; x += 2) sites_differ = p[x] != p[x + 1] || p[x] != p[w + x + 1];
  EXPECT_TRUE(sites_differ);
  EXPECT_LE(*std::max_element(p.begin(), p.end()), 255);
  EXPECT_TRUE(camera.Stop().ok());
}

// vivid has a user gain control (with autogain) but no exposure control.
TEST_F(VividTest, GainIsSetThroughTheUserControlAndExposureIsNominal) {
  ASSERT_TRUE(raw_.Has(V4L2_CID_GAIN));
  const v4l2_queryctrl gain = raw_.Query(V4L2_CID_GAIN);
  V4l2Camera camera("vivid", Options());
  ASSERT_TRUE(camera.Open().ok());
  CameraSettings s = Settings("Mono8");
  s.gain_db = 37.4;
  const auto adjustments = camera.Configure(s);
  ASSERT_TRUE(adjustments.ok()) << adjustments.status().ToString();
  EXPECT_EQ(camera.settings().gain_db, 37.0);
  EXPECT_EQ(raw_.Get(V4L2_CID_GAIN), 37) << "read back through another handle";
  if (raw_.Has(V4L2_CID_AUTOGAIN)) {
    EXPECT_EQ(raw_.Get(V4L2_CID_AUTOGAIN), 0);
  }
  bool gain_reported = false, exposure_reported = false;
  for (const auto& a : adjustments.value()) {
    if (a.field == "gain_db") gain_reported = a.requested == 37.4 && a.applied == 37.0;
    if (a.field == "exposure_us") exposure_reported = a.reason.find("nominal") != std::string::npos;
  }
  EXPECT_TRUE(gain_reported);
  EXPECT_EQ(exposure_reported, !raw_.Has(V4L2_CID_EXPOSURE_ABSOLUTE));

  s.gain_db = gain.maximum + 1000.0;  // clamped to the control's range
  ASSERT_TRUE(camera.Configure(s).ok());
  EXPECT_EQ(camera.settings().gain_db, gain.maximum);
  EXPECT_EQ(raw_.Get(V4L2_CID_GAIN), gain.maximum);
}

TEST_F(VividTest, FreeRunFramesHaveIncreasingIdsAndFramePeriodTimestamps) {
  V4l2Camera camera("vivid", Options());
  StartCamera(&camera, Settings("Mono8"));
  const std::int64_t period_ns = raw_.FramePeriodNs();
  ASSERT_GT(period_ns, 0);
  std::vector<Frame> frames;
  for (int i = 0; i < 8; ++i) {
    auto frame = camera.WaitFrame(3000);
    ASSERT_TRUE(frame.ok()) << frame.status().ToString();
    frames.push_back(std::move(frame).value());
  }
  const std::int64_t now_ns = MonotonicNs();
  for (std::size_t i = 1; i < frames.size(); ++i) {
    const Frame& a = frames[i - 1];
    const Frame& b = frames[i];
    ASSERT_GT(b.frame_id, a.frame_id);
    EXPECT_EQ(b.dropped_before, b.frame_id - a.frame_id - 1);
    // vivid numbers a frame by the nearest slot of its frame clock and stamps
    // it when filled: each stamp lies within half a period of its slot.
    const std::int64_t expected = static_cast<std::int64_t>(b.frame_id - a.frame_id) * period_ns;
    EXPECT_NEAR(b.device_timestamp_ns - a.device_timestamp_ns, expected, period_ns) << "frame " << b.frame_id;
    EXPECT_GE(b.host_timestamp_ns, a.host_timestamp_ns);
  }
  // CLOCK_MONOTONIC stamps, not wall-clock ones.
  EXPECT_LT(std::llabs(frames.back().device_timestamp_ns - now_ns), 5'000'000'000LL);
  // The pattern's text overlay shows a running counter: consecutive frames differ.
  EXPECT_NE(frames.front().pixels, frames.back().pixels);
  EXPECT_EQ(camera.statistics().frames, frames.size());
}

TEST_F(VividTest, SequenceGapsAreCountedAsDroppedFrames) {
  V4l2Camera camera("vivid", Options());
  StartCamera(&camera, Settings("Mono8"));
  ScopedControl drops(raw_, "Percentage of Dropped Buffers", 60);
  std::vector<Frame> frames;
  for (int i = 0; i < 12; ++i) {
    auto frame = camera.WaitFrame(3000);
    ASSERT_TRUE(frame.ok()) << frame.status().ToString();
    frames.push_back(std::move(frame).value());
  }
  std::uint64_t dropped = 0;
  for (std::size_t i = 1; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].dropped_before, frames[i].frame_id - frames[i - 1].frame_id - 1);
    dropped += frames[i].dropped_before;
  }
  EXPECT_GT(dropped, 0u) << "60% of the buffers were dropped, yet no gap was seen";
  EXPECT_EQ(camera.statistics().dropped, dropped + frames.front().dropped_before);
}

TEST_F(VividTest, PollTimesOutWhenNoFrameArrives) {
  {
    // Software trigger never sent: frames stream but are all stale.
    V4l2Camera camera("vivid", Options());
    StartCamera(&camera, Settings("Mono8", TriggerMode::kSoftware));
    const std::int64_t start = MonotonicNs();
    const auto frame = camera.WaitFrame(400);
    const std::int64_t elapsed_ms = (MonotonicNs() - start) / 1000000;
    EXPECT_EQ(frame.status().code(), StatusCode::kTimeout);
    EXPECT_NE(frame.status().message().find("was it triggered"), std::string::npos);
    EXPECT_GE(elapsed_ms, 399);
    EXPECT_LT(elapsed_ms, 3000);
    EXPECT_EQ(camera.statistics().timeouts, 1u);
    EXPECT_GT(camera.statistics().stale, 0u);
  }
  // Free run with every buffer dropped: poll itself times out; frames resume afterwards.
  V4l2Camera camera("vivid", Options());
  StartCamera(&camera, Settings("Mono8"));
  // Gaps are counted from the first delivered frame on.
  const auto first = camera.WaitFrame(3000);
  ASSERT_TRUE(first.ok()) << first.status().ToString();
  std::uint64_t last_id = first->frame_id;
  {
    ScopedControl drops(raw_, "Percentage of Dropped Buffers", 100);
    // Buffers filled before the injection come first; then poll waits in vain.
    bool timed_out = false;
    for (int i = 0; i < 8 && !timed_out; ++i) {
      const std::int64_t start = MonotonicNs();
      const auto frame = camera.WaitFrame(300);
      const std::int64_t elapsed_ms = (MonotonicNs() - start) / 1000000;
      if (frame.ok()) {
        last_id = frame->frame_id;
        continue;
      }
      timed_out = true;
      EXPECT_EQ(frame.status().code(), StatusCode::kTimeout) << frame.status().ToString();
      EXPECT_GE(elapsed_ms, 299);
      EXPECT_LT(elapsed_ms, 3000);
    }
    EXPECT_TRUE(timed_out);
  }
  const auto frame = camera.WaitFrame(3000);
  ASSERT_TRUE(frame.ok()) << frame.status().ToString();
  EXPECT_GT(frame->dropped_before, 0u) << "the frames dropped during the timeout are a sequence gap: frame "
                                       << frame->frame_id << " after " << last_id;
}

// vivid's default timestamp source is the end of the frame, whose exposure
// began up to a frame period earlier: the delivered frame must have started
// after the trigger, even though vivid has no exposure control.
TEST_F(VividTest, SoftwareTriggerDeliversAFrameExposedAfterTheTrigger) {
  const std::uint32_t source = raw_.ControlId("Timestamp Source");
  ASSERT_NE(source, 0u);
  ASSERT_EQ(raw_.Get(source), 0) << "expected vivid's default 'End of Frame' timestamps";
  V4l2Camera camera("vivid", Options());
  StartCamera(&camera, Settings("Mono8", TriggerMode::kSoftware));
  const std::int64_t period_ns = raw_.FramePeriodNs();
  ASSERT_GT(period_ns, 0);
  std::int64_t last_id = -1;
  for (int i = 0; i < 4; ++i) {
    // Trigger at varying phases of the frame clock.
    usleep(static_cast<useconds_t>(period_ns / 1000 * i / 4));
    const std::int64_t before_trigger = MonotonicNs();
    ASSERT_TRUE(camera.Trigger().ok());
    const auto frame = camera.WaitFrame(3000);
    ASSERT_TRUE(frame.ok()) << frame.status().ToString();
    EXPECT_GE(frame->device_timestamp_ns - period_ns, before_trigger)
        << "frame " << frame->frame_id << " began exposing before the trigger";
    EXPECT_GT(static_cast<std::int64_t>(frame->frame_id), last_id);
    last_id = static_cast<std::int64_t>(frame->frame_id);
  }
  EXPECT_EQ(camera.statistics().frames, 4u);
  EXPECT_EQ(camera.WaitFrame(200).status().code(), StatusCode::kTimeout) << "one frame per trigger";
}

TEST_F(VividTest, BufferFlaggedAsDamagedIsDataLossNotAFrame) {
  V4l2Camera camera("vivid", Options());
  StartCamera(&camera, Settings("Mono8"));
  ASSERT_TRUE(camera.WaitFrame(3000).ok());
  ScopedControl inject(raw_, "Inject V4L2_BUF_FLAG_ERROR", 1);
  bool damaged = false;
  for (int i = 0; i < 8 && !damaged; ++i) {  // queued good buffers may come first
    const auto frame = camera.WaitFrame(3000);
    if (frame.ok()) continue;
    damaged = true;
    EXPECT_EQ(frame.status().code(), StatusCode::kDataLoss) << frame.status().ToString();
    EXPECT_NE(frame.status().message().find("damaged"), std::string::npos);
  }
  EXPECT_TRUE(damaged);
  EXPECT_EQ(camera.statistics().corrupt, 1u);
  // The buffer went back to the driver: streaming goes on.
  EXPECT_TRUE(camera.WaitFrame(3000).ok());
}

TEST_F(VividTest, FatalQueueErrorIsUnavailableUntilRestarted) {
  V4l2Camera camera("vivid", Options());
  StartCamera(&camera, Settings("Mono8"));
  ASSERT_TRUE(camera.WaitFrame(3000).ok());
  {
    ScopedControl inject(raw_, "Inject Fatal Streaming Error", 1);
    const auto frame = camera.WaitFrame(3000);
    EXPECT_EQ(frame.status().code(), StatusCode::kUnavailable) << frame.status().ToString();
    EXPECT_NE(frame.status().message().find(kDevice), std::string::npos);
  }
  EXPECT_TRUE(camera.Stop().ok());
  ASSERT_TRUE(camera.Start().ok());
  const auto frame = camera.WaitFrame(3000);
  EXPECT_TRUE(frame.ok()) << frame.status().ToString();
}

}  // namespace
}  // namespace photorig
