#pragma once
// Faults the simulated devices inject on purpose, so the sequencer's and the
// daemon's recovery paths run in tests exactly as they would on hardware.
// Indices count triggers (camera) or pattern commands (lights) from 0 since
// the device was created, so a fault fires once even across reopen.

#include <cstdint>
#include <map>
#include <set>

namespace photorig::sim {

struct CameraFaults {
  std::set<std::uint64_t> drop_frames;     // the trigger yields no frame: WaitFrame times out
  std::set<std::uint64_t> short_frames;    // half the pixels arrive; Camera::WaitFrame reports kDataLoss
  std::set<std::uint64_t> corrupt_frames;  // damaged payload, reported as kDataLoss (as a buffer status would)
  std::set<std::uint64_t> disconnect_at;   // the link drops at this trigger: kUnavailable until Close + Open
  // The trigger delivers the previous frame's pixels again under a new frame
  // id, as a driver that hands out a stale buffer: only the data can tell.
  std::set<std::uint64_t> repeat_frames;
  bool lens_cap = false;                   // no light reaches the sensor: every frame is black level and noise
};

struct AxisFaults {
  // Moves (1-based, counting every move the axis was asked for) the drive
  // does not acknowledge: kUnavailable, as when a fieldbus command is lost.
  // The axis then sits in Fault until it is cleared and homed again.
  std::set<std::uint64_t> refused_moves;
};

struct LightFaults {
  std::set<std::uint64_t> fail_commands;   // SetPattern returns kUnavailable (e.g. a Modbus timeout)
  std::set<int> stuck_off_channels;        // these LEDs never light, whatever is commanded
  // Channel -> fraction of its light the LED emits (0: dead) while the
  // controller accepts and reads back every command: a burnt-out LED or a
  // broken wire after the driver, which only the frames reveal.
  std::map<int, double> dim_channels;
};

}  // namespace photorig::sim
