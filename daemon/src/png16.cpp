#include "photorig/daemon/png16.h"

#include <zlib.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <stdexcept>

namespace photorig::daemon {
namespace {

constexpr std::size_t kMaxStoredBlock = 65535;  // deflate's limit for one stored block
constexpr std::size_t kStoredHeader = 5;        // BFINAL/BTYPE byte, LEN, NLEN
constexpr std::array<std::uint8_t, 8> kSignature = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};

std::uint8_t* PutBigEndian32(std::uint8_t* out, std::uint32_t value) {
  out[0] = static_cast<std::uint8_t>(value >> 24);
  out[1] = static_cast<std::uint8_t>(value >> 16);
  out[2] = static_cast<std::uint8_t>(value >> 8);
  out[3] = static_cast<std::uint8_t>(value);
  return out + 4;
}

std::uint32_t Crc(std::uint32_t crc, const std::uint8_t* data, std::size_t size) {
  return static_cast<std::uint32_t>(::crc32_z(crc, data, size));
}

// A whole small chunk: length, type, data, CRC over type and data.
std::uint8_t* PutChunk(std::uint8_t* out, const char* type, const std::uint8_t* data, std::size_t size) {
  out = PutBigEndian32(out, static_cast<std::uint32_t>(size));
  std::uint8_t* typed = out;
  std::memcpy(out, type, 4);
  if (size > 0) std::memcpy(out + 4, data, size);
  out += 4 + size;
  return PutBigEndian32(out, Crc(0, typed, 4 + size));
}

// Writes the filtered scanline bytes [begin, end) of the image (each row: a
// filter byte 0, then big-endian samples) to `out`.
void FillScanlines(const std::uint16_t* pixels, int width, std::size_t begin, std::size_t end, std::uint8_t* out) {
  const std::size_t row_bytes = 1 + 2 * static_cast<std::size_t>(width);
  std::size_t offset = begin;
  while (offset < end) {
    const std::size_t row = offset / row_bytes;
    std::size_t in_row = offset % row_bytes;
    const std::size_t stop = std::min(end, (row + 1) * row_bytes);
    const std::uint16_t* row_pixels = pixels + row * static_cast<std::size_t>(width);
    if (in_row == 0) {
      *out++ = 0;
      ++in_row;
    }
    // Byte k of the row (k >= 1) is the high byte of sample (k-1)/2 when k is odd.
    std::size_t k = in_row;
    const std::size_t k_stop = stop - row * row_bytes;
    if (k < k_stop && (k % 2) == 0) *out++ = static_cast<std::uint8_t>(row_pixels[(k++ - 1) / 2]);
    for (; k + 1 < k_stop; k += 2) {
      const std::uint16_t v = row_pixels[(k - 1) / 2];
      out[0] = static_cast<std::uint8_t>(v >> 8);
      out[1] = static_cast<std::uint8_t>(v);
      out += 2;
    }
    if (k < k_stop) *out++ = static_cast<std::uint8_t>(row_pixels[(k - 1) / 2] >> 8);
    offset = stop;
  }
}

struct SlicePartials {
  std::uint32_t adler = 1;     // of the scanline bytes in the slice
  std::size_t raw_bytes = 0;
  std::uint32_t idat_crc = 0;  // of every output byte of the slice (block headers included)
  std::size_t out_bytes = 0;
  std::uint32_t pixel_crc = 0;
  std::size_t pixel_bytes = 0;
};

}  // namespace

