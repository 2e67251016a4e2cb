#pragma once
// Encoder for the run store's frame files: 16-bit grayscale PNG with filter 0
// and stored (uncompressed) deflate blocks. Noisy 12-bit frames barely
// compress, and libpng's adaptive filtering plus deflate cost ~40 ms per
// megapixel; this writes the file in one pass over the pixels, split across
// threads, with the checksums (zlib's Adler-32, the chunk's CRC-32 and the
// pixel CRC-32 the run manifest records) combined from per-slice partials.
// Any PNG reader decodes the result.

#include <cstddef>
#include <cstdint>
#include <vector>

namespace photorig::daemon {

class Png16Encoder {
 public:
  struct Encoded {
    const std::uint8_t* data = nullptr;  // valid until the next Encode
    std::size_t size = 0;
    std::uint32_t pixel_crc32 = 0;  // CRC-32 of the pixels as native 16-bit words (what LoadFrame checks)
  };

  // Reuses its buffer across calls, so a run of equal-sized frames does not
  // fault in fresh pages for every frame.
  Encoded Encode(const std::uint16_t* pixels, int width, int height);

 private:
  std::vector<std::uint8_t> buffer_;
};

}  // namespace photorig::daemon
