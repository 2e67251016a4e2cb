// Radiance RGBE (.hdr): a text header ending in the resolution line, then one
// scanline per row, top to bottom, each either flat (R, G, B, E bytes a
// pixel) or run-length encoded a component at a time ("new-style" RLE), told
// apart scanline by scanline as Radiance's reader does. A component decodes
// as mantissa * 2^(E - 136), and E = 0 is black: OpenCV's convention too, so
// the two decode a file to the same floats.

#include "formats.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstring>
#include <string_view>

namespace photorig::solvers::codecs::internal {
namespace {

// Run-length encoded scanlines store their width in 15 bits, and narrower
// than 8 pixels they do not pay; such widths are always flat.
constexpr int kMinRleWidth = 8, kMaxRleWidth = 0x7fff;
constexpr int kRunFlag = 128;  // a count byte above 128 is a run of (count - 128) copies, otherwise a literal
constexpr int kMaxRun = 127, kMaxLiteral = 128;
// A shorter run costs as many bytes as the literal it would split once that
// literal needs a second count byte.
constexpr int kMinRun = 4;

// 255 * 2^(255 - 136): the largest value RGBE holds.
constexpr float kLargestValue = 0x1.fep126f;

using Rgbe = std::array<std::uint8_t, 4>;

bool RunLengthEncodable(int width) { return width >= kMinRleWidth && width <= kMaxRleWidth; }

// Header text for a message: printable, and short whatever a hostile file holds.
std::string Quoted(std::string_view text) {
  std::string quoted = "\"";
  for (const char c : text.substr(0, 40)) quoted += (c >= ' ' && c <= '~') ? c : '?';
  return quoted + "\"";
}

bool ParsePositive(std::string_view token, int* value) {
  const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), *value);
  return error == std::errc() && end == token.data() + token.size() && *value > 0;
}

// "-Y <height> +X <width>", apart by spaces: rows top to bottom, pixels left
// to right, the only orientation read.
bool ParseResolution(std::string_view line, int* height, int* width) {
  std::array<std::string_view, 4> tokens;
  std::size_t count = 0;
  for (std::size_t begin = line.find_first_not_of(' '); begin != std::string_view::npos;
       begin = line.find_first_not_of(' ', begin)) {
    const std::size_t end = std::min(line.find(' ', begin), line.size());
    if (count == tokens.size()) return false;
    tokens[count++] = line.substr(begin, end - begin);
    begin = end;
  }
  return count == tokens.size() && tokens[0] == "-Y" && tokens[2] == "+X" && ParsePositive(tokens[1], height) &&
         ParsePositive(tokens[3], width);
}

// Reads the header through the resolution line; `*offset` is then the first scanline's.
bool ReadHeader(std::span<const std::uint8_t> bytes, std::uint64_t max_pixel_bytes, int* width, int* height,
                std::size_t* offset, std::string* why) {
  const std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  std::size_t position = 0;
  const auto next_line = [&](std::string_view* line) {
    const std::size_t end = text.find('\n', position);
    if (end == std::string_view::npos) return false;
    *line = text.substr(position, end - position);
    position = end + 1;
    return true;
  };
  std::string_view line;
  if (!next_line(&line) || !(line.starts_with("#?RADIANCE") || line.starts_with("#?RGBE"))) {
    *why = "Radiance HDR: the first line is not #?RADIANCE or #?RGBE";
    return false;
  }
  // Variables up to a blank line; only FORMAT matters, and RGBE when it is
  // absent, as in Radiance (EXPOSURE and the like describe the scene, and
  // OpenCV ignores them as well).
  while (next_line(&line) && !line.empty()) {
    if (line.starts_with("FORMAT=") && line != "FORMAT=32-bit_rle_rgbe") {
      *why = "Radiance HDR: " + Quoted(line) + " is not supported, only FORMAT=32-bit_rle_rgbe";
      return false;
    }
  }
  if (!line.empty()) {
    *why = "Radiance HDR: the header has no end (truncated)";
    return false;
  }
  if (!next_line(&line)) {
    *why = "Radiance HDR: the file ends before the resolution line (truncated)";
    return false;
  }
  if (!ParseResolution(line, height, width)) {
    *why = "Radiance HDR: resolution line " + Quoted(line) + " is not \"-Y <height> +X <width>\"";
    return false;
  }
  if (std::uint64_t{static_cast<std::uint32_t>(*width)} * static_cast<std::uint32_t>(*height) * 3 * sizeof(float) >
      max_pixel_bytes) {
    *why = "Radiance HDR: header says " + std::to_string(*width) + " x " + std::to_string(*height) +
           " pixels, past the " + LimitText(max_pixel_bytes) + " limit";
    return false;
  }
  *offset = position;
  return true;
}

