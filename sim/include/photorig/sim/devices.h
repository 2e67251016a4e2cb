#pragma once
// Simulated devices behind the same interfaces as the real drivers.

#include "photorig/drivers/camera.h"
#include "photorig/drivers/light_controller.h"
#include "photorig/drivers/trigger_output.h"
#include "photorig/sim/world.h"

#include <deque>
#include <memory>
#include <mutex>
#include <set>

namespace photorig::sim {

class SimLightDome : public drivers::LightController {
 public:
  SimLightDome(std::string id, std::shared_ptr<World> world);
  int channel_count() const override;

 protected:
  Status DoOpen() override;
  Status DoSetPattern(const drivers::LightPattern& pattern) override;
  Result<drivers::LightPattern> DoReadBack() override;
  Status DoClose() override;

 private:
  std::shared_ptr<World> world_;
  std::uint64_t commands_ = 0;
};

// Renders a frame from the world's current state on every trigger: a
// software trigger, or with TriggerMode::kHardware a pulse on the world's
// trigger wire (SimTriggerLine) while streaming.
class SimCamera : public drivers::Camera {
 public:
  SimCamera(std::string id, std::shared_ptr<World> world);
  ~SimCamera() override;

 protected:
  Status DoOpen() override;
  Result<std::vector<drivers::SettingAdjustment>> DoConfigure(drivers::CameraSettings* settings) override;
  Status DoStart() override;
  Status DoTrigger() override;
  Result<drivers::Frame> DoWaitFrame(int timeout_ms) override;
  Status DoStop() override;
  Status DoClose() override;

 private:
  Status Capture();
  std::string SensorPixelFormat() const;

  std::shared_ptr<World> world_;
  std::mutex frames_mutex_;  // a hardware pulse arrives on the trigger output's thread
  std::deque<drivers::Frame> ready_;
  std::uint64_t next_frame_id_ = 0;  // device counter: a dropped frame leaves a gap
  std::uint64_t triggers_ = 0;       // lifetime count, indexes CameraFaults
  bool link_lost_ = false;
  std::set<std::uint64_t> corrupt_ids_;
  std::vector<std::uint16_t> last_pixels_;  // what CameraFaults::repeat_frames delivers again
};

// The simulated rig's trigger output: each Fire pulses the world's trigger
// wire, so an armed SimCamera takes a frame. A pulse no camera hears is
// reported as an error here, where a real output could not know.
class SimTriggerLine : public drivers::TriggerOutput {
 public:
  SimTriggerLine(std::string id, std::shared_ptr<World> world);
  ~SimTriggerLine() override;

 protected:
  Status DoOpen() override { return Status::Ok(); }
  Status DoFire(std::chrono::microseconds width) override;
  Status DoClose() override { return Status::Ok(); }

 private:
  std::shared_ptr<World> world_;
};

}  // namespace photorig::sim
