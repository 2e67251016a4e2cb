#pragma once
// GenICam cameras (GigE Vision, USB3 Vision) through Aravis 0.8.
//
// Open finds the device by Aravis id, serial number or IP address. Configure
// picks the pixel format (MonoN for the requested bit depth, or the named
// format), exposure (ExposureTime or ExposureTimeAbs), gain and trigger, reads
// every value back and reports what the camera rounded or clamped. Start
// allocates a bounded pool of stream buffers; frames arrive as 16-bit samples.
//
// Losses are reported, never hidden: a buffer with missing packets or a short
// payload is kDataLoss, and gaps in the device's frame counter are counted in
// Frame::dropped_before and in statistics(). When the control link is lost
// (the device stopped answering or another host took control) the driver
// reopens the device with bounded retries, re-applies the settings, restarts
// the stream and re-issues a pending software trigger.

#include "photorig/drivers/camera.h"

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>
#include <vector>

namespace photorig::drivers {

struct AravisCameraOptions {
  // Aravis device id ("Aravis-Fake-GV01"), serial number or IP address.
  // Empty: the only camera found (an error when there are several).
  std::string device;
  int buffer_count = 4;               // stream buffers; a frame arriving while all are full is dropped
  double link_bandwidth_mbps = 1000;  // estimates readout time for the frame timeout
  int timeout_margin_ms = 200;        // added to exposure + readout
  bool packet_resend = true;          // GigE Vision: ask the camera to resend lost packets
  // GigE Vision: receive through a kernel packet ring (needs CAP_NET_RAW) instead of the UDP socket.
  // Off by default: the ring is attached by the stream's own thread after acquisition starts, so a
  // frame triggered at once can pass before it exists and is lost; the UDP socket is bound first and
  // queues it. Worth turning on only for free-running streams near the link's bandwidth.
  bool packet_socket = false;
  int reconnect_attempts = 3;         // after the control link is lost
  int reconnect_delay_ms = 250;       // between attempts

  bool IsValid(std::string* why) const;
};

class AravisCamera : public Camera {
 public:
  struct Statistics {
    std::uint64_t frames = 0;        // delivered complete
    std::uint64_t dropped = 0;       // gaps in the device frame counter
    std::uint64_t incomplete = 0;    // buffers with missing packets, wrong size, ...
    std::uint64_t timeouts = 0;
    std::uint64_t reconnects = 0;    // successful recoveries of the control link
  };

  AravisCamera(std::string id, AravisCameraOptions options);
  ~AravisCamera() override;

  const Statistics& statistics() const { return stats_; }
  // Aravis id of the opened device ("" while closed).
  const std::string& device_id() const { return device_id_; }
  // Bound on the wait for one frame: exposure + readout + margin.
  int FrameTimeoutMs() const;

 protected:
  Status DoOpen() override;
  Result<std::vector<SettingAdjustment>> DoConfigure(CameraSettings* settings) override;
  Status DoStart() override;
  Status DoTrigger() override;
  Result<Frame> DoWaitFrame(int timeout_ms) override;
  Status DoStop() override;
  Status DoClose() override;

 private:
  struct Handles;

  Status Connect();
  void Disconnect();
  void Abandon();  // drops a device that stopped answering without waiting for it
  Status StartStream();
  void StopStream();
  bool LinkLost();
  Status Reconnect();
  Result<Frame> PopFrame(int timeout_ms);
  Status Error(StatusCode code, const std::string& what) const;

  AravisCameraOptions options_;
  std::unique_ptr<Handles> handles_;
  std::shared_ptr<std::atomic<bool>> control_lost_;
  std::string device_id_;
  CameraSettings applied_;         // last settings the device accepted
  bool configured_ = false;
  bool streaming_ = false;
  bool trigger_pending_ = false;   // software trigger sent, frame not yet delivered
  bool have_last_frame_id_ = false;
  std::uint64_t last_frame_id_ = 0;
  std::size_t payload_bytes_ = 0;
  Statistics stats_;
  std::vector<std::thread> graveyard_;  // releases of abandoned devices, joined on destruction
};

// Every GenICam camera Aravis can see. With `details`, opens each one briefly
// to read sensor size, pixel formats and exposure range (a camera another
// host controls reports why in CameraInfo::error).
std::vector<CameraInfo> DiscoverAravisCameras(bool details);

}  // namespace photorig::drivers
