// The JPEG decoder against OpenCV's (cv::imdecode, IMREAD_UNCHANGED) on
// files OpenCV and libjpeg write, and on truncated, corrupt and oversized
// ones; the OpenEXR encoder read back by OpenEXR itself and by OpenCV.

#include "formats.h"
#include "photorig/solvers/codecs/image_codecs.h"

#include <OpenEXR/Iex.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfCompression.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfInputFile.h>
#include "same_bits.h"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <cstdio>  // jpeglib.h needs FILE and size_t declared first

#include <jpeglib.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <iterator>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace photorig::solvers::codecs::internal {
namespace {

// OpenCV reads OPENCV_IO_ENABLE_OPENEXR once, at its first OpenEXR file, so
// it is set before any test runs.
class OpenCvReadsOpenExr : public ::testing::Environment {
 public:
  void SetUp() override { setenv("OPENCV_IO_ENABLE_OPENEXR", "1", 1); }
};
[[maybe_unused]] ::testing::Environment* const kOpenCvReadsOpenExr =
    ::testing::AddGlobalTestEnvironment(new OpenCvReadsOpenExr);

using photorig::solvers::codecs::test_support::SameBits;

// Gradients, a sharp edge and noise: smooth areas, ringing, and colour that
// changes within a chroma block.
cv::Mat TestImage(int rows, int cols, int channels) {
  cv::Mat image(rows, cols, CV_8UC(channels));
  cv::RNG rng(static_cast<std::uint64_t>(rows) * 1000 + cols);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c)
      for (int k = 0; k < channels; ++k)
        image.ptr(r)[c * channels + k] =
            cv::saturate_cast<std::uint8_t>(r * 5 + c * 3 * (k + 1) + (c > cols / 2 ? 90 : 0) + rng.uniform(-25, 26));
  return image;
}

std::vector<std::uint8_t> OpenCvJpeg(const cv::Mat& image, const std::vector<int>& params) {
  std::vector<std::uint8_t> bytes;
  EXPECT_TRUE(cv::imencode(".jpg", image, bytes, params));
  return bytes;
}

