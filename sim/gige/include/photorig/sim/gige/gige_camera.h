#pragma once
// A GigE Vision camera on the loopback interface whose frames are rendered
// from a sim::World: Aravis' fake GV camera speaks the real GVCP/GVSP
// protocols, and its fill callback exposes the World's current radiance (the
// lights the simulated dome set) through the sensor model. The real Aravis
// driver then captures from it exactly as from hardware.
//
// The fake offers Mono8, Mono10, Mono12 and Mono16 (16-bit samples for the
// wider ones), ExposureTimeAbs in 1 us steps and GainRaw 0..10, rendered as
// that many dB. Frame ids are 16-bit and start near the wrap (65400).

#include "photorig/drivers/aravis/aravis_camera.h"
#include "photorig/drivers/status.h"
#include "photorig/sim/world.h"

#include <cstdint>
#include <memory>
#include <string>

namespace photorig::sim {

struct GigeFakeCameraOptions {
  std::string address = "127.0.0.1";  // an address of a local interface; GVCP listens on its port 3956
  std::string serial = "SIMGV0";
  double lost_packet_ratio = 0.0;     // fraction of GVSP packets the camera never sends, in [0, 1)
  double trigger_poll_hz = 500.0;     // how often the camera looks for a software trigger (Aravis' own default: 25)

  bool IsValid(std::string* why) const;
};

class GigeFakeCamera {
 public:
  // Listens until destroyed. kUnavailable when the address is not a local
  // interface or another camera already listens there.
  static Result<std::unique_ptr<GigeFakeCamera>> Start(std::shared_ptr<World> world, GigeFakeCameraOptions options);
  ~GigeFakeCamera();
  GigeFakeCamera(const GigeFakeCamera&) = delete;
  GigeFakeCamera& operator=(const GigeFakeCamera&) = delete;

  const GigeFakeCameraOptions& options() const;
  std::uint64_t frames_rendered() const;

 private:
  struct Impl;
  explicit GigeFakeCamera(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// The Aravis driver pointed at a GigeFakeCamera it starts on Open and stops
// on Close: a simulated rig that still captures over real GigE Vision.
class AravisCameraOnGigeFake : public drivers::AravisCamera {
 public:
  AravisCameraOnGigeFake(std::string id, drivers::AravisCameraOptions camera_options, std::shared_ptr<World> world,
                         GigeFakeCameraOptions fake_options);
  ~AravisCameraOnGigeFake() override;

 protected:
  Status DoOpen() override;
  Status DoClose() override;

 private:
  std::shared_ptr<World> world_;
  GigeFakeCameraOptions fake_options_;
  std::unique_ptr<GigeFakeCamera> fake_;
};

}  // namespace photorig::sim
