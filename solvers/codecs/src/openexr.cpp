// OpenEXR on the library's C++ API, written to memory: 32-bit float
// channels, ZIP-compressed (lossless, blocks of 16 scanlines).

#include "formats.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfCompression.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfOutputFile.h>

#include <cstring>
#include <exception>

namespace photorig::solvers::codecs::internal {
namespace {

// Appends the file to `out`. Positions count from where the file starts:
// OpenEXR seeks back to fill in the table of block offsets it writes into
// the file.
class AppendingStream final : public Imf::OStream {
 public:
  explicit AppendingStream(std::vector<std::uint8_t>* out) : Imf::OStream("memory"), out_(out), start_(out->size()) {}

  void write(const char bytes[], int count) override {
    const std::size_t at = start_ + position_;
    if (out_->size() < at + count) out_->resize(at + count);
    std::memcpy(out_->data() + at, bytes, count);
    position_ += count;
  }
  std::uint64_t tellp() override { return position_; }
  void seekp(std::uint64_t position) override { position_ = position; }

 private:
  std::vector<std::uint8_t>* out_;
  std::size_t start_;
  std::uint64_t position_ = 0;
};

}  // namespace

bool EncodeOpenExr(const cv::Mat& image, std::vector<std::uint8_t>* out, std::string* why) {
  if (image.empty() || (image.type() != CV_32FC1 && image.type() != CV_32FC3)) {
    *why = "OpenEXR is written from 32-bit float images of 1 or 3 channels";
    return false;
  }
  const std::size_t start = out->size();
  try {
    Imf::Header header(image.cols, image.rows);
    header.compression() = Imf::ZIP_COMPRESSION;
    Imf::FrameBuffer frame;
    // OpenEXR only reads the slices of a file it writes; they take a
    // non-const pointer all the same.
    char* pixels = reinterpret_cast<char*>(const_cast<std::uint8_t*>(image.data));
    const std::size_t pixel_bytes = image.elemSize(), row_bytes = image.step[0];
    if (image.channels() == 1) {
      header.channels().insert("Y", Imf::Channel(Imf::FLOAT));
      frame.insert("Y", Imf::Slice(Imf::FLOAT, pixels, pixel_bytes, row_bytes));
    } else {
      const char* names[] = {"B", "G", "R"};  // OpenCV's order in memory
      for (int c = 0; c < 3; ++c) {
        header.channels().insert(names[c], Imf::Channel(Imf::FLOAT));
        frame.insert(names[c], Imf::Slice(Imf::FLOAT, pixels + c * sizeof(float), pixel_bytes, row_bytes));
      }
    }
    AppendingStream stream(out);
    // The file's destructor writes the offset table over the placeholder it
    // wrote first: into bytes that exist, so it cannot fail.
    Imf::OutputFile file(stream, header);
    file.setFrameBuffer(frame);
    file.writePixels(image.rows);
  } catch (const std::exception& error) {
    out->resize(start);
    *why = std::string("OpenEXR: ") + error.what();
    return false;
  }
  return true;
}

}  // namespace photorig::solvers::codecs::internal
