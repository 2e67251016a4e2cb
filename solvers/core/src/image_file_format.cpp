#include "photorig/solvers/core/image_file_format.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string_view>
#include <system_error>

namespace photorig::solvers::core {
namespace {

bool StartsWith(std::span<const std::uint8_t> head, std::string_view magic) {
  return head.size() >= magic.size() &&
         std::equal(magic.begin(), magic.end(), head.begin(),
                    [](char m, std::uint8_t h) { return static_cast<std::uint8_t>(m) == h; });
}

bool IsSpace(std::uint8_t c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f'; }

}  // namespace

// The same tests as OpenCV's decoders' checkSignature, so that a file named
// here reaches the decoder of its format.
ImageFileFormat ImageFileFormatOf(std::span<const std::uint8_t> head) {
  using namespace std::string_view_literals;
  if (StartsWith(head, "\x89PNG\r\n\x1a\n"sv)) return ImageFileFormat::kPng;
  if (StartsWith(head, "II\x2a\x00"sv) || StartsWith(head, "MM\x00\x2a"sv) || StartsWith(head, "II\x2b\x00"sv) ||
      StartsWith(head, "MM\x00\x2b"sv))
    return ImageFileFormat::kTiff;
  if (StartsWith(head, "\xff\xd8\xff"sv)) return ImageFileFormat::kJpeg;
  if (StartsWith(head, "BM"sv)) return ImageFileFormat::kBmp;
  // P1-P6 (PBM, PGM, PPM), P7 (PAM), Pf and PF (PFM), each followed by white space.
  if (head.size() >= 3 && head[0] == 'P' &&
      ((head[1] >= '1' && head[1] <= '7') || head[1] == 'f' || head[1] == 'F') && IsSpace(head[2]))
    return ImageFileFormat::kPnm;
  if (StartsWith(head, "#?RGBE"sv) || StartsWith(head, "#?RADIANCE"sv)) return ImageFileFormat::kRadianceHdr;
  return ImageFileFormat::kUnknown;
}

const char* ReadableImageFormats() { return "PNG, TIFF, JPEG, BMP, PNM or Radiance HDR"; }

bool ReadImageFileBytes(const std::string& path, std::vector<std::uint8_t>* bytes, std::string* why) {
  namespace fs = std::filesystem;
  std::error_code error;
  if (!fs::is_regular_file(path, error)) {  // a device such as /dev/urandom would never end
    *why = fs::exists(path, error) ? "not a regular file" : "missing";
    return false;
  }
  if (const std::uintmax_t size = fs::file_size(path, error); error || size > kMaxImageFileBytes) {
    *why = error ? "cannot tell its size (" + error.message() + ")" : "larger than 1 GiB";
    return false;
  }
  std::ifstream in(path, std::ios::binary);
  bytes->assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  if (!in.is_open() || in.bad()) {
    *why = "read error";
    return false;
  }
  if (ImageFileFormatOf(*bytes) == ImageFileFormat::kUnknown) {
    *why = std::string("not a ") + ReadableImageFormats() + " file: its first bytes name none of them";
    return false;
  }
  return true;
}

}  // namespace photorig::solvers::core
