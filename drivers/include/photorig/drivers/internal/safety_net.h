#pragma once
// Last line of defence for devices still open when the process ends: on
// exit() (atexit) and on std::terminate, every registered device is shut down
// (lights off, motion stopped) before the process goes away. Devices register
// when they open and deregister when they close, so a clean run leaves the
// net empty. Fatal signals (SIGKILL, power loss) are beyond any software net:
// the hardware's own watchdogs cover them (docs/lights-and-motion.md).

#include <functional>

namespace photorig::drivers {

class SafetyNet {
 public:
  // `key` identifies the device (its address); `shutdown` must not throw.
  static void Add(const void* key, std::function<void()> shutdown);
  static void Remove(const void* key);
  // Runs every registered shutdown once and empties the net.
  static void ShutdownAll();
  static int size();
};

}  // namespace photorig::drivers
