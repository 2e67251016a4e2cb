// Windows and OS/2 bitmaps: a 14-byte file header; an info header (OS/2's
// 12-byte core header, or Windows' 40-byte one or a later, longer version);
// a palette for 1, 4 and 8 bits a pixel; then the rows, bottom to top (top to
// bottom when the height is negative), each padded to 4 bytes, or RLE8/RLE4
// codes. The pixels are OpenCV's: a palette of greys gives 1 channel, any
// other 3 (B, G, R); 16 and 24 bits give 3; 32 bits give 3, or 4 (B, G, R, A)
// with bit fields. Where OpenCV 4.6 misreads a file (OS/2 core headers,
// 16-bit bit fields inside a V4 or V5 header, RLE4 deltas), the format's
// definition is followed.

#include "formats.h"

#include <algorithm>
#include <array>
#include <cstdlib>
#include <cstring>
#include <iterator>

namespace photorig::solvers::codecs::internal {
namespace {

constexpr std::size_t kFileHeaderBytes = 14;
constexpr std::uint32_t kCoreHeaderBytes = 12, kInfoHeaderBytes = 40, kV5HeaderBytes = 124;
// The bit fields' R, G, B masks are 40 bytes into the info header: inside
// the longer ones, right after a 40-byte one. Headers of 56 bytes on hold the
// A mask at byte 52.
constexpr std::uint32_t kMasksOffset = 40, kAlphaMaskOffset = 52;

enum Compression : std::uint32_t { kRgb = 0, kRle8 = 1, kRle4 = 2, kBitFields = 3 };

using Bgr = std::array<std::uint8_t, 3>;
using Palette = std::array<Bgr, 256>;  // indices past a palette's entries are black, as OpenCV reads them

std::uint16_t Le16(const std::uint8_t* p) { return static_cast<std::uint16_t>(p[0] | p[1] << 8); }
std::uint32_t Le32(const std::uint8_t* p) { return p[0] | p[1] << 8 | p[2] << 16 | std::uint32_t{p[3]} << 24; }

std::string CompressionName(std::uint32_t compression) {
  constexpr const char* kNames[] = {"BI_RGB", "BI_RLE8", "BI_RLE4", "BI_BITFIELDS", "BI_JPEG", "BI_PNG",
                                    "BI_ALPHABITFIELDS"};
  return compression < std::size(kNames) ? kNames[compression] : "code " + std::to_string(compression);
}

bool Supported(std::uint32_t compression, int bits) {
  switch (compression) {
    case kRgb: return bits == 1 || bits == 4 || bits == 8 || bits == 16 || bits == 24 || bits == 32;
    case kRle8: return bits == 8;
    case kRle4: return bits == 4;
    case kBitFields: return bits == 16 || bits == 32;
    default: return false;
  }
}

struct Layout {
  int width = 0, height = 0;
  bool top_down = false;
  int bits = 0;
  std::uint32_t compression = kRgb;
  bool rgb565 = false;  // 16 bits: 5-6-5 bit fields rather than 5-5-5
  bool alpha = false;   // 32 bits with bit fields: a fourth channel...
  bool opaque = false;  // ...which is 255 when the header's A mask is 0, as OpenCV reads it
  std::size_t palette_offset = 0, palette_entry_bytes = 4;
  std::uint32_t palette_entries = 0;
  std::size_t pixel_offset = 0;
};

bool Truncated(std::string* why) {
  *why = "BMP: the file ends inside its headers or palette (truncated)";
  return false;
}

// The bit fields: 5-5-5 or 5-6-5 for 16 bits, bytes B, G, R(, A) for 32 (the
// masks OpenCV assumes without reading them).
bool ReadMasks(std::span<const std::uint8_t> bytes, std::uint32_t header_bytes, Layout* layout, std::string* why) {
  const std::size_t masks = kFileHeaderBytes + kMasksOffset;
  if (bytes.size() < masks + 12) return Truncated(why);
  const std::uint32_t red = Le32(&bytes[masks]), green = Le32(&bytes[masks + 4]), blue = Le32(&bytes[masks + 8]);
  if (layout->bits == 16) {
    layout->rgb565 = red == 0xf800 && green == 0x7e0 && blue == 0x1f;
    if (layout->rgb565 || (red == 0x7c00 && green == 0x3e0 && blue == 0x1f)) return true;
    *why = "BMP: 16-bit bit fields other than 5-5-5 and 5-6-5 are not supported";
    return false;
  }
  const bool has_alpha_mask = header_bytes >= kAlphaMaskOffset + 4;
  const std::uint32_t alpha = has_alpha_mask ? Le32(&bytes[kFileHeaderBytes + kAlphaMaskOffset]) : 0xff000000;
  if (red != 0xff0000 || green != 0xff00 || blue != 0xff || (alpha != 0 && alpha != 0xff000000)) {
    *why = "BMP: 32-bit bit fields other than bytes B, G, R, A are not supported";
    return false;
  }
  layout->alpha = true;
  layout->opaque = alpha == 0;
  return true;
}

bool ReadLayout(std::span<const std::uint8_t> bytes, Layout* layout, std::string* why) {
  if (bytes.size() < 2 || bytes[0] != 'B' || bytes[1] != 'M') {
    *why = "BMP: no BM signature";
    return false;
  }
  if (bytes.size() < kFileHeaderBytes + 4) return Truncated(why);
  const std::uint32_t header_bytes = Le32(&bytes[kFileHeaderBytes]);
  if (header_bytes != kCoreHeaderBytes && (header_bytes < kInfoHeaderBytes || header_bytes > kV5HeaderBytes)) {
    *why = "BMP: a " + std::to_string(header_bytes) + "-byte info header is not one read (12, or 40 to 124)";
    return false;
  }
  if (bytes.size() < kFileHeaderBytes + header_bytes) return Truncated(why);
  const std::uint8_t* info = &bytes[kFileHeaderBytes];
  std::int64_t width = 0, height = 0;
  std::uint32_t colours_used = 0;
  if (header_bytes == kCoreHeaderBytes) {
    width = Le16(info + 4);
    height = Le16(info + 6);
    layout->bits = Le16(info + 10);
    layout->palette_entry_bytes = 3;  // OS/2's entries have no fourth byte
  } else {
    width = static_cast<std::int32_t>(Le32(info + 4));
    height = static_cast<std::int32_t>(Le32(info + 8));
    layout->bits = Le16(info + 14);
    layout->compression = Le32(info + 16);
    colours_used = Le32(info + 32);
  }
  const int bits = layout->bits;
  const std::uint32_t compression = layout->compression;
  if (compression > kBitFields) {
    *why = "BMP: " + CompressionName(compression) + " compression is not supported";
    return false;
  }
  if (!Supported(compression, bits)) {
    *why = "BMP: " + std::to_string(bits) + " bits a pixel with " + CompressionName(compression) +
           " is not supported";
    return false;
  }
  if (width <= 0 || height == 0 || height == INT32_MIN) {
    *why = "BMP: header says " + std::to_string(width) + " x " + std::to_string(height) + " pixels";
    return false;
  }
  layout->width = static_cast<int>(width);
  layout->height = static_cast<int>(std::abs(height));
  layout->top_down = height < 0;
  if (compression == kBitFields && !ReadMasks(bytes, header_bytes, layout, why)) return false;
  if (bits <= 8) {
    layout->palette_offset = kFileHeaderBytes + header_bytes;
    layout->palette_entries = colours_used == 0 ? 1u << bits : std::min(colours_used, 1u << bits);
    if (bytes.size() < layout->palette_offset + layout->palette_entries * layout->palette_entry_bytes)
      return Truncated(why);
  }
  layout->pixel_offset = Le32(&bytes[10]);
  if (layout->pixel_offset > bytes.size()) {
    *why = "BMP: the pixels' offset is past the end of the file (truncated)";
    return false;
  }
  return true;
}

// The `x`th index of a row packed at 1, 4 or 8 bits, the leftmost pixel in the highest bits.
int IndexAt(const std::uint8_t* packed, int bits, int x) {
  const int per_byte = 8 / bits;
  return (packed[x / per_byte] >> (bits * (per_byte - 1 - x % per_byte))) & ((1 << bits) - 1);
}

// Palette colours of `count` indices to pixels of 1 (grey) or 3 channels.
void Paint(const std::uint8_t* indices, int count, const Palette& palette, int channels, std::uint8_t* out) {
  for (int i = 0; i < count; ++i) {
    const Bgr& colour = palette[indices[i]];
    if (channels == 1) {
      out[i] = colour[0];
    } else {
      std::copy(colour.begin(), colour.end(), out + 3 * i);
    }
  }
}

std::uint8_t* StoredRow(cv::Mat& image, const Layout& layout, int row) {
  return image.ptr(layout.top_down ? row : layout.height - 1 - row);
}

// RLE8 or RLE4 codes painted into `image`, whose pixels the codes skip (end
// of line, delta, end of bitmap) keep palette entry 0, as OpenCV fills them.
bool DecodeRle(std::span<const std::uint8_t> codes, const Layout& layout, const Palette& palette, cv::Mat& image,
               std::string* why) {
  const int width = layout.width, bits = layout.bits;
  image.setTo(cv::Scalar(palette[0][0], palette[0][1], palette[0][2]));
  std::array<std::uint8_t, 255> indices;
  std::size_t at = 0;
  int x = 0, y = 0;
  while (y < layout.height) {
    if (codes.size() - at < 2) {
      if (y == layout.height - 1 && x == width) return true;  // whole but for the end-of-bitmap code
      *why = "BMP: the RLE codes end early (truncated)";
      return false;
    }
    const int count = codes[at], code = codes[at + 1];
    at += 2;
    if (count == 0 && code == 0) {  // end of line
      x = 0;
      ++y;
      continue;
    }
    if (count == 0 && code == 1) return true;  // end of bitmap
    if (count == 0 && code == 2) {             // delta: right, and rows on
      if (codes.size() - at < 2) {
        *why = "BMP: the RLE codes end early (truncated)";
        return false;
      }
      x += codes[at];
      y += codes[at + 1];
      at += 2;
      if (y < layout.height && x > width) {
        *why = "BMP: an RLE delta moves past the end of a row";
        return false;
      }
      continue;
    }
    // A run: `count` pixels of the index in `code` (RLE4: its two indices in
    // turn); or after a 0, `code` indices as stored, padded to 2 bytes.
    const bool run = count > 0;
    const int length = run ? count : code;
    const std::uint8_t* source = run ? &codes[at - 1] : codes.data() + at;
    const std::size_t source_bytes =
        run ? 0 : ((static_cast<std::size_t>(length) * bits + 7) / 8 + 1) & ~std::size_t{1};
    if (length > width - x) {
      *why = "BMP: an RLE run crosses the end of a row";
      return false;
    }
    if (codes.size() - at < source_bytes) {
      *why = "BMP: the RLE codes end early (truncated)";
      return false;
    }
    for (int i = 0; i < length; ++i)
      indices[i] = static_cast<std::uint8_t>(IndexAt(source, bits, run ? i % (8 / bits) : i));
    Paint(indices.data(), length, palette, image.channels(), StoredRow(image, layout, y) + x * image.channels());
    x += length;
    at += source_bytes;
  }
  return true;
}

// A stored row of 16, 24 or 32 bits a pixel.
void ConvertRow(const std::uint8_t* stored, const Layout& layout, std::uint8_t* out) {
  const int width = layout.width;
  if (layout.bits == 24) {
    std::memcpy(out, stored, 3 * static_cast<std::size_t>(width));
  } else if (layout.bits == 16) {
    for (int x = 0; x < width; ++x, out += 3) {
      // Each field at the top of its byte, the low bits 0, as OpenCV expands them.
      const int value = Le16(stored + 2 * x);
      out[0] = static_cast<std::uint8_t>((value << 3) & 0xf8);
      out[1] = static_cast<std::uint8_t>(layout.rgb565 ? (value >> 3) & 0xfc : (value >> 2) & 0xf8);
      out[2] = static_cast<std::uint8_t>(layout.rgb565 ? (value >> 8) & 0xf8 : (value >> 7) & 0xf8);
    }
  } else {
    for (int x = 0; x < width; ++x, stored += 4) {
      out = std::copy(stored, stored + 3, out);
      if (layout.alpha) *out++ = layout.opaque ? 255 : stored[3];
    }
  }
}

}  // namespace

cv::Mat DecodeBmp(std::span<const std::uint8_t> bytes, std::string* why, std::uint64_t max_pixel_bytes) {
  Layout layout;
  if (!ReadLayout(bytes, &layout, why)) return {};
  Palette palette{};
  bool grey = true;
  for (std::uint32_t i = 0; i < layout.palette_entries; ++i) {
    const std::uint8_t* entry = &bytes[layout.palette_offset + i * layout.palette_entry_bytes];
    palette[i] = {entry[0], entry[1], entry[2]};
    grey = grey && entry[0] == entry[1] && entry[1] == entry[2];
  }
  const int channels = layout.bits <= 8 ? (grey ? 1 : 3) : layout.alpha ? 4 : 3;
  const int width = layout.width, height = layout.height;
  if (std::uint64_t{static_cast<std::uint32_t>(width)} * static_cast<std::uint32_t>(height) * channels >
      max_pixel_bytes) {
    *why = "BMP: header says " + std::to_string(width) + " x " + std::to_string(height) +
           " pixels, past the " + LimitText(max_pixel_bytes) + " limit";
    return {};
  }
  const bool run_length = layout.compression == kRle8 || layout.compression == kRle4;
  const std::uint64_t stride = (std::uint64_t{static_cast<std::uint32_t>(width)} * layout.bits + 31) / 32 * 4;
  if (!run_length && bytes.size() - layout.pixel_offset < stride * static_cast<std::uint32_t>(height)) {
    *why = "BMP: the file ends before its " + std::to_string(width) + " x " + std::to_string(height) +
           " pixels (truncated)";
    return {};
  }
  cv::Mat image(height, width, CV_8UC(channels));
  if (run_length) {
    if (!DecodeRle(bytes.subspan(layout.pixel_offset), layout, palette, image, why)) return {};
    return image;
  }
  std::vector<std::uint8_t> indices(layout.bits <= 8 ? width : 0);
  for (int y = 0; y < height; ++y) {
    const std::uint8_t* stored = &bytes[layout.pixel_offset + y * stride];
    if (layout.bits > 8) {
      ConvertRow(stored, layout, StoredRow(image, layout, y));
      continue;
    }
    for (int x = 0; x < width; ++x) indices[x] = static_cast<std::uint8_t>(IndexAt(stored, layout.bits, x));
    Paint(indices.data(), width, palette, channels, StoredRow(image, layout, y));
  }
  return image;
}

}  // namespace photorig::solvers::codecs::internal
