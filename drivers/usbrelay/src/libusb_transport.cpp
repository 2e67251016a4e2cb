// HidTransport over libusb-1.0: HID class SET_REPORT / GET_REPORT control
// transfers for feature report 0 on interface 0.
#include "photorig/drivers/usbrelay/usb_relay.h"

#include <libusb.h>

#include <cstdlib>

namespace photorig::drivers {
namespace {

constexpr int kTimeoutMs = 500;
constexpr std::uint16_t kFeatureReport0 = 0x0300;
// bmRequestType: class request to the interface, host-to-device / device-to-host.
constexpr std::uint8_t kHostToInterface = 0x21, kInterfaceToHost = 0xA1;

Status UsbError(const std::string& what, int code) {
  return {StatusCode::kUnavailable,
          "USB relay: " + what + ": " + libusb_strerror(static_cast<libusb_error>(code))};
}

class LibusbHidTransport : public HidTransport {
 public:
  LibusbHidTransport(libusb_context* context, libusb_device_handle* handle) : context_(context), handle_(handle) {}
  ~LibusbHidTransport() override {
    libusb_release_interface(handle_, 0);
    libusb_close(handle_);
    libusb_exit(context_);
  }

  Status SetFeature(const usb_relay::Report& report) override {
    usb_relay::Report data = report;
    const int sent = libusb_control_transfer(
        handle_, kHostToInterface, 0x09 /* SET_REPORT */,
        kFeatureReport0, 0, data.data(), data.size(), kTimeoutMs);
    return sent == static_cast<int>(data.size()) ? Status::Ok() : UsbError("SET_FEATURE", sent);
  }

  Result<usb_relay::Report> GetFeature() override {
    usb_relay::Report data{};
    const int got = libusb_control_transfer(
        handle_, kInterfaceToHost, 0x01 /* GET_REPORT */,
        kFeatureReport0, 0, data.data(), data.size(), kTimeoutMs);
    if (got != static_cast<int>(data.size())) return UsbError("GET_FEATURE", got);
    return data;
  }

 private:
  libusb_context* context_;
  libusb_device_handle* handle_;
};

// Calls `visit` with each relay board opened and claimed; it returns true to keep the handle.
Status ForEachBoard(libusb_context* context,
                    const std::function<bool(libusb_device_handle*, const UsbRelayBoardInfo&)>& visit) {
  libusb_device** list = nullptr;
  const ssize_t count = libusb_get_device_list(context, &list);
  if (count < 0) return UsbError("list devices", static_cast<int>(count));
  for (ssize_t i = 0; i < count; ++i) {
    libusb_device_descriptor descriptor{};
    if (libusb_get_device_descriptor(list[i], &descriptor) != 0) continue;
    if (descriptor.idVendor != usb_relay::kVendorId || descriptor.idProduct != usb_relay::kProductId) continue;
    libusb_device_handle* handle = nullptr;
    if (libusb_open(list[i], &handle) != 0) continue;
    unsigned char product[64] = {};
    libusb_get_string_descriptor_ascii(handle, descriptor.iProduct, product, sizeof(product));
    const std::string name(reinterpret_cast<char*>(product));
    libusb_set_auto_detach_kernel_driver(handle, 1);
    if (name.rfind("USBRelay", 0) != 0 || libusb_claim_interface(handle, 0) != 0) {
      libusb_close(handle);
      continue;
    }
    UsbRelayBoardInfo info;
    info.relays = std::atoi(name.c_str() + 8);
    info.bus = libusb_get_bus_number(list[i]);
    info.address = libusb_get_device_address(list[i]);
    usb_relay::Report state{};
    if (libusb_control_transfer(handle, kInterfaceToHost,
                                0x01, kFeatureReport0, 0, state.data(), state.size(), kTimeoutMs) == 8)
      info.serial = usb_relay::SerialOf(state);
    if (!visit(handle, info)) {
      libusb_release_interface(handle, 0);
      libusb_close(handle);
    }
  }
  libusb_free_device_list(list, 1);
  return Status::Ok();
}

}  // namespace

Result<std::vector<UsbRelayBoardInfo>> EnumerateUsbRelayBoards() {
  libusb_context* context = nullptr;
  if (int rc = libusb_init(&context); rc != 0) return UsbError("init", rc);
  std::vector<UsbRelayBoardInfo> boards;
  Status status = ForEachBoard(context, [&](libusb_device_handle*, const UsbRelayBoardInfo& info) {
    boards.push_back(info);
    return false;
  });
  libusb_exit(context);
  if (!status.ok()) return status;
  return boards;
}

Result<std::unique_ptr<HidTransport>> OpenUsbRelayBoard(const std::string& serial) {
  libusb_context* context = nullptr;
  if (int rc = libusb_init(&context); rc != 0) return UsbError("init", rc);
  libusb_device_handle* chosen = nullptr;
  std::vector<std::string> seen;
  Status status = ForEachBoard(context, [&](libusb_device_handle* handle, const UsbRelayBoardInfo& info) {
    seen.push_back(info.serial);
    if (chosen || !(serial.empty() || info.serial == serial)) return false;
    chosen = handle;
    return true;
  });
  if (status.ok() && chosen && serial.empty() && seen.size() > 1) {
    libusb_release_interface(chosen, 0);
    libusb_close(chosen);
    chosen = nullptr;
    status = {StatusCode::kInvalidArgument, "USB relay: several boards present; name one by serial"};
  }
  if (!status.ok() || !chosen) {
    libusb_exit(context);
    if (!status.ok()) return status;
    std::string found;
    for (const auto& s : seen) found += (found.empty() ? "" : ", ") + s;
    return Status{StatusCode::kUnavailable, "USB relay: no board with serial '" + serial + "' (found: " +
                                                (found.empty() ? "none" : found) + ")"};
  }
  return std::unique_ptr<HidTransport>(std::make_unique<LibusbHidTransport>(context, chosen));
}

}  // namespace photorig::drivers
