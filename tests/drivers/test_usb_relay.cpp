// The USB HID relay protocol at the transport seam, against an in-memory
// board that decodes feature reports like the board's firmware.

#include "photorig/drivers/usbrelay/internal/usb_relay_memory.h"

#include <gtest/gtest.h>

namespace photorig::drivers {
namespace {

using usb_relay::Report;

// The controller owns its transport and drops it on Close; the test keeps the
// board itself alive to inspect it afterwards.
struct Forward : HidTransport {
  std::shared_ptr<InMemoryRelayBoard> board;
  explicit Forward(std::shared_ptr<InMemoryRelayBoard> b) : board(std::move(b)) {}
  Status SetFeature(const Report& report) override { return board->SetFeature(report); }
  Result<Report> GetFeature() override { return board->GetFeature(); }
};

struct Board {
  std::shared_ptr<InMemoryRelayBoard> board;
  std::unique_ptr<UsbRelayLightController> lights;
  Board(int relays, int channels) : board(std::make_shared<InMemoryRelayBoard>("QWE12", relays)) {
    lights = std::make_unique<UsbRelayLightController>(
        "relays", channels,
        [b = board]() -> Result<std::unique_ptr<HidTransport>> { return std::unique_ptr<HidTransport>(new Forward(b)); },
        relays);
  }
};

TEST(UsbRelay, ReportEncoding) {
  EXPECT_EQ(usb_relay::On(3), (Report{0xFF, 3, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(usb_relay::Off(1), (Report{0xFD, 1, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(usb_relay::AllOn()[0], 0xFE);
  EXPECT_EQ(usb_relay::AllOff()[0], 0xFC);
  const Report state{'A', 'B', 'C', 'D', 'E', 0, 0, 0b101};
  EXPECT_EQ(usb_relay::SerialOf(state), "ABCDE");
  EXPECT_EQ(usb_relay::StatesOf(state), 0b101);
}

TEST(UsbRelay, SetsChannelsWithTheFewestReportsAndReadsState) {
  Board b(4, 4);
  ASSERT_TRUE(b.lights->Open().ok());
  auto count = [&] { return b.board->received().size(); };
  const std::size_t opened = count();  // Open starts dark; nothing was on, so no report needed
  EXPECT_EQ(opened, 0u);
  ASSERT_TRUE(b.lights->SetPattern({{1, 0, 0.5, 0}}).ok());
  EXPECT_EQ(b.board->states(), 0b0101);
  auto sent = b.board->received();
  ASSERT_EQ(sent.size(), 2u);
  EXPECT_EQ(sent[0], usb_relay::On(1));
  EXPECT_EQ(sent[1], usb_relay::On(3));
  ASSERT_TRUE(b.lights->SetPattern({{1, 1, 1, 1}}).ok());
  EXPECT_EQ(b.board->received().back(), usb_relay::AllOn());
  EXPECT_EQ(b.board->received().size(), 3u);
  ASSERT_TRUE(b.lights->SetPattern({{1, 1, 0, 1}}).ok());
  EXPECT_EQ(b.board->received().back(), usb_relay::Off(3));
  auto back = b.lights->ReadBack();
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->levels, (std::vector<double>{1, 1, 0, 1}));
  ASSERT_TRUE(b.lights->Close().ok());
  EXPECT_EQ(b.board->received().back(), usb_relay::AllOff());
  EXPECT_EQ(b.board->states(), 0);
}

TEST(UsbRelay, FewerLedsThanRelaysLeavesTheRestAlone) {
  Board b(8, 2);
  ASSERT_TRUE(b.lights->Open().ok());
  ASSERT_TRUE(b.lights->SetPattern({{1, 1}}).ok());
  // All-on for 2 LEDs must not close relays 3..8.
  EXPECT_EQ(b.board->states(), 0b11);
}

TEST(UsbRelay, StuckRelayIsReportedWithTheBoardSerial) {
  Board b(2, 2);
  b.board->set_stuck_off(2);
  ASSERT_TRUE(b.lights->Open().ok());
  const Status status = b.lights->SetPattern({{0, 1}});
  EXPECT_EQ(status.code(), StatusCode::kDataLoss);
  EXPECT_NE(status.message().find("QWE12"), std::string::npos) << status.message();
  EXPECT_NE(status.message().find("relay 2 reads off"), std::string::npos) << status.message();
}

TEST(UsbRelay, MissingBoardFailsOpenClearly) {
  UsbRelayLightController lights("relays", 2, [] { return OpenUsbRelayBoard("NOPE1"); });
  const Status status = lights.Open();
  EXPECT_FALSE(status.ok());
  EXPECT_NE(status.message().find("light controller relays"), std::string::npos) << status.message();
}

}  // namespace
}  // namespace photorig::drivers
