// Netpbm bitmaps, greymaps and pixmaps, P1-P6: a text header (magic, width,
// height and, but for bitmaps, maxval) with # comments, then the samples as
// decimal text (P1-P3) or binary (P4-P6; 16-bit samples big-endian). The
// samples are OpenCV's: a maxval up to 255 gives 8 bits, one up to 65535 16
// bits; plain 8-bit samples are clamped to maxval and scaled to 0-255
// (v * 255 / maxval, truncated), plain 16-bit ones only clamped, binary ones
// kept as stored; bitmaps give 255 for white (0) and 0 for black (1). A #
// right after a number starts a comment, as in Netpbm (OpenCV takes it for the
// number's end and reads on inside the comment).

#include "formats.h"

#include <algorithm>
#include <climits>
#include <cstdio>

namespace photorig::solvers::codecs::internal {
namespace {

constexpr int kMaxMaxval = 65535;

bool IsSpace(std::uint8_t c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f'; }
bool IsDigit(std::uint8_t c) { return c >= '0' && c <= '9'; }

std::string Describe(std::uint8_t c) {
  char text[16];
  std::snprintf(text, sizeof text, c > ' ' && c <= '~' ? "'%c'" : "byte 0x%02x", c);
  return text;
}

// The numbers of the header and of a plain raster, past white space and
// comments (# to the end of the line).
class TextReader {
 public:
  TextReader(std::span<const std::uint8_t> bytes, std::size_t offset) : bytes_(bytes), offset_(offset) {}

  // A decimal number up to INT_MAX. It ends at white space, which is consumed
  // (so a binary raster starts right after the one white-space byte ending the
  // header), or at a comment; a number the bytes end in may have been cut.
  bool Number(int* value, std::string* why) {
    if (!SkipToToken(why)) return false;
    if (!IsDigit(bytes_[offset_])) {
      *why = "PNM: " + Describe(bytes_[offset_]) + " where a number should be";
      return false;
    }
    std::int64_t number = 0;
    while (offset_ < bytes_.size() && IsDigit(bytes_[offset_])) {
      number = number * 10 + (bytes_[offset_++] - '0');
      if (number > INT_MAX) {
        *why = "PNM: a number past " + std::to_string(INT_MAX);
        return false;
      }
    }
    if (offset_ == bytes_.size()) {
      *why = "PNM: the file ends inside a number (truncated)";
      return false;
    }
    if (IsSpace(bytes_[offset_])) {
      ++offset_;
    } else if (bytes_[offset_] != '#') {
      *why = "PNM: " + Describe(bytes_[offset_]) + " after a number";
      return false;
    }
    *value = static_cast<int>(number);
    return true;
  }

  // A plain bitmap's pixel: one digit, 0 or 1, with or without space around it.
  bool Bit(bool* black, std::string* why) {
    if (!SkipToToken(why)) return false;
    const std::uint8_t c = bytes_[offset_++];
    if (c != '0' && c != '1') {
      *why = "PNM: " + Describe(c) + " where a bitmap's 0 or 1 should be";
      return false;
    }
    *black = c == '1';
    return true;
  }

  // Where a binary raster starts; false if the header's last number did not end
  // in white space.
  bool RasterStart(std::size_t* offset, std::string* why) const {
    if (!IsSpace(bytes_[offset_ - 1])) {
      *why = "PNM: the header does not end in a white-space byte before the pixels";
      return false;
    }
    *offset = offset_;
    return true;
  }

  std::size_t Remaining() const { return bytes_.size() - offset_; }

 private:
  bool SkipToToken(std::string* why) {
    while (offset_ < bytes_.size() && (IsSpace(bytes_[offset_]) || bytes_[offset_] == '#')) {
      if (bytes_[offset_] != '#') {
        ++offset_;
        continue;
      }
      while (offset_ < bytes_.size() && bytes_[offset_] != '\n' && bytes_[offset_] != '\r') ++offset_;
    }
    if (offset_ == bytes_.size()) {
      *why = "PNM: the file ends early (truncated)";
      return false;
    }
    return true;
  }

  std::span<const std::uint8_t> bytes_;
  std::size_t offset_;
};

// Stores the file's `sample`th sample: OpenCV's order turns R, G, B into B, G, R.
void Store(cv::Mat& image, std::size_t sample, int value) {
  if (image.channels() == 3) sample += 2 - 2 * (sample % 3);
  if (image.depth() == CV_16U) {
    image.ptr<std::uint16_t>()[sample] = static_cast<std::uint16_t>(value);
  } else {
    image.data[sample] = static_cast<std::uint8_t>(value);
  }
}

}  // namespace

cv::Mat DecodePnm(std::span<const std::uint8_t> bytes, std::string* why, std::uint64_t max_pixel_bytes) {
  if (bytes.size() < 2 || bytes[0] != 'P' || bytes[1] < '1' || bytes[1] > '6') {
    const bool pam_or_pfm =
        bytes.size() >= 2 && bytes[0] == 'P' && (bytes[1] == '7' || bytes[1] == 'f' || bytes[1] == 'F');
    *why = pam_or_pfm ? std::string("PNM: P") + static_cast<char>(bytes[1]) + " (PAM or PFM) is not supported"
                      : "PNM: no P1-P6 magic number";
    return {};
  }
  if (bytes.size() == 2 || !IsSpace(bytes[2])) {
    *why = std::string("PNM: no white space after the magic number P") + static_cast<char>(bytes[1]);
    return {};
  }
  const int kind = bytes[1] - '0';
  const bool plain = kind <= 3, bitmap = kind == 1 || kind == 4;
  const int channels = kind == 3 || kind == 6 ? 3 : 1;
  TextReader reader(bytes, 3);
  int width = 0, height = 0, maxval = 1;
  if (!reader.Number(&width, why) || !reader.Number(&height, why) || (!bitmap && !reader.Number(&maxval, why)))
    return {};
  if (width == 0 || height == 0) {
    *why = "PNM: header says " + std::to_string(width) + " x " + std::to_string(height) + " pixels";
    return {};
  }
  if (maxval == 0 || maxval > kMaxMaxval) {
    *why = "PNM: maxval " + std::to_string(maxval) + " is not in 1-65535";
    return {};
  }
  const int depth = maxval > 255 ? CV_16U : CV_8U;
  const std::size_t sample_bytes = depth == CV_16U ? 2 : 1;
  const std::uint64_t samples = std::uint64_t{static_cast<std::uint32_t>(width)} * static_cast<std::uint32_t>(height) *
                                static_cast<std::uint32_t>(channels);
  if (samples * sample_bytes > max_pixel_bytes) {
    *why = "PNM: header says " + std::to_string(width) + " x " + std::to_string(height) +
           " pixels, past the " + LimitText(max_pixel_bytes) + " limit";
    return {};
  }
  // Bytes the pixels take at the least (a plain sample is a digit and, but in
  // a bitmap, the space or comment after it), so that a short file is refused
  // before the allocation.
  const std::size_t bitmap_row_bytes = (static_cast<std::size_t>(width) + 7) / 8;
  const std::uint64_t pixel_bytes = plain    ? (bitmap ? samples : 2 * samples)
                                    : bitmap ? bitmap_row_bytes * static_cast<std::size_t>(height)
                                             : samples * sample_bytes;
  std::size_t raster = 0;
  if (!plain && !reader.RasterStart(&raster, why)) return {};
  if (reader.Remaining() < pixel_bytes) {
    *why = "PNM: the file ends before its " + std::to_string(width) + " x " + std::to_string(height) +
           " pixels (truncated)";
    return {};
  }

  cv::Mat image(height, width, CV_MAKETYPE(depth, channels));
  if (plain && bitmap) {
    for (std::size_t i = 0; i < samples; ++i) {
      bool black = false;
      if (!reader.Bit(&black, why)) return {};
      Store(image, i, black ? 0 : 255);
    }
  } else if (plain) {
    for (std::size_t i = 0; i < samples; ++i) {
      int value = 0;
      if (!reader.Number(&value, why)) return {};
      value = std::min(value, maxval);
      Store(image, i, depth == CV_8U && maxval != 255 ? value * 255 / maxval : value);
    }
  } else if (bitmap) {
    for (int y = 0; y < height; ++y) {
      const std::uint8_t* row = &bytes[raster + static_cast<std::size_t>(y) * bitmap_row_bytes];
      std::uint8_t* out = image.ptr(y);
      for (int x = 0; x < width; ++x) out[x] = (row[x / 8] >> (7 - x % 8)) & 1 ? 0 : 255;
    }
  } else {
    const std::uint8_t* sample = &bytes[raster];
    for (std::size_t i = 0; i < samples; ++i, sample += sample_bytes)
      Store(image, i, sample_bytes == 2 ? (sample[0] << 8) | sample[1] : sample[0]);
  }
  return image;
}

}  // namespace photorig::solvers::codecs::internal
