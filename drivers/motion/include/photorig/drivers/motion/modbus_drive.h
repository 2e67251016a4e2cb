#pragma once
// A servo/stepper drive speaking the rig's Modbus drive profile: one block of
// holding registers per axis, starting at the axis's base address, laid out
// so a move is one write-multiple and a status poll is one read:
//
//   base+0..1  target position, int32 millidegrees, high word first   (write)
//   base+2     velocity, 0.1 deg/s                                    (write)
//   base+3     acceleration, 0.1 deg/s^2                              (write)
//   base+4     command: 0 none, 1 move, 2 home, 3 stop, 4 clear fault (write; drive resets it to 0)
//   base+5     status bits: 0 busy, 1 homed, 2 fault, 3 low limit, 4 high limit (read)
//   base+6..7  actual position, int32 millidegrees, high word first   (read)
//   base+8     fault code (see DriveFaultText)                         (read)
//
// The simulated arms in sim/modbus serve this profile.

#include "photorig/drivers/modbus/modbus_link.h"
#include "photorig/drivers/motion.h"

#include <cstdint>
#include <string>

namespace photorig::drivers {

namespace drive_profile {
inline constexpr int kTarget = 0, kVelocity = 2, kAcceleration = 3, kCommand = 4, kStatus = 5, kPosition = 6,
                     kFaultCode = 8, kRegisterCount = 9;
enum Command : std::uint16_t { kNone = 0, kMove = 1, kHome = 2, kStop = 3, kClearFault = 4 };
enum StatusBit : std::uint16_t { kBusy = 1, kHomed = 2, kFault = 4, kLimitLow = 8, kLimitHigh = 16 };
enum FaultCode : std::uint16_t { kNoFault = 0, kFollowingError = 1, kLimitSwitch = 2, kOverTemperature = 3 };

const char* DriveFaultText(std::uint16_t code);
void EncodeMillidegrees(double degrees, std::uint16_t* high_low);
double DecodeMillidegrees(const std::uint16_t* high_low);
}  // namespace drive_profile

class ModbusDriveAxis : public Motion {
 public:
  ModbusDriveAxis(std::string id, ModbusLinkOptions link, int base_address, AxisLimits limits, SettleOptions settle);
  ~ModbusDriveAxis() override;

 protected:
  Status DoOpen() override;
  Status DoStartHome() override;
  Status DoStartMove(double target_deg, const MotionProfile& profile) override;
  Result<AxisStatus> DoReadStatus() override;
  Status DoStop() override;
  Status DoClearFault() override;
  Status DoClose() override;

 private:
  Status Command(drive_profile::Command command);

  ModbusLink link_;
  int base_;
};

}  // namespace photorig::drivers
