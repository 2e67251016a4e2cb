#pragma once
// LEDs and camera trigger lines on GPIO (libgpiod 1.6, the character-device
// API Debian 12 ships). Lines are named by chip ("gpiochip0" or a path) and
// offset. Values here are logical (1 = LED lit / trigger asserted); the
// driver applies active-low itself, so a backend only ever sees physical
// levels. All lines of one chip are set with one bulk call; closing drives
// every line off before releasing it, so a released dome is dark.
//
// A process that dies without closing cannot do that: the kernel releases
// its lines, and a released line is no longer controlled (its uAPI says it
// "may revert to its default state"; many chips keep the last value, so a
// lit LED stays lit). GPIO itself has no watchdog. The dead-man is therefore
// outside the chip: an optional heartbeat line that KeepAlive toggles (the
// safety layer calls it every 250 ms while the process lives), wired to a
// retriggerable watchdog (a supervisor's WDI input, a retriggerable
// monostable) that enables the LED supply only while the edges keep coming.
// See docs/lights-and-motion.md for the wiring.
//
// GpioBackend is the seam around the libgpiod calls: the real one talks to
// /dev/gpiochipN; InMemoryGpioChips (internal/gpio_memory.h) emulates the
// kernel side for tests, since Debian's kernel has neither gpio-sim nor
// gpio-mockup.

#include "photorig/drivers/light_controller.h"
#include "photorig/drivers/trigger_output.h"

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace photorig::drivers {

struct GpioLine {
  std::string chip;      // "gpiochip0", "/dev/gpiochip0" or a chip label
  unsigned offset = 0;
  bool active_low = false;
};

// Physical levels, one per requested line, in request order.
class GpioBackend {
 public:
  virtual ~GpioBackend() = default;
  // Requests the lines as outputs driven to `initial` from the start.
  virtual Status Request(const std::string& consumer, const std::vector<GpioLine>& lines,
                         const std::vector<int>& initial) = 0;
  virtual Status Set(const std::vector<int>& physical) = 0;
  virtual Result<std::vector<int>> Get() = 0;
  virtual void Release() = 0;
};

std::unique_ptr<GpioBackend> MakeLibgpiodBackend();

// One line per LED; a level > 0 lights it (GPIO has no intensity). With a
// `heartbeat` line, it is requested with the LEDs (logical 0 at Open) and
// each KeepAlive inverts it.
class GpioLightController : public LightController {
 public:
  GpioLightController(std::string id, std::vector<GpioLine> lines, std::unique_ptr<GpioBackend> backend,
                      std::optional<GpioLine> heartbeat = std::nullopt);
  ~GpioLightController() override;
  int channel_count() const override { return static_cast<int>(leds_); }

 protected:
  Status DoOpen() override;
  Status DoSetPattern(const LightPattern& pattern) override;
  Result<LightPattern> DoReadBack() override;
  Status DoClose() override;
  Status DoKeepAlive() override;

 private:
  Status Drive();  // every line to `logical_`

  std::size_t leds_;
  std::vector<GpioLine> lines_;  // the LEDs', then the heartbeat's if any
  bool has_heartbeat_;
  std::vector<int> logical_;  // what each line of `lines_` is driven to
  std::unique_ptr<GpioBackend> backend_;
};

// A camera hardware-trigger output on one line: Fire asserts it for `width`.
class GpioTriggerLine : public TriggerOutput {
 public:
  GpioTriggerLine(std::string id, GpioLine line, std::unique_ptr<GpioBackend> backend);
  ~GpioTriggerLine() override;

 protected:
  Status DoOpen() override;
  Status DoFire(std::chrono::microseconds width) override;
  Status DoClose() override;

 private:
  GpioLine line_;
  std::unique_ptr<GpioBackend> backend_;
};

}  // namespace photorig::drivers