// DecodeJpeg's image is OpenCV's, bit for bit.
void ExpectAsOpenCv(const std::vector<std::uint8_t>& jpeg) {
  std::string why;
  const cv::Mat decoded = DecodeJpeg(jpeg, &why, kMaxDecodedBytes);
  const cv::Mat expected = cv::imdecode(jpeg, cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(expected.empty());
  ASSERT_FALSE(decoded.empty()) << why;
  EXPECT_TRUE(SameBits(decoded, expected));
}

struct LibjpegOptions {
  J_COLOR_SPACE file_space = JCS_YCbCr;
  int luma_h = 2, luma_v = 2;  // YCbCr's luma sampling factors; chroma is 1 x 1
  bool progressive = false;
  bool arithmetic = false;  // arithmetic coding in place of Huffman's
  std::vector<jpeg_scan_info> scans = {};  // a scan script of its own when not empty
};

// `pixels` holds interleaved samples in `input_space`'s order. libjpeg's
// default error handler ends the program on an error: these inputs are valid.
std::vector<std::uint8_t> LibjpegJpeg(const cv::Mat& pixels, J_COLOR_SPACE input_space,
                                      const LibjpegOptions& options) {
  jpeg_compress_struct info{};
  jpeg_error_mgr errors{};
  info.err = jpeg_std_error(&errors);
  jpeg_create_compress(&info);
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  jpeg_mem_dest(&info, &buffer, &size);
  info.image_width = static_cast<JDIMENSION>(pixels.cols);
  info.image_height = static_cast<JDIMENSION>(pixels.rows);
  info.input_components = pixels.channels();
  info.in_color_space = input_space;
  jpeg_set_defaults(&info);
  jpeg_set_colorspace(&info, options.file_space);
  jpeg_set_quality(&info, 90, TRUE);
  if (options.file_space == JCS_YCbCr) {
    info.comp_info[0].h_samp_factor = options.luma_h;
    info.comp_info[0].v_samp_factor = options.luma_v;
  }
  if (!options.scans.empty()) {
    info.scan_info = options.scans.data();
    info.num_scans = static_cast<int>(options.scans.size());
  } else if (options.progressive) {
    jpeg_simple_progression(&info);
  }
  info.arith_code = options.arithmetic;
  jpeg_start_compress(&info, TRUE);
  while (info.next_scanline < info.image_height) {
    JSAMPROW row = const_cast<JSAMPROW>(pixels.ptr(static_cast<int>(info.next_scanline)));
    jpeg_write_scanlines(&info, &row, 1);
  }
  jpeg_finish_compress(&info);
  jpeg_destroy_compress(&info);
  std::vector<std::uint8_t> bytes(buffer, buffer + size);
  std::free(buffer);
  return bytes;
}

// A marker segment before the first scan: its offset, marker byte and size
// with the marker.
struct Segment {
  std::size_t offset;
  std::uint8_t marker;
  std::size_t size;
};

std::vector<Segment> HeaderSegments(const std::vector<std::uint8_t>& jpeg) {
  std::vector<Segment> segments;
  std::size_t at = 2;  // past SOI
  while (at + 4 <= jpeg.size() && jpeg[at] == 0xff) {
    const Segment segment{at, jpeg[at + 1], 2 + static_cast<std::size_t>(jpeg[at + 2] << 8 | jpeg[at + 3])};
    segments.push_back(segment);
    if (segment.marker == 0xda) break;  // SOS: entropy-coded data follows
    at += segment.size;
  }
  return segments;
}

// The file with its frame header (SOF0-SOF2) claiming another size.
std::vector<std::uint8_t> WithSize(std::vector<std::uint8_t> jpeg, unsigned width, unsigned height) {
  for (const Segment& segment : HeaderSegments(jpeg)) {
    if (segment.marker < 0xc0 || segment.marker > 0xc2) continue;
    std::uint8_t* sof = jpeg.data() + segment.offset;
    sof[5] = static_cast<std::uint8_t>(height >> 8);
    sof[6] = static_cast<std::uint8_t>(height);
    sof[7] = static_cast<std::uint8_t>(width >> 8);
    sof[8] = static_cast<std::uint8_t>(width);
    return jpeg;
  }
  ADD_FAILURE() << "no frame header";
  return jpeg;
}

TEST(Jpeg, ColourFromOpenCvDecodesAsOpenCvDoes) {
  for (const cv::Size size : {cv::Size(1, 1), cv::Size(5, 3), cv::Size(48, 64), cv::Size(131, 67)}) {
    const cv::Mat image = TestImage(size.height, size.width, 3);
    for (const int quality : {5, 50, 75, 95, 100}) {
      for (const int progressive : {0, 1}) {
        SCOPED_TRACE(testing::Message() << size << " quality " << quality << " progressive " << progressive);
        ExpectAsOpenCv(OpenCvJpeg(image, {cv::IMWRITE_JPEG_QUALITY, quality, cv::IMWRITE_JPEG_PROGRESSIVE,
                                          progressive}));
      }
    }
    SCOPED_TRACE(testing::Message() << size);
    ExpectAsOpenCv(OpenCvJpeg(image, {cv::IMWRITE_JPEG_OPTIMIZE, 1, cv::IMWRITE_JPEG_RST_INTERVAL, 2}));
    ExpectAsOpenCv(OpenCvJpeg(image, {cv::IMWRITE_JPEG_LUMA_QUALITY, 90, cv::IMWRITE_JPEG_CHROMA_QUALITY, 30}));
  }
}

TEST(Jpeg, GreyFromOpenCvDecodesAsOpenCvDoes) {
  for (const cv::Size size : {cv::Size(1, 1), cv::Size(5, 3), cv::Size(131, 67)}) {
    const cv::Mat image = TestImage(size.height, size.width, 1);
    for (const int quality : {5, 75, 100}) {
      for (const int progressive : {0, 1}) {
        SCOPED_TRACE(testing::Message() << size << " quality " << quality << " progressive " << progressive);
        const std::vector<std::uint8_t> jpeg =
            OpenCvJpeg(image, {cv::IMWRITE_JPEG_QUALITY, quality, cv::IMWRITE_JPEG_PROGRESSIVE, progressive});
        ExpectAsOpenCv(jpeg);
        std::string why;
        EXPECT_EQ(DecodeJpeg(jpeg, &why, kMaxDecodedBytes).type(), CV_8UC1);
      }
    }
  }
}

// OpenCV 4.6 writes 4:2:0 Huffman-coded files only; libjpeg writes the other
// samplings (3 x 2: one with no smoothing filter of its own), RGB without a
// colour transform, and arithmetic coding.
TEST(Jpeg, EveryChromaSamplingRgbAndArithmeticCodingDecodeAsOpenCvDoes) {
  const cv::Mat rgb = TestImage(45, 77, 3);
  const std::pair<int, int> samplings[] = {{1, 1}, {2, 1}, {1, 2}, {2, 2}, {4, 1}, {3, 2}};
  for (const auto& [h, v] : samplings) {
    for (const bool progressive : {false, true}) {
      SCOPED_TRACE(testing::Message() << "luma " << h << " x " << v << " progressive " << progressive);
      ExpectAsOpenCv(LibjpegJpeg(rgb, JCS_RGB, {.luma_h = h, .luma_v = v, .progressive = progressive}));
    }
  }
  ExpectAsOpenCv(LibjpegJpeg(rgb, JCS_RGB, {.file_space = JCS_RGB}));
  for (const bool progressive : {false, true}) {
    SCOPED_TRACE(testing::Message() << "arithmetic, progressive " << progressive);
    ExpectAsOpenCv(LibjpegJpeg(rgb, JCS_RGB, {.progressive = progressive, .arithmetic = true}));
  }
}

// OpenCV turns four components into B, G, R by its own formula, the decoder
// by the same.
TEST(Jpeg, CmykAndYcckBecomeBgrAsOpenCvConvertsThem) {
  const cv::Mat cmyk = TestImage(37, 51, 4);
  for (const J_COLOR_SPACE space : {JCS_CMYK, JCS_YCCK}) {
    for (const bool progressive : {false, true}) {
      SCOPED_TRACE(testing::Message() << "colour space " << space << " progressive " << progressive);
      const std::vector<std::uint8_t> jpeg =
          LibjpegJpeg(cmyk, JCS_CMYK, {.file_space = space, .progressive = progressive});
      ExpectAsOpenCv(jpeg);
      std::string why;
      EXPECT_EQ(DecodeJpeg(jpeg, &why, kMaxDecodedBytes).type(), CV_8UC3);
    }
  }
}

// Motion-JPEG frames leave out the Huffman tables; the standard ones apply.
TEST(Jpeg, MotionJpegWithoutHuffmanTablesDecodesAsOpenCvDoes) {
  const std::vector<std::uint8_t> jpeg = OpenCvJpeg(TestImage(40, 56, 3), {});
  std::vector<std::uint8_t> frame(jpeg.begin(), jpeg.begin() + 2);
  std::size_t copied = 2;
  for (const Segment& segment : HeaderSegments(jpeg)) {
    if (segment.marker == 0xc4) {  // DHT
      frame.insert(frame.end(), jpeg.begin() + copied, jpeg.begin() + segment.offset);
      copied = segment.offset + segment.size;
    }
  }
  frame.insert(frame.end(), jpeg.begin() + copied, jpeg.end());
  ASSERT_LT(frame.size(), jpeg.size());
  ExpectAsOpenCv(frame);
  std::string why;
  EXPECT_TRUE(SameBits(DecodeJpeg(frame, &why, kMaxDecodedBytes), DecodeJpeg(jpeg, &why, kMaxDecodedBytes)));
}

// IMREAD_UNCHANGED keeps the stored orientation, and so does the decoder.
TEST(Jpeg, ExifOrientationIsNotApplied) {
  const std::vector<std::uint8_t> jpeg = OpenCvJpeg(TestImage(24, 40, 3), {});
  // APP1: "Exif", then a little-endian TIFF header whose one IFD entry is
  // Orientation (0x0112), SHORT, 6: rotate 90 degrees clockwise to display.
  const std::vector<std::uint8_t> app1 = {0xff, 0xe1, 0x00, 0x22, 'E', 'x', 'i', 'f', 0, 0, 'I', 'I', 0x2a, 0,
                                          8,    0,    0,    0,    1,   0,   0x12, 0x01, 3, 0, 1, 0, 0, 0, 6, 0,
                                          0,    0,    0,    0,    0,   0};
  std::vector<std::uint8_t> rotated(jpeg.begin(), jpeg.begin() + 2);
  rotated.insert(rotated.end(), app1.begin(), app1.end());
  rotated.insert(rotated.end(), jpeg.begin() + 2, jpeg.end());
  ASSERT_EQ(cv::imdecode(rotated, cv::IMREAD_COLOR).size(), cv::Size(24, 40));  // the orientation is read
  std::string why;
  const cv::Mat decoded = DecodeJpeg(rotated, &why, kMaxDecodedBytes);
  EXPECT_EQ(decoded.size(), cv::Size(40, 24)) << why;
  ExpectAsOpenCv(rotated);
}

// OpenCV reads nothing after the last row either: padding before the end
// marker (some cameras write it) and bytes after it change nothing.
TEST(Jpeg, BytesAfterTheLastRowAreNotRead) {
  const std::vector<std::uint8_t> jpeg = OpenCvJpeg(TestImage(40, 56, 3), {});
  ASSERT_EQ(jpeg[jpeg.size() - 2], 0xff);
  ASSERT_EQ(jpeg.back(), 0xd9);  // EOI
  std::vector<std::uint8_t> padded(jpeg.begin(), jpeg.end() - 2);
  padded.insert(padded.end(), {0, 0, 0, 0, 0, 0xff, 0xd9, 'j', 'u', 'n', 'k'});
  ExpectAsOpenCv(padded);
  std::string why;
  EXPECT_TRUE(SameBits(DecodeJpeg(padded, &why, kMaxDecodedBytes), DecodeJpeg(jpeg, &why, kMaxDecodedBytes)));
}

// libjpeg warns of a JFIF version or an Adobe colour transform it does not
// know, and decodes as OpenCV does (an unknown transform of four components
// taken for YCCK).
TEST(Jpeg, UnknownJfifVersionAndAdobeTransformDecodeAsOpenCvDoes) {
  std::vector<std::uint8_t> jfif = OpenCvJpeg(TestImage(16, 24, 3), {});
  const Segment app0 = HeaderSegments(jfif).front();
  ASSERT_EQ(app0.marker, 0xe0);
  ASSERT_EQ(std::string(jfif.begin() + app0.offset + 4, jfif.begin() + app0.offset + 9), std::string("JFIF", 5));
  jfif[app0.offset + 9] = 3;  // major version
  ExpectAsOpenCv(jfif);

  std::vector<std::uint8_t> adobe = LibjpegJpeg(TestImage(16, 24, 4), JCS_CMYK, {.file_space = JCS_CMYK});
  bool patched = false;
  for (const Segment& segment : HeaderSegments(adobe)) {
    if (segment.marker != 0xee) continue;  // APP14: "Adobe", version, two flag words, transform
    ASSERT_EQ(adobe[segment.offset + 15], 0);  // CMYK
    adobe[segment.offset + 15] = 7;
    patched = true;
  }
  ASSERT_TRUE(patched);
  ExpectAsOpenCv(adobe);
}

// Every cut of a file is refused as truncated, unless only the end marker is
// missing and the image is whole. OpenCV 4.6 instead hands back a cut
// baseline file, its missing rows copies of the last row it decoded.
TEST(Jpeg, CutFilesAreRefusedAsTruncated) {
  const cv::Mat colour = TestImage(40, 56, 3);
  const std::vector<std::vector<std::uint8_t>> files = {
      OpenCvJpeg(colour, {}), OpenCvJpeg(colour, {cv::IMWRITE_JPEG_PROGRESSIVE, 1}),
      OpenCvJpeg(TestImage(40, 56, 1), {}), OpenCvJpeg(colour, {cv::IMWRITE_JPEG_RST_INTERVAL, 1}),
      LibjpegJpeg(colour, JCS_RGB, {.arithmetic = true}),
      LibjpegJpeg(colour, JCS_RGB, {.progressive = true, .arithmetic = true})};
  for (const std::vector<std::uint8_t>& whole : files) {
    std::string why;
    const cv::Mat expected = DecodeJpeg(whole, &why, kMaxDecodedBytes);
    ASSERT_FALSE(expected.empty()) << why;
    int accepted = 0;
    for (std::size_t size = 0; size < whole.size(); ++size) {
      SCOPED_TRACE(testing::Message() << size << " of " << whole.size() << " bytes");
      // A copy of exactly the cut, so that a read past it is out of bounds.
      const std::vector<std::uint8_t> cut(whole.begin(), whole.begin() + size);
      why.clear();
      const cv::Mat decoded = DecodeJpeg(cut, &why, kMaxDecodedBytes);
      if (decoded.empty()) {
        EXPECT_EQ(why, "JPEG: the file ends early (truncated)");
        continue;
      }
      EXPECT_GE(size, whole.size() - 2);
      EXPECT_TRUE(SameBits(decoded, expected));
      ++accepted;
    }
    EXPECT_LE(accepted, 2);
  }
}

// A wrong restart marker: libjpeg warns and resynchronises, OpenCV hands
// back the damaged image (with the warning on stderr); the decoder refuses.
TEST(Jpeg, CorruptDataIsRefused) {
  std::vector<std::uint8_t> jpeg = OpenCvJpeg(TestImage(40, 56, 3), {cv::IMWRITE_JPEG_RST_INTERVAL, 1});
  const Segment scan = HeaderSegments(jpeg).back();
  ASSERT_EQ(scan.marker, 0xda);
  std::size_t at = scan.offset + scan.size;
  while (at + 1 < jpeg.size() && !(jpeg[at] == 0xff && jpeg[at + 1] == 0xd0)) ++at;
  ASSERT_LT(at + 1, jpeg.size());
  jpeg[at + 1] = 0xd3;  // RST3 where RST0 belongs
  EXPECT_FALSE(cv::imdecode(jpeg, cv::IMREAD_UNCHANGED).empty());
  std::string why;
  EXPECT_TRUE(DecodeJpeg(jpeg, &why, kMaxDecodedBytes).empty());
  EXPECT_EQ(why.rfind("JPEG: Corrupt JPEG data", 0), 0u) << why;
}

// Width x height x channels up to 1 GiB; a header claiming more is refused
// before any pixel is allocated.
TEST(Jpeg, ImagesPastOneGibAreRefused) {
  const std::vector<std::uint8_t> grey = OpenCvJpeg(TestImage(16, 16, 1), {});
  const std::vector<std::uint8_t> colour = OpenCvJpeg(TestImage(16, 16, 3), {});
  std::string why;
  EXPECT_TRUE(DecodeJpeg(WithSize(grey, 32768, 32769), &why, kMaxDecodedBytes).empty());
  EXPECT_EQ(why, "JPEG: 32768 x 32769 pixels, past the 1 GiB limit");
  EXPECT_TRUE(DecodeJpeg(WithSize(colour, 18919, 18919), &why, kMaxDecodedBytes).empty());
  EXPECT_EQ(why, "JPEG: 18919 x 18919 pixels, past the 1 GiB limit");
  EXPECT_TRUE(DecodeJpeg(WithSize(grey, 65500, 65500), &why, kMaxDecodedBytes).empty());
  EXPECT_EQ(why, "JPEG: 65500 x 65500 pixels, past the 1 GiB limit");
  // Exactly 1 GiB passes the limit; the scan then meets the end marker
  // long before the last row.
  EXPECT_TRUE(DecodeJpeg(WithSize(grey, 32768, 32768), &why, kMaxDecodedBytes).empty());
  EXPECT_EQ(why, "JPEG: Corrupt JPEG data: premature end of data segment");
}

// A progressive file keeps every coefficient while it is read: as many
// bytes as the decoded colour image at 4:2:0, twice as many at 4:4:4. The
// image and libjpeg's buffers together are held to 1.5 GiB, checked before
// either is allocated.
TEST(Jpeg, ProgressiveFilesNeedingOverOneAndAHalfGibAreRefused) {
  const std::vector<std::uint8_t> full =
      LibjpegJpeg(TestImage(16, 16, 3), JCS_RGB, {.luma_h = 1, .luma_v = 1, .progressive = true});
  const std::vector<std::uint8_t> subsampled = OpenCvJpeg(TestImage(16, 16, 3), {cv::IMWRITE_JPEG_PROGRESSIVE, 1});
  std::string why;
  EXPECT_TRUE(DecodeJpeg(WithSize(full, 18000, 18000), &why, kMaxDecodedBytes).empty());  // 972 MB of pixels, 1.9 GB of coefficients
  EXPECT_EQ(why, "JPEG: decoding it takes more than 1.5 GiB of memory");
  EXPECT_TRUE(DecodeJpeg(WithSize(subsampled, 17000, 17000), &why, kMaxDecodedBytes).empty());  // 867 MB and 868 MB
  EXPECT_EQ(why, "JPEG: decoding it takes more than 1.5 GiB of memory");
  EXPECT_TRUE(DecodeJpeg(WithSize(full, 4000, 4000), &why, kMaxDecodedBytes).empty());  // within the limit, short of data
  EXPECT_EQ(why, "JPEG: Corrupt JPEG data: premature end of data segment");
}

// A lower pixel limit (DecodeOptions) lowers the memory held to with it.
TEST(Jpeg, TheMemoryLimitIsOneAndAHalfTimesThePixelLimit) {
  const std::vector<std::uint8_t> full =
      LibjpegJpeg(TestImage(16, 16, 3), JCS_RGB, {.luma_h = 1, .luma_v = 1, .progressive = true});
  constexpr std::uint64_t k64MiB = std::uint64_t{64} << 20;
  std::string why;
  // 48 MB of pixels, 96 MB of coefficients: past 96 MiB together.
  EXPECT_TRUE(DecodeJpeg(WithSize(full, 4000, 4000), &why, k64MiB).empty());
  EXPECT_EQ(why, "JPEG: decoding it takes more than 96 MiB of memory");
  EXPECT_TRUE(DecodeJpeg(WithSize(full, 5000, 5000), &why, k64MiB).empty());  // 75 MB of pixels
  EXPECT_EQ(why, "JPEG: 5000 x 5000 pixels, past the 64 MiB limit");
  EXPECT_TRUE(DecodeJpeg(WithSize(full, 2000, 2000), &why, k64MiB).empty());  // within it, short of data
  EXPECT_EQ(why, "JPEG: Corrupt JPEG data: premature end of data segment");
}

// A grey progressive file whose AC coefficients come one at a time, each in
// `passes` successive-approximation scans: 1 + 63 x passes scans.
std::vector<std::uint8_t> ManyScans(int passes) {
  std::vector<jpeg_scan_info> scans = {{1, {0}, 0, 0, 0, 0}};
  for (int k = 1; k < 64; ++k) {
    scans.push_back({1, {0}, k, k, 0, passes - 1});
    for (int bit = passes - 1; bit > 0; --bit) scans.push_back({1, {0}, k, k, bit, bit - 1});
  }
  return LibjpegJpeg(TestImage(24, 24, 1), JCS_GRAYSCALE, {.file_space = JCS_GRAYSCALE, .scans = scans});
}

TEST(Jpeg, ScansPastFiveHundredAreRefused) {
  ExpectAsOpenCv(ManyScans(7));  // 442 scans
  const std::vector<std::uint8_t> jpeg = ManyScans(8);  // 505 scans
  EXPECT_FALSE(cv::imdecode(jpeg, cv::IMREAD_UNCHANGED).empty());
  std::string why;
  EXPECT_TRUE(DecodeJpeg(jpeg, &why, kMaxDecodedBytes).empty());
  EXPECT_EQ(why, "JPEG: more than 500 scans");
}

TEST(Jpeg, OtherInputIsRefusedWithLibjpegsReason) {
  std::string why;
  EXPECT_TRUE(DecodeJpeg({}, &why, kMaxDecodedBytes).empty());
  EXPECT_EQ(why, "JPEG: the file ends early (truncated)");
  const std::vector<std::uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 0, 0, 0, 13};
  EXPECT_TRUE(DecodeJpeg(png, &why, kMaxDecodedBytes).empty());
  EXPECT_EQ(why.rfind("JPEG: Not a JPEG file", 0), 0u) << why;
  // Two components: neither grey nor colour in OpenCV's terms.
  const std::vector<std::uint8_t> two = LibjpegJpeg(TestImage(16, 16, 2), JCS_UNKNOWN, {.file_space = JCS_UNKNOWN});
  EXPECT_TRUE(cv::imdecode(two, cv::IMREAD_UNCHANGED).empty());
  EXPECT_TRUE(DecodeJpeg(two, &why, kMaxDecodedBytes).empty());
  EXPECT_EQ(why, "JPEG: Unsupported color conversion request");
}

