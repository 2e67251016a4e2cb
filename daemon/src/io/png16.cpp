#include "photorig/daemon/io/png16.h"

#include <libdeflate.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <stdexcept>

namespace photorig::daemon {
namespace {

constexpr std::size_t kMaxStoredBlock = 65535;  // deflate's limit for one stored block
constexpr std::size_t kStoredHeader = 5;        // BFINAL/BTYPE byte, LEN, NLEN
constexpr std::array<std::uint8_t, 8> kSignature = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
constexpr std::size_t kIhdrChunk = 4 + 4 + 13 + 4, kIendChunk = 12;
constexpr std::size_t kPrefixBytes = kSignature.size() + kIhdrChunk + 8 + 2;  // up to the first stored block
constexpr std::size_t kTrailerBytes = 4 + 4 + kIendChunk;                      // Adler-32, IDAT CRC, IEND
static_assert(Png16Encoder::kPieceBytes >=
              kPrefixBytes + Png16Encoder::kBlocksPerPiece * (kStoredHeader + kMaxStoredBlock) + kTrailerBytes);

std::uint8_t* PutBigEndian32(std::uint8_t* out, std::uint32_t value) {
  out[0] = static_cast<std::uint8_t>(value >> 24);
  out[1] = static_cast<std::uint8_t>(value >> 16);
  out[2] = static_cast<std::uint8_t>(value >> 8);
  out[3] = static_cast<std::uint8_t>(value);
  return out + 4;
}

std::uint32_t Crc(std::uint32_t crc, const std::uint8_t* data, std::size_t size) {
  return libdeflate_crc32(crc, data, size);
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
    std::size_t k = offset % row_bytes;  // byte k >= 1 of a row is the high byte of sample (k-1)/2 when k is odd
    const std::size_t k_stop = std::min(end, (row + 1) * row_bytes) - row * row_bytes;
    const std::uint16_t* row_pixels = pixels + row * static_cast<std::size_t>(width);
    if (k == 0) {
      *out++ = 0;
      ++k;
    }
    if (k < k_stop && (k % 2) == 0) *out++ = static_cast<std::uint8_t>(row_pixels[(k++ - 1) / 2]);
    // Whole samples: a plain byte-swapping loop the compiler vectorises.
    const std::uint16_t* samples = row_pixels + (k - 1) / 2;
    const std::size_t count = (k_stop - k) / 2;
    for (std::size_t i = 0; i < count; ++i) {
      const std::uint16_t big_endian = static_cast<std::uint16_t>((samples[i] >> 8) | (samples[i] << 8));
      std::memcpy(out + 2 * i, &big_endian, 2);
    }
    out += 2 * count;
    k += 2 * count;
    if (k < k_stop) *out++ = static_cast<std::uint8_t>(row_pixels[(k - 1) / 2] >> 8);
    offset = row * row_bytes + k_stop;
  }
}

}  // namespace

std::uint32_t Png16Encoder::Encode(const std::uint16_t* pixels, int width, int height, const Sink& sink, int channels) {
  if (width <= 0 || height <= 0) throw std::invalid_argument("Png16Encoder: empty frame");
  if (channels != 1 && channels != 3) throw std::invalid_argument("Png16Encoder: frames have 1 or 3 channels");
  const int samples_per_row = width * channels;  // a row of R, G, B is a row of 3 x width samples
  const std::size_t row_bytes = 1 + 2 * static_cast<std::size_t>(samples_per_row);
  const std::size_t raw_size = row_bytes * static_cast<std::size_t>(height);
  const std::size_t blocks = (raw_size + kMaxStoredBlock - 1) / kMaxStoredBlock;
  const std::size_t zlib_size = 2 + blocks * kStoredHeader + raw_size + 4;
  if (zlib_size > 0x7fffffffu) throw std::invalid_argument("Png16Encoder: frame too large for one IDAT chunk");
  piece_.resize(kPieceBytes);

  std::uint8_t* out = std::copy(kSignature.begin(), kSignature.end(), piece_.data());
  std::array<std::uint8_t, 13> ihdr{};
  PutBigEndian32(ihdr.data(), static_cast<std::uint32_t>(width));
  PutBigEndian32(ihdr.data() + 4, static_cast<std::uint32_t>(height));
  ihdr[8] = 16;  // bit depth; colour type 0 (grey) or 2 (RGB), deflate, filter method 0, no interlace
  ihdr[9] = channels == 3 ? 2 : 0;
  out = PutChunk(out, "IHDR", ihdr.data(), ihdr.size());
  out = PutBigEndian32(out, static_cast<std::uint32_t>(zlib_size));
  const std::uint8_t* idat_from = out;  // the chunk CRC covers the type and the data
  std::memcpy(out, "IDAT", 4);
  out += 4;
  out[0] = 0x78;  // deflate, 32K window; FCHECK makes the header a multiple of 31
  out[1] = 0x01;
  out += 2;

  std::uint32_t adler = 1, idat_crc = 0;
  for (std::size_t b = 0; b < blocks; ++b) {
    const std::size_t begin = b * kMaxStoredBlock;
    const std::size_t size = std::min(kMaxStoredBlock, raw_size - begin);
    const bool last = b + 1 == blocks;
    out[0] = last ? 1 : 0;  // BFINAL on the last block; BTYPE 00 = stored
    out[1] = static_cast<std::uint8_t>(size);
    out[2] = static_cast<std::uint8_t>(size >> 8);
    out[3] = static_cast<std::uint8_t>(~size);
    out[4] = static_cast<std::uint8_t>(~size >> 8);
    FillScanlines(pixels, samples_per_row, begin, begin + size, out + kStoredHeader);
    adler = libdeflate_adler32(adler, out + kStoredHeader, size);
    out += kStoredHeader + size;
    if (!last && (b + 1) % kBlocksPerPiece != 0) continue;
    if (last) out = PutBigEndian32(out, adler);
    idat_crc = Crc(idat_crc, idat_from, static_cast<std::size_t>(out - idat_from));
    if (last) {
      out = PutBigEndian32(out, idat_crc);
      out = PutChunk(out, "IEND", nullptr, 0);
    }
    sink(piece_.data(), static_cast<std::size_t>(out - piece_.data()));
    out = piece_.data();
    idat_from = out;
  }
  const std::size_t pixel_bytes = static_cast<std::size_t>(samples_per_row) * static_cast<std::size_t>(height) * 2;
  return Crc(0, reinterpret_cast<const std::uint8_t*>(pixels), pixel_bytes);
}

}  // namespace photorig::daemon