// Decodes the scanline at `*offset` into `rgbe` (R, G, B, E a pixel) and moves `*offset` past it.
bool ReadScanline(std::span<const std::uint8_t> bytes, int width, std::size_t* offset, std::uint8_t* rgbe,
                  std::string* why) {
  const std::span<const std::uint8_t> rest = bytes.subspan(*offset);
  const std::size_t flat_bytes = 4 * static_cast<std::size_t>(width);
  const bool encoded =
      RunLengthEncodable(width) && rest.size() >= 4 && rest[0] == 2 && rest[1] == 2 && (rest[2] & 0x80) == 0;
  if (!encoded) {
    if (rest.size() < flat_bytes) {
      *why = "Radiance HDR: the pixels end early (truncated)";
      return false;
    }
    std::memcpy(rgbe, rest.data(), flat_bytes);
    *offset += flat_bytes;
    return true;
  }
  if (const int stated = (rest[2] << 8) | rest[3]; stated != width) {
    *why = "Radiance HDR: a scanline says it is " + std::to_string(stated) + " pixels wide, the image " +
           std::to_string(width);
    return false;
  }
  std::size_t at = 4;
  for (int component = 0; component < 4; ++component) {
    for (int x = 0; x < width;) {
      if (at == rest.size()) {
        *why = "Radiance HDR: the pixels end early (truncated)";
        return false;
      }
      const int count = rest[at++];
      const bool run = count > kRunFlag;
      const int length = run ? count - kRunFlag : count;
      if (length == 0 || length > width - x) {
        *why = "Radiance HDR: a bad run-length code (empty, or past the end of its scanline)";
        return false;
      }
      const std::size_t code_bytes = run ? 1 : static_cast<std::size_t>(length);
      if (rest.size() - at < code_bytes) {
        *why = "Radiance HDR: the pixels end early (truncated)";
        return false;
      }
      for (int i = 0; i < length; ++i) rgbe[4 * (x + i) + component] = rest[at + (run ? 0 : i)];
      at += code_bytes;
      x += length;
    }
  }
  *offset += at;
  return true;
}

void RgbeToBgr(const std::uint8_t* rgbe, int width, float* bgr) {
  for (int x = 0; x < width; ++x, rgbe += 4, bgr += 3) {
    const float scale = rgbe[3] == 0 ? 0.0f : std::ldexp(1.0f, rgbe[3] - 136);
    bgr[0] = rgbe[2] * scale;
    bgr[1] = rgbe[1] * scale;
    bgr[2] = rgbe[0] * scale;
  }
}

// The shared exponent is the largest component's; each mantissa is truncated,
// as Radiance's own writer does. Negative and NaN components are black, and
// past the largest RGBE value components are that value.
Rgbe ToRgbe(float red, float green, float blue) {
  const auto representable = [](float value) { return value > 0 ? std::min(value, kLargestValue) : 0.0f; };
  const double components[3] = {representable(red), representable(green), representable(blue)};
  const double largest = std::max({components[0], components[1], components[2]});
  if (largest < 0x1p-128) return {0, 0, 0, 0};  // below 0.5 * 2^-127, the smallest exponent's least
  int exponent = 0;
  std::frexp(largest, &exponent);                     // largest = m * 2^exponent, 0.5 <= m < 1
  const double scale = std::ldexp(256.0, -exponent);  // exact: takes the largest to [128, 256)
  return {static_cast<std::uint8_t>(components[0] * scale), static_cast<std::uint8_t>(components[1] * scale),
          static_cast<std::uint8_t>(components[2] * scale), static_cast<std::uint8_t>(exponent + 128)};
}