// OpenEXR from memory, for reading back what the encoder wrote.
class MemoryInput final : public Imf::IStream {
 public:
  explicit MemoryInput(const std::vector<std::uint8_t>& bytes, std::size_t start = 0)
      : Imf::IStream("memory"), bytes_(bytes), start_(start) {}
  bool read(char out[], int count) override {
    if (count < 0 || start_ + position_ + count > bytes_.size()) throw Iex::InputExc("read past the end");
    std::memcpy(out, bytes_.data() + start_ + position_, count);
    position_ += count;
    return start_ + position_ < bytes_.size();
  }
  std::uint64_t tellg() override { return position_; }
  void seekg(std::uint64_t position) override { position_ = position; }

 private:
  const std::vector<std::uint8_t>& bytes_;
  std::size_t start_;
  std::uint64_t position_ = 0;
};

struct ExrFile {
  std::vector<std::string> channels;  // in the file's order
  Imf::Compression compression;
  cv::Mat pixels;  // CV_32FC(channels), in the file's channel order
};

ExrFile ReadExr(const std::vector<std::uint8_t>& bytes, std::size_t start = 0) {
  MemoryInput stream(bytes, start);
  Imf::InputFile file(stream);
  const Imath::Box2i window = file.header().dataWindow();
  ExrFile exr;
  exr.compression = file.header().compression();
  for (auto channel = file.header().channels().begin(); channel != file.header().channels().end(); ++channel) {
    EXPECT_EQ(channel.channel().type, Imf::FLOAT) << channel.name();
    exr.channels.push_back(channel.name());
  }
  const int count = static_cast<int>(exr.channels.size());
  exr.pixels.create(window.max.y - window.min.y + 1, window.max.x - window.min.x + 1, CV_32FC(count));
  Imf::FrameBuffer frame;
  for (int c = 0; c < count; ++c)
    frame.insert(exr.channels[c], Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(exr.pixels.ptr<float>() + c),
                                             exr.pixels.elemSize(), exr.pixels.step[0]));
  file.setFrameBuffer(frame);
  file.readPixels(window.min.y, window.max.y);
  return exr;
}

