#include "photorig/drivers/usbrelay/usb_relay.h"

namespace photorig::drivers {
namespace usb_relay {

Report On(int relay) { return {0xFF, static_cast<std::uint8_t>(relay), 0, 0, 0, 0, 0, 0}; }
Report Off(int relay) { return {0xFD, static_cast<std::uint8_t>(relay), 0, 0, 0, 0, 0, 0}; }
Report AllOn() { return {0xFE, 0, 0, 0, 0, 0, 0, 0}; }
Report AllOff() { return {0xFC, 0, 0, 0, 0, 0, 0, 0}; }

std::string SerialOf(const Report& state) {
  std::string serial;
  for (int i = 0; i < 5 && state[i] != 0; ++i) serial.push_back(static_cast<char>(state[i]));
  return serial;
}

std::uint8_t StatesOf(const Report& state) { return state[7]; }

}  // namespace usb_relay

UsbRelayLightController::UsbRelayLightController(std::string id, int channels, Opener opener, int board_relays)
    : LightController(std::move(id)), channels_(channels), board_relays_(board_relays), opener_(std::move(opener)) {}

UsbRelayLightController::~UsbRelayLightController() { (void)Close(); }

Status UsbRelayLightController::DoOpen() {
  if (channels_ < 1 || channels_ > 8)
    return {StatusCode::kInvalidArgument, "light controller " + id() + ": a USB relay board has 1 to 8 relays"};
  auto opened = opener_();
  if (!opened.ok()) return {opened.status().code(), "light controller " + id() + ": " + opened.status().message()};
  transport_ = std::move(opened.value());
  return Status::Ok();
}

Status UsbRelayLightController::DoSetPattern(const LightPattern& pattern) {
  std::uint8_t wanted = 0;
  for (int i = 0; i < channels_; ++i)
    if (pattern.levels[i] > 0.0) wanted |= static_cast<std::uint8_t>(1u << i);
  auto current = transport_->GetFeature();
  if (!current.ok()) return current.status();
  const std::uint8_t all = static_cast<std::uint8_t>((1u << channels_) - 1);
  const std::uint8_t have = usb_relay::StatesOf(current.value()) & all;
  // The fewest reports: one for all-on / all-off, else one per relay that changes.
  std::vector<usb_relay::Report> reports;
  if (wanted == all && have != all && board_relays_ == channels_) reports.push_back(usb_relay::AllOn());
  else if (wanted == 0 && have != 0) reports.push_back(usb_relay::AllOff());
  else
    for (int i = 0; i < channels_; ++i) {
      const bool want = (wanted >> i) & 1u, is = (have >> i) & 1u;
      if (want != is) reports.push_back(want ? usb_relay::On(i + 1) : usb_relay::Off(i + 1));
    }
  for (const auto& report : reports)
    if (Status status = transport_->SetFeature(report); !status.ok()) return status;
  auto after = transport_->GetFeature();
  if (!after.ok()) return after.status();
  const std::uint8_t got = usb_relay::StatesOf(after.value()) & all;
  if (got != wanted)
    for (int i = 0; i < channels_; ++i)
      if (((got ^ wanted) >> i) & 1u)
        return {StatusCode::kDataLoss, "light controller " + id() + " (USB relay board " +
                                           usb_relay::SerialOf(after.value()) + "): relay " + std::to_string(i + 1) +
                                           " reads " + (((got >> i) & 1u) ? "on" : "off") + " after the command"};
  return Status::Ok();
}

Result<LightPattern> UsbRelayLightController::DoReadBack() {
  auto state = transport_->GetFeature();
  if (!state.ok()) return state.status();
  LightPattern pattern = LightPattern::AllOff(channels_);
  for (int i = 0; i < channels_; ++i) pattern.levels[i] = (usb_relay::StatesOf(state.value()) >> i) & 1u ? 1.0 : 0.0;
  return pattern;
}

Status UsbRelayLightController::DoClose() {
  transport_.reset();
  return Status::Ok();
}

}  // namespace photorig::drivers