// Identical components from `component[4 * from]` on, up to a run's longest.
int RunLength(const std::uint8_t* component, int from, int width) {
  int length = 1;
  while (from + length < width && length < kMaxRun && component[4 * (from + length)] == component[4 * from]) ++length;
  return length;
}

// One component of a scanline (every fourth byte from `component`) as runs and literals.
void PutComponent(const std::uint8_t* component, int width, std::vector<std::uint8_t>* out) {
  for (int x = 0; x < width;) {
    if (const int run = RunLength(component, x, width); run >= kMinRun) {
      out->push_back(static_cast<std::uint8_t>(kRunFlag + run));
      out->push_back(component[4 * x]);
      x += run;
      continue;
    }
    int end = x + 1;
    while (end < width && end - x < kMaxLiteral && RunLength(component, end, width) < kMinRun) ++end;
    out->push_back(static_cast<std::uint8_t>(end - x));
    for (; x < end; ++x) out->push_back(component[4 * x]);
  }
}

}  // namespace

cv::Mat DecodeRadianceHdr(std::span<const std::uint8_t> bytes, std::string* why, std::uint64_t max_pixel_bytes) {
  int width = 0, height = 0;
  std::size_t offset = 0;
  if (!ReadHeader(bytes, max_pixel_bytes, &width, &height, &offset, why)) return {};
  // The fewest bytes a scanline can take (every component in runs of the
  // longest, or flat), so that a short file is refused before the allocation.
  const std::uint64_t min_scanline_bytes =
      RunLengthEncodable(width) ? 4 + 4 * 2 * ((width + kMaxRun - 1) / kMaxRun) : 4 * static_cast<std::uint64_t>(width);
  if (bytes.size() - offset < min_scanline_bytes * static_cast<std::uint64_t>(height)) {
    *why = "Radiance HDR: the file is too short for " + std::to_string(width) + " x " + std::to_string(height) +
           " pixels (truncated)";
    return {};
  }
  cv::Mat image(height, width, CV_32FC3);
  std::vector<std::uint8_t> rgbe(4 * static_cast<std::size_t>(width));
  for (int y = 0; y < height; ++y) {
    if (!ReadScanline(bytes, width, &offset, rgbe.data(), why)) return {};
    RgbeToBgr(rgbe.data(), width, image.ptr<float>(y));
  }
  return image;
}

bool EncodeRadianceHdr(const cv::Mat& image, std::vector<std::uint8_t>* out, std::string* why) {
  if (image.empty() || (image.type() != CV_32FC3 && image.type() != CV_32FC1)) {
    *why = "Radiance HDR holds 32-bit float images of 1 or 3 channels";
    return false;
  }
  const int width = image.cols;
  const std::string header = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y " + std::to_string(image.rows) + " +X " +
                             std::to_string(width) + "\n";
  out->insert(out->end(), header.begin(), header.end());
  std::vector<std::uint8_t> rgbe(4 * static_cast<std::size_t>(width));
  for (int y = 0; y < image.rows; ++y) {
    const float* pixels = image.ptr<float>(y);
    for (int x = 0; x < width; ++x) {
      const Rgbe pixel = image.channels() == 3 ? ToRgbe(pixels[3 * x + 2], pixels[3 * x + 1], pixels[3 * x])
                                               : ToRgbe(pixels[x], pixels[x], pixels[x]);
      std::copy(pixel.begin(), pixel.end(), rgbe.begin() + 4 * x);
    }
    if (!RunLengthEncodable(width)) {
      out->insert(out->end(), rgbe.begin(), rgbe.end());
      continue;
    }
    out->insert(out->end(), {2, 2, static_cast<std::uint8_t>(width >> 8), static_cast<std::uint8_t>(width)});
    for (int component = 0; component < 4; ++component) PutComponent(rgbe.data() + component, width, out);
  }
  return true;
}

}  // namespace photorig::solvers::codecs::internal