float FloatOfBits(std::uint32_t bits) {
  float value;
  std::memcpy(&value, &bits, sizeof value);
  return value;
}

// Random bit patterns (NaNs with payloads, denormals, both signs), then the
// special values at the start; 41 rows span three ZIP blocks.
cv::Mat FloatImage(int channels) {
  cv::Mat image(41, 19, CV_32FC(channels));
  std::mt19937 random(7);
  for (int r = 0; r < image.rows; ++r)
    for (int i = 0; i < image.cols * channels; ++i) image.ptr<float>(r)[i] = FloatOfBits(random());
  const std::uint32_t specials[] = {
      0x7fc00000, 0xffc00001, 0x7f800001,  // quiet NaN, negative NaN with a payload, signalling NaN
      0x7f800000, 0xff800000,              // +inf, -inf
      0x00000001, 0x007fffff, 0x80000001,  // smallest and largest denormal, a negative denormal
      0x80000000, 0x00000000,              // -0, +0
      0x7f7fffff, 0xff7fffff, 0x00800000,  // largest and lowest finite, smallest normal
      0xbfc00000, 0x3f800000, 0xc2f6e979,  // -1.5, 1, -123.456
  };
  float* first = image.ptr<float>(0);
  for (std::size_t i = 0; i < std::size(specials); ++i) first[i] = FloatOfBits(specials[i]);
  return image;
}

