#pragma once
// Video4Linux2 capture devices (/dev/videoN): USB/UVC cameras, frame grabbers
// and the kernel's vivid test driver.
//
// Configure sets the format (GREY, Y10, Y12, Y16, YUYV luma; picked from the
// bit depth or named by CameraSettings::pixel_format as a GenICam or V4L2
// name), manual exposure through V4L2_CID_EXPOSURE_ABSOLUTE (100 us units) and
// gain through V4L2_CID_GAIN, reading each back. Start maps a bounded pool of
// buffers (REQBUFS/QBUF/STREAMON). V4L2 has no trigger: in software-trigger
// mode the device streams and WaitFrame delivers the first frame whose
// exposure started after Trigger() (a device without an exposure control is
// taken to expose for its whole frame period); hardware triggers are refused.
// Gaps in the buffer sequence numbers, from the first delivered frame on, are
// counted as dropped frames. A device another handle is streaming from is
// kUnavailable ("busy").

#include "photorig/drivers/camera.h"

#include <cstdint>
#include <string>
#include <vector>

namespace photorig::drivers {

struct V4l2CameraOptions {
  std::string device = "/dev/video0";
  int buffer_count = 4;  // mmap buffers; the driver may grant more or fewer

  bool IsValid(std::string* why) const;
};

class V4l2Camera : public Camera {
 public:
  struct Statistics {
    std::uint64_t frames = 0;
    std::uint64_t dropped = 0;    // gaps in the sequence numbers
    std::uint64_t corrupt = 0;    // buffers flagged V4L2_BUF_FLAG_ERROR or short
    std::uint64_t timeouts = 0;
    std::uint64_t stale = 0;      // frames discarded because they began before the trigger
  };

  V4l2Camera(std::string id, V4l2CameraOptions options);
  ~V4l2Camera() override;

  const Statistics& statistics() const { return stats_; }
  // From VIDIOC_QUERYCAP once open: "vivid", "uvcvideo", ...
  const std::string& driver_name() const { return driver_name_; }
  const std::string& card() const { return card_; }

 protected:
  Status DoOpen() override;
  Result<std::vector<SettingAdjustment>> DoConfigure(CameraSettings* settings) override;
  Status DoStart() override;
  Status DoTrigger() override;
  Result<Frame> DoWaitFrame(int timeout_ms) override;
  Status DoStop() override;
  Status DoClose() override;

 private:
  struct Mapping {
    void* start = nullptr;
    std::size_t length = 0;
  };
  Status Errno(StatusCode code, const std::string& what) const;
  Status Fail(StatusCode code, const std::string& what) const;
  void ReleaseBuffers();

  V4l2CameraOptions options_;
  int fd_ = -1;
  std::string driver_name_, card_;
  std::uint32_t fourcc_ = 0;
  std::uint32_t bytes_per_line_ = 0;
  bool has_exposure_control_ = false;
  std::int64_t frame_period_ns_ = 0;  // from VIDIOC_G_PARM at Start; 0 = unknown
  std::vector<Mapping> buffers_;
  bool have_sequence_ = false;
  std::uint32_t last_sequence_ = 0;
  std::int64_t trigger_time_ns_ = -1;  // CLOCK_MONOTONIC of the last Trigger(); -1 = none pending
  Statistics stats_;
};

// Capture devices among the video* nodes of `device_directory`, with formats,
// largest frame size and exposure range. Nodes that do not answer
// VIDIOC_QUERYCAP as a single-planar capture device are left out; nodes that
// cannot be opened are listed with the reason in CameraInfo::error.
std::vector<CameraInfo> DiscoverV4l2Cameras(const std::string& device_directory = "/dev");

}  // namespace photorig::drivers
