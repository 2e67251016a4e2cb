#pragma once
// Encoder for the run store's frame files: 16-bit grayscale PNG with filter 0
// and stored (uncompressed) deflate blocks. Noisy 12-bit frames barely
// compress, and libpng's adaptive filtering plus deflate cost ~40 ms per
// megapixel; this writes the file in one pass over the pixels on one thread,
// with libdeflate's vectorised checksums (zlib's Adler-32, the chunk's CRC-32
// and the pixel CRC-32 the run manifest records; ~20 GB/s against zlib's
// ~4 GB/s CRC). The file comes out in pieces of a few stored blocks, so a
// caller can hand the head to the disk while the rest is being encoded.
// Any PNG reader decodes the result.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

namespace photorig::daemon {

class Png16Encoder {
 public:
  // Receives consecutive pieces of the file, each valid only during the call.
  using Sink = std::function<void(const std::uint8_t* data, std::size_t size)>;

  // Streams the file to `sink` in order, in pieces of at most kPieceBytes, and
  // returns the CRC-32 of the pixels as native 16-bit words (what LoadFrame
  // checks). Throws std::invalid_argument for an empty frame or one too large
  // for a single IDAT chunk.
  // `channels` 3: pixels hold R, G, B per pixel and the file is an RGB PNG.
  std::uint32_t Encode(const std::uint16_t* pixels, int width, int height, const Sink& sink, int channels = 1);

  // Stored blocks per piece: large enough that a write per piece costs
  // little, small enough that writeback of the first piece starts early.
  static constexpr std::size_t kBlocksPerPiece = 4;
  // A piece's blocks plus, at either end of the file, the headers or trailer.
  static constexpr std::size_t kPieceBytes = kBlocksPerPiece * (5 + 65535) + 64;

 private:
  std::vector<std::uint8_t> piece_;  // reused, so equal-sized frames fault in no fresh pages
};

}  // namespace photorig::daemon
