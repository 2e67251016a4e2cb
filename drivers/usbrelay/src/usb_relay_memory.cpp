#include "photorig/drivers/usbrelay/internal/usb_relay_memory.h"

namespace photorig::drivers {

InMemoryRelayBoard::InMemoryRelayBoard(std::string serial, int relays) : serial_(std::move(serial)), relays_(relays) {}

Status InMemoryRelayBoard::SetFeature(const usb_relay::Report& report) {
  std::lock_guard lock(mutex_);
  received_.push_back(report);
  const std::uint8_t all = static_cast<std::uint8_t>((1u << relays_) - 1);
  const int relay = report[1];
  const bool valid_relay = relay >= 1 && relay <= relays_;
  switch (report[0]) {
    case 0xFF: if (valid_relay) states_ |= static_cast<std::uint8_t>(1u << (relay - 1)); break;
    case 0xFD: if (valid_relay) states_ &= static_cast<std::uint8_t>(~(1u << (relay - 1))); break;
    case 0xFE: states_ = all; break;
    case 0xFC: states_ = 0; break;
    default: break;  // the firmware ignores unknown commands
  }
  states_ &= static_cast<std::uint8_t>(~stuck_off_mask_);
  return Status::Ok();
}

Result<usb_relay::Report> InMemoryRelayBoard::GetFeature() {
  std::lock_guard lock(mutex_);
  usb_relay::Report report{};
  for (std::size_t i = 0; i < 5 && i < serial_.size(); ++i) report[i] = static_cast<std::uint8_t>(serial_[i]);
  report[7] = states_;
  return report;
}

std::uint8_t InMemoryRelayBoard::states() const {
  std::lock_guard lock(mutex_);
  return states_;
}

std::vector<usb_relay::Report> InMemoryRelayBoard::received() const {
  std::lock_guard lock(mutex_);
  return received_;
}

}  // namespace photorig::drivers
