#include "photorig/drivers/internal/safety_net.h"

#include <cstdlib>
#include <exception>
#include <map>
#include <mutex>

namespace photorig::drivers {
namespace {

struct Registry {
  std::mutex mutex;
  std::map<const void*, std::function<void()>> devices;
  std::terminate_handler previous = nullptr;
};

// Never destroyed, so the atexit handler can run after static destructors.
Registry& Get() {
  static Registry* registry = new Registry;
  return *registry;
}

void OnTerminate() {
  SafetyNet::ShutdownAll();
  if (Get().previous) Get().previous();
  std::abort();
}

void InstallOnce() {
  static std::once_flag once;
  std::call_once(once, [] {
    std::atexit([] { SafetyNet::ShutdownAll(); });
    Get().previous = std::set_terminate(OnTerminate);
  });
}

}  // namespace

void SafetyNet::Add(const void* key, std::function<void()> shutdown) {
  InstallOnce();
  std::lock_guard lock(Get().mutex);
  Get().devices[key] = std::move(shutdown);
}

void SafetyNet::Remove(const void* key) {
  std::lock_guard lock(Get().mutex);
  Get().devices.erase(key);
}

void SafetyNet::ShutdownAll() {
  std::map<const void*, std::function<void()>> devices;
  {
    std::lock_guard lock(Get().mutex);
    devices.swap(Get().devices);
  }
  for (auto& [key, shutdown] : devices) shutdown();
}

int SafetyNet::size() {
  std::lock_guard lock(Get().mutex);
  return static_cast<int>(Get().devices.size());
}

}  // namespace photorig::drivers