Png16Encoder::Encoded Png16Encoder::Encode(const std::uint16_t* pixels, int width, int height) {
  if (width <= 0 || height <= 0) throw std::invalid_argument("Png16Encoder: empty frame");
  const std::size_t row_bytes = 1 + 2 * static_cast<std::size_t>(width);
  const std::size_t raw_size = row_bytes * static_cast<std::size_t>(height);
  const std::size_t blocks = (raw_size + kMaxStoredBlock - 1) / kMaxStoredBlock;
  const std::size_t zlib_size = 2 + blocks * kStoredHeader + raw_size + 4;
  if (zlib_size > 0x7fffffffu) throw std::invalid_argument("Png16Encoder: frame too large for one IDAT chunk");
  constexpr std::size_t kIhdrChunk = 4 + 4 + 13 + 4, kIendChunk = 12;
  const std::size_t total = kSignature.size() + kIhdrChunk + 8 + zlib_size + 4 + kIendChunk;
  buffer_.resize(total);

  std::uint8_t* out = std::copy(kSignature.begin(), kSignature.end(), buffer_.data());
  std::array<std::uint8_t, 13> ihdr{};
  PutBigEndian32(ihdr.data(), static_cast<std::uint32_t>(width));
  PutBigEndian32(ihdr.data() + 4, static_cast<std::uint32_t>(height));
  ihdr[8] = 16;  // bit depth; colour type 0 (grey), deflate, filter method 0, no interlace
  out = PutChunk(out, "IHDR", ihdr.data(), ihdr.size());
  out = PutBigEndian32(out, static_cast<std::uint32_t>(zlib_size));
  std::uint8_t* idat_type = out;
  std::memcpy(out, "IDAT", 4);
  out += 4;
  out[0] = 0x78;  // deflate, 32K window; FCHECK makes the header a multiple of 31
  out[1] = 0x01;
  out += 2;
  std::uint8_t* const blocks_begin = out;

  // Slices of whole stored blocks, so each slice's output is independent.
  const std::size_t slices = std::min<std::size_t>(blocks, 16);
  const std::size_t pixel_count = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  std::vector<SlicePartials> partials(slices);
#pragma omp parallel for schedule(static)
  for (std::size_t s = 0; s < slices; ++s) {
    SlicePartials& p = partials[s];
    const std::size_t first_block = blocks * s / slices, last_block = blocks * (s + 1) / slices;
    std::uint8_t* const slice_out = blocks_begin + first_block * (kStoredHeader + kMaxStoredBlock);
    std::uint8_t* block_out = slice_out;
    for (std::size_t b = first_block; b < last_block; ++b) {
      const std::size_t begin = b * kMaxStoredBlock;
      const std::size_t size = std::min(kMaxStoredBlock, raw_size - begin);
      block_out[0] = b + 1 == blocks ? 1 : 0;  // BFINAL on the last block; BTYPE 00 = stored
      block_out[1] = static_cast<std::uint8_t>(size);
      block_out[2] = static_cast<std::uint8_t>(size >> 8);
      block_out[3] = static_cast<std::uint8_t>(~size);
      block_out[4] = static_cast<std::uint8_t>(~size >> 8);
      FillScanlines(pixels, width, begin, begin + size, block_out + kStoredHeader);
      p.adler = static_cast<std::uint32_t>(::adler32_z(p.adler, block_out + kStoredHeader, size));
      p.raw_bytes += size;
      block_out += kStoredHeader + size;
    }
    p.out_bytes = static_cast<std::size_t>(block_out - slice_out);
    p.idat_crc = Crc(0, slice_out, p.out_bytes);
    const std::size_t first_pixel = pixel_count * s / slices, last_pixel = pixel_count * (s + 1) / slices;
    p.pixel_bytes = (last_pixel - first_pixel) * sizeof(std::uint16_t);
    p.pixel_crc = Crc(0, reinterpret_cast<const std::uint8_t*>(pixels + first_pixel), p.pixel_bytes);
  }

  std::uint32_t adler = 1, idat_crc = Crc(0, idat_type, 4 + 2), pixel_crc = 0;
  for (const SlicePartials& p : partials) {
    adler = static_cast<std::uint32_t>(::adler32_combine(adler, p.adler, static_cast<z_off_t>(p.raw_bytes)));
    idat_crc = static_cast<std::uint32_t>(::crc32_combine(idat_crc, p.idat_crc, static_cast<z_off_t>(p.out_bytes)));
    pixel_crc = static_cast<std::uint32_t>(::crc32_combine(pixel_crc, p.pixel_crc, static_cast<z_off_t>(p.pixel_bytes)));
  }
  out = blocks_begin + blocks * kStoredHeader + raw_size;
  std::uint8_t adler_bytes[4];
  PutBigEndian32(adler_bytes, adler);
  std::memcpy(out, adler_bytes, 4);
  idat_crc = Crc(idat_crc, adler_bytes, 4);
  out = PutBigEndian32(out + 4, idat_crc);
  out = PutChunk(out, "IEND", nullptr, 0);
  if (static_cast<std::size_t>(out - buffer_.data()) != total) throw std::logic_error("Png16Encoder: size mismatch");
  return {buffer_.data(), total, pixel_crc};
}

}  // namespace photorig::daemon
