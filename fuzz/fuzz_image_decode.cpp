// Image files: the first byte picks the read mode, the rest is the file.
// The contract is an image of the size and type the header states, or an
// empty one with a reason; never a crash, a read past the bytes or an
// allocation past the 1 GiB limit.
#include "photorig/solvers/codecs/image_codecs.h"

#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using photorig::solvers::codecs::ReadMode;
  if (size == 0) return 0;
  const ReadMode modes[] = {ReadMode::kAsStored, ReadMode::kWithoutAlpha, ReadMode::kGrey};
  std::string why;
  const cv::Mat image = photorig::solvers::codecs::DecodeImage({data + 1, size - 1}, modes[data[0] % 3], &why);
  if (image.empty() == why.empty()) std::abort();  // a reason exactly when there is no image
  if (!image.empty() && image.total() * image.elemSize() > (std::size_t{1} << 30)) std::abort();
  return 0;
}
