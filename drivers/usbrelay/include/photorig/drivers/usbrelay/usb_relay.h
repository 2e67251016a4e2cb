#pragma once
// The common USB HID relay boards (VID 16c0, PID 05df, product "USBRelayN"),
// driving LEDs through their relays. Protocol, as 8-byte HID feature reports
// (report id 0):
//   SET_FEATURE [0xFF, n] relay n (1-based) on   [0xFD, n] relay n off
//               [0xFE]    all on                 [0xFC]    all off
//   GET_FEATURE bytes 0..4 the board's serial (ASCII), byte 7 the relay
//               states, bit n-1 = relay n.
// HidTransport is the seam: LibusbHidTransport speaks to the board through
// libusb-1.0 control transfers; InMemoryRelayBoard (internal/usb_relay_memory.h)
// decodes the reports like the board's firmware, for tests.

#include "photorig/drivers/light_controller.h"

#include <array>
#include <functional>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace photorig::drivers {

namespace usb_relay {
inline constexpr std::uint16_t kVendorId = 0x16c0, kProductId = 0x05df;
inline constexpr int kReportBytes = 8;
using Report = std::array<std::uint8_t, kReportBytes>;
Report On(int relay);
Report Off(int relay);
Report AllOn();
Report AllOff();
std::string SerialOf(const Report& state);
std::uint8_t StatesOf(const Report& state);
}  // namespace usb_relay

class HidTransport {
 public:
  virtual ~HidTransport() = default;
  virtual Status SetFeature(const usb_relay::Report& report) = 0;
  virtual Result<usb_relay::Report> GetFeature() = 0;
};

struct UsbRelayBoardInfo {
  std::string serial;
  int relays = 0;  // from the product string "USBRelayN"
  int bus = 0, address = 0;
};

// Every board on the bus (needs read/write access to the USB device nodes).
Result<std::vector<UsbRelayBoardInfo>> EnumerateUsbRelayBoards();
// Opens the board with this serial (or the only board, if serial is empty).
Result<std::unique_ptr<HidTransport>> OpenUsbRelayBoard(const std::string& serial);

// One relay per LED (LED i on relay i+1); a level > 0 closes it. All-off is
// used for a dark pattern (relays beyond the LEDs open too: the safe side). The
// transport is opened lazily by the factory given here, so Open names the
// device when the board is missing.
class UsbRelayLightController : public LightController {
 public:
  using Opener = std::function<Result<std::unique_ptr<HidTransport>>()>;
  // `board_relays`: the board's relay count when known; only then may all-on
  // (which closes every relay on the board) stand in for per-relay reports.
  UsbRelayLightController(std::string id, int channels, Opener opener, int board_relays = 0);
  ~UsbRelayLightController() override;
  int channel_count() const override { return channels_; }

 protected:
  Status DoOpen() override;
  Status DoSetPattern(const LightPattern& pattern) override;
  Result<LightPattern> DoReadBack() override;
  Status DoClose() override;

 private:
  int channels_;
  int board_relays_;
  Opener opener_;
  std::unique_ptr<HidTransport> transport_;
};

}  // namespace photorig::drivers
