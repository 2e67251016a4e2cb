#include "photorig/drivers/motion/modbus_drive.h"

#include <algorithm>
#include <cmath>

namespace photorig::drivers {
namespace drive_profile {

const char* DriveFaultText(std::uint16_t code) {
  switch (code) {
    case kNoFault: return "";
    case kFollowingError: return "following error";
    case kLimitSwitch: return "limit switch";
    case kOverTemperature: return "over temperature";
  }
  return "unknown drive fault";
}

void EncodeMillidegrees(double degrees, std::uint16_t* high_low) {
  const auto value = static_cast<std::uint32_t>(static_cast<std::int32_t>(std::lround(degrees * 1000.0)));
  high_low[0] = static_cast<std::uint16_t>(value >> 16);
  high_low[1] = static_cast<std::uint16_t>(value & 0xFFFFu);
}

double DecodeMillidegrees(const std::uint16_t* high_low) {
  const std::uint32_t value = (static_cast<std::uint32_t>(high_low[0]) << 16) | high_low[1];
  return static_cast<std::int32_t>(value) / 1000.0;
}

}  // namespace drive_profile

namespace dp = drive_profile;

ModbusDriveAxis::ModbusDriveAxis(std::string id, ModbusLinkOptions link, int base_address, AxisLimits limits,
                                 SettleOptions settle)
    : Motion(id, limits, settle), link_("axis " + id, std::move(link)), base_(base_address) {}

ModbusDriveAxis::~ModbusDriveAxis() { (void)Close(); }

Status ModbusDriveAxis::DoOpen() { return link_.Connect(); }

Status ModbusDriveAxis::Command(dp::Command command) {
  return link_.WriteRegisters(base_ + dp::kCommand, {command});
}

Status ModbusDriveAxis::DoStartHome() { return Command(dp::kHome); }

Status ModbusDriveAxis::DoStartMove(double target_deg, const MotionProfile& profile) {
  std::vector<std::uint16_t> block(dp::kCommand + 1);
  dp::EncodeMillidegrees(target_deg, &block[dp::kTarget]);
  auto tenths = [](double value) {
    return static_cast<std::uint16_t>(std::clamp(std::lround(value * 10.0), 1L, 65535L));
  };
  block[dp::kVelocity] = tenths(profile.velocity_deg_s);
  block[dp::kAcceleration] = tenths(profile.acceleration_deg_s2);
  block[dp::kCommand] = dp::kMove;
  return link_.WriteRegisters(base_, block);
}

Result<AxisStatus> ModbusDriveAxis::DoReadStatus() {
  auto read = link_.ReadRegisters(base_ + dp::kStatus, dp::kRegisterCount - dp::kStatus);
  if (!read.ok()) return read.status();
  const std::vector<std::uint16_t>& r = read.value();
  const std::uint16_t bits = r[0];
  AxisStatus status;
  status.busy = bits & dp::kBusy;
  status.homed = bits & dp::kHomed;
  status.fault = bits & dp::kFault;
  status.limit_low = bits & dp::kLimitLow;
  status.limit_high = bits & dp::kLimitHigh;
  status.position_deg = dp::DecodeMillidegrees(&r[dp::kPosition - dp::kStatus]);
  status.fault_text = dp::DriveFaultText(r[dp::kFaultCode - dp::kStatus]);
  return status;
}

Status ModbusDriveAxis::DoStop() { return Command(dp::kStop); }
Status ModbusDriveAxis::DoClearFault() { return Command(dp::kClearFault); }

Status ModbusDriveAxis::DoClose() {
  link_.Disconnect();
  return Status::Ok();
}

}  // namespace photorig::drivers
