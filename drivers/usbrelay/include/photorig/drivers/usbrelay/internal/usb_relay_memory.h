#pragma once
// An in-memory USB relay board behind the HidTransport seam: it decodes the
// feature reports the way the board's firmware does and keeps every report it
// received, so tests can check both the relay states and the traffic.

#include "photorig/drivers/usbrelay/usb_relay.h"

#include <mutex>

namespace photorig::drivers {

class InMemoryRelayBoard : public HidTransport {
 public:
  InMemoryRelayBoard(std::string serial, int relays);
  Status SetFeature(const usb_relay::Report& report) override;
  Result<usb_relay::Report> GetFeature() override;
  std::uint8_t states() const;
  std::vector<usb_relay::Report> received() const;
  void set_stuck_off(int relay) { stuck_off_mask_ |= static_cast<std::uint8_t>(1u << (relay - 1)); }

 private:
  mutable std::mutex mutex_;
  std::string serial_;
  int relays_;
  std::uint8_t states_ = 0;
  std::uint8_t stuck_off_mask_ = 0;
  std::vector<usb_relay::Report> received_;
};

}  // namespace photorig::drivers