TEST(OpenExr, ColourIsRgbFloatChannelsWithEveryBitKept) {
  const cv::Mat bgr = FloatImage(3);
  std::vector<std::uint8_t> bytes;
  std::string why;
  ASSERT_TRUE(EncodeOpenExr(bgr, &bytes, &why)) << why;
  const ExrFile exr = ReadExr(bytes);
  EXPECT_EQ(exr.channels, (std::vector<std::string>{"B", "G", "R"}));  // OpenEXR lists channels by name
  EXPECT_EQ(exr.compression, Imf::ZIP_COMPRESSION);
  EXPECT_TRUE(SameBits(exr.pixels, bgr));  // B, G, R in the file's order is OpenCV's
}

TEST(OpenExr, GreyIsOneYChannel) {
  const cv::Mat grey = FloatImage(1);
  std::vector<std::uint8_t> bytes;
  std::string why;
  ASSERT_TRUE(EncodeOpenExr(grey, &bytes, &why)) << why;
  const ExrFile exr = ReadExr(bytes);
  EXPECT_EQ(exr.channels, std::vector<std::string>{"Y"});
  EXPECT_TRUE(SameBits(exr.pixels, grey));
}

TEST(OpenExr, OpenCvReadsTheSamePixels) {
  for (const int channels : {1, 3}) {
    SCOPED_TRACE(testing::Message() << channels << " channels");
    const cv::Mat image = FloatImage(channels);
    std::vector<std::uint8_t> bytes;
    std::string why;
    ASSERT_TRUE(EncodeOpenExr(image, &bytes, &why)) << why;
    EXPECT_TRUE(SameBits(cv::imdecode(bytes, cv::IMREAD_UNCHANGED), image));
  }
}

