// Image files: the first byte picks the read mode, the rest is the file.
// The contract is an image of the size and type the header states, or an
// empty one with a reason; never a crash, a read past the bytes or an
// allocation past the limit. The limit is 64 MiB rather than the default
// 1 GiB: a few hundred bytes of arithmetic-coded JPEG may legally claim a
// 1 GiB image, which takes seconds to decode under the sanitizers and would
// read as a timeout; what the decoders do at any size is the same code.
#include "photorig/solvers/codecs/image_codecs.h"

#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using photorig::solvers::codecs::ReadMode;
  if (size == 0) return 0;
  const ReadMode modes[] = {ReadMode::kAsStored, ReadMode::kWithoutAlpha, ReadMode::kGrey};
  const photorig::solvers::codecs::DecodeOptions options{.mode = modes[data[0] % 3],
                                                         .max_pixel_bytes = std::uint64_t{64} << 20};
  std::string why;
  const cv::Mat image = photorig::solvers::codecs::DecodeImage({data + 1, size - 1}, options, &why);
  if (image.empty() == why.empty()) std::abort();  // a reason exactly when there is no image
  if (!image.empty() && image.total() * image.elemSize() > options.max_pixel_bytes) std::abort();
  return 0;
}