// The file goes after what `out` holds, its offsets counted from its own
// start; a region of a larger image (rows apart in memory) is written as it
// looks.
TEST(OpenExr, AppendsARegionAfterExistingBytes) {
  const cv::Mat whole = FloatImage(3);
  const cv::Mat region = whole(cv::Rect(3, 2, 11, 37));
  const std::vector<std::uint8_t> prefix = {1, 2, 3, 4, 5};
  std::vector<std::uint8_t> bytes = prefix;
  std::string why;
  ASSERT_TRUE(EncodeOpenExr(region, &bytes, &why)) << why;
  EXPECT_TRUE(std::equal(prefix.begin(), prefix.end(), bytes.begin()));
  EXPECT_TRUE(SameBits(ReadExr(bytes, prefix.size()).pixels, region.clone()));
}

TEST(OpenExr, OtherImagesAreRefused) {
  const std::vector<std::uint8_t> prefix = {9, 9};
  for (const cv::Mat& image : {cv::Mat(4, 4, CV_8UC3), cv::Mat(4, 4, CV_32FC4), cv::Mat(4, 4, CV_32FC2),
                               cv::Mat(4, 4, CV_64FC1), cv::Mat(4, 4, CV_16UC1), cv::Mat(0, 0, CV_32FC3)}) {
    SCOPED_TRACE(testing::Message() << "type " << image.type() << " " << image.size());
    std::vector<std::uint8_t> bytes = prefix;
    std::string why;
    EXPECT_FALSE(EncodeOpenExr(image, &bytes, &why));
    EXPECT_EQ(why, "OpenEXR is written from 32-bit float images of 1 or 3 channels");
    EXPECT_EQ(bytes, prefix);
  }
}

}  // namespace
}  // namespace photorig::solvers::codecs::internal
